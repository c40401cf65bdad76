//! Tests of [`super`]: point lookups read what the field reconstructs, picked emission
//! points average to the interpolated emission, still shadow rays stay exact under null
//! collisions, and the read-ahead recorder sees the real walk's lookups first.

use super::*;
use crate::medium::{Convention, Emission, EmissionKind, TemperatureMap};
use plume_core::sampling::phase::sample_uniform_sphere;
use plume_volume::trilinear::Trilinear;
use plume_volume::Volume;

/// A generated 24³ explosion and a blackbody emission for it.
fn hot_explosion() -> (plume_synth::Explosion, Emission) {
    let ex = plume_synth::explosion(&plume_synth::ExplosionParams {
        resolution: 24,
        seed: 2,
        ..Default::default()
    });
    let emission = Emission {
        kind: EmissionKind::Blackbody,
        convention: Convention::Physical,
        scale: 1e-3,
        color: plume_core::color::Rgb::ONE,
        temperature_map: TemperatureMap::Kelvin,
        cutoff_kelvin: 500.0,
    };
    (ex, emission)
}

/// The hot explosion's volume, nearest and trilinear, and a scattering medium with its
/// blackbody.
fn hot_fields() -> (Volume, Trilinear, Medium) {
    let (ex, emission) = hot_explosion();
    let volume =
        || Volume::build(&ex.density, Some(&ex.temperature), |v| emission.map_source(v)).unwrap();
    (
        volume(),
        Trilinear::new(volume()),
        Medium {
            sigma_t: 2.0,
            albedo: plume_core::color::Rgb::splat(0.8),
            g: 0.0,
            emission,
            extinction: Default::default(),
        },
    )
}

/// What null collisions read of a still volume is exactly what the field
/// reconstructs there (bit for bit), nearest and trilinear, at random points in and
/// around a hot explosion; and a moving volume at time 0 with zero velocity reads the
/// same.
#[test]
fn points_read_what_the_field_reconstructs() {
    let (nearest, linear, medium) = hot_fields();
    let motion = Motion::new(
        &nearest,
        plume_volume::velocity::Velocity::Uniform(glam::DVec3::ZERO),
        1.0,
        [0.0, 0.0],
    );
    let b = nearest.world_bounds();
    let mut rng = Sampler::new(5, 0, 0);
    let mut emitting = 0;
    for _ in 0..8000 {
        let u = glam::DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64());
        let p = b.lo
            + (b.hi - b.lo) * (u * 1.2 - 0.1)
            + 1e-3 * sample_uniform_sphere([rng.next_f64(), rng.next_f64()]);
        for (still, moving) in [
            (
                Points::new(&nearest, &medium, None, PointLookup::Exact).sample(p, true),
                Points::new(&nearest, &medium, Some((&motion, 0.0)), PointLookup::Exact)
                    .sample(p, true),
            ),
            (
                Points::new(&linear, &medium, None, PointLookup::Exact).sample(p, true),
                Points::new(&linear, &medium, Some((&motion, 0.0)), PointLookup::Exact)
                    .sample(p, true),
            ),
        ] {
            assert_eq!(still, moving, "at {p}");
        }
        let check = |field: &dyn Fn(
            glam::DVec3,
        ) -> (
            plume_volume::field::PointValues,
            plume_volume::field::VoxelValues,
            f32,
        ),
                     points: &dyn PointField| {
            let (v, values, albedo) = field(p);
            let s = points.sample(p, true);
            assert_eq!(
                points.sample(p, false),
                PointSample { emission: [0.0; 3], ..s },
                "sample without emission at {p}"
            );
            assert_eq!(points.density(p).to_bits(), v.density.to_bits(), "density at {p}");
            assert_eq!(
                points.emission(p).map(f64::to_bits),
                v.emission.map(f64::to_bits),
                "emission at {p}"
            );
            assert_eq!(
                s,
                PointSample {
                    density: v.density,
                    source: values.source,
                    emission: v.emission,
                    albedo
                },
                "sample at {p}"
            );
            v.emission.iter().any(|&e| e > 0.0)
        };
        let le = |d: f32, s: f32| medium.emission.le(d, s);
        emitting += usize::from(check(
            &|q| (nearest.reconstruct(q, &le), nearest.values_at(q), nearest.albedo_at(q)),
            &Points::new(&nearest, &medium, None, PointLookup::Exact),
        ));
        emitting += usize::from(check(
            &|q| (linear.reconstruct(q, &le), linear.values_at(q), linear.albedo_at(q)),
            &Points::new(&linear, &medium, None, PointLookup::Exact),
        ));
    }
    assert!(emitting > 200, "only {emitting} emitting points checked");
}

/// A picked emission point is an unbiased estimate of the exact one: over `N`
/// stratified `u` every corner is picked `w_c N` times to within 1, so the mean of the
/// picked corners' `le` is the interpolated emission to within `8/N` of the corners'
/// largest `le`, per channel, at points in and around a hot explosion (blackbody, whose
/// corners differ by orders of magnitude). Only `stochastic-emission` on a trilinear field
/// picks emission points, and a camera segment's lookup never does.
#[test]
fn picked_emission_points_average_to_the_interpolated_emission() {
    let (nearest, linear, medium) = hot_fields();
    let points = Points::new(&linear, &medium, None, PointLookup::StochasticEmission);
    assert!(points.picks_emission() && points.picks());
    assert!(!Points::new(&linear, &medium, None, PointLookup::Stochastic).picks_emission());
    assert!(!Points::new(&linear, &medium, None, PointLookup::Exact).picks_emission());
    assert!(!Points::new(&nearest, &medium, None, PointLookup::StochasticEmission).picks_emission());
    assert_eq!(PointLookup::StochasticEmission.on_camera(), PointLookup::Stochastic);
    assert_eq!(PointLookup::Exact.on_camera(), PointLookup::Exact);
    let b = nearest.world_bounds();
    let mut rng = Sampler::new(11, 0, 0);
    let n = 4096;
    let (mut dark, mut emitting, mut spread) = (0, 0, 0);
    for _ in 0..100_000 {
        let u = glam::DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64());
        let p = b.lo + (b.hi - b.lo) * (u * 1.1 - 0.05);
        let exact = points.emission(p);
        let corners = linear
            .interpolate_world(p)
            .corners
            .map(|v| medium.emission.le(v.density, v.source).to_f64());
        if corners.iter().all(|e| *e == [0.0; 3]) {
            // No corner emits: every pick reads 0
            if dark < 200 {
                assert!(
                    (0..8)
                        .all(|i| points.emission_picked(p, (f64::from(i) + 0.5) / 8.0) == [0.0; 3]),
                    "at {p}"
                );
                dark += 1;
            }
            continue;
        }
        let mut sum = [0.0f64; 3];
        for i in 0..n {
            let e = points.emission_picked(p, (f64::from(i) + 0.5) / f64::from(n));
            assert!(corners.contains(&e), "at {p}: picked {e:?}, not one corner's le");
            sum.iter_mut().zip(e).for_each(|(s, e)| *s += e);
        }
        for c in 0..3 {
            let largest = corners.iter().map(|e| e[c]).fold(0.0, f64::max);
            let mean = sum[c] / f64::from(n);
            assert!(
                (mean - exact[c]).abs() <= 8.0 / f64::from(n) * largest + 1e-12 * largest,
                "at {p}, channel {c}: picked mean {mean} against {}",
                exact[c]
            );
        }
        emitting += 1;
        let (lo, hi) = corners
            .iter()
            .map(|e| e[0])
            .fold((f64::MAX, 0.0f64), |(lo, hi), e| (lo.min(e), hi.max(e)));
        spread += usize::from(hi > 10.0 * lo);
        if emitting == 300 {
            break;
        }
    }
    assert!(
        dark == 200 && emitting == 300 && spread > 30,
        "{dark} dark points, {emitting} emitting, {spread} with corners 10× apart"
    );
}

/// Shadow rays of a still volume are exact under null collisions: the same τ and steps
/// as regular tracking, bit for bit, and no random number drawn.
#[test]
fn still_shadow_rays_are_exact_under_null_collisions() {
    let ex = plume_synth::explosion(&plume_synth::ExplosionParams {
        resolution: 24,
        seed: 2,
        ..Default::default()
    });
    let volume = Volume::build(&ex.density, None, |v| v).unwrap();
    let majorants = MajorantGrid::new(&volume, 0.0);
    let medium = Medium {
        sigma_t: 3.0,
        albedo: plume_core::color::Rgb::splat(0.8),
        g: 0.0,
        emission: Emission::none(),
        extinction: Default::default(),
    };
    let b = volume.world_bounds();
    let mut rng = Sampler::new(9, 0, 0);
    for _ in 0..500 {
        let u = glam::DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64());
        let ray = Ray {
            origin: b.lo + (b.hi - b.lo) * u,
            direction: sample_uniform_sphere([rng.next_f64(), rng.next_f64()]),
        };
        let t_max = 4.0 * rng.next_f64();
        let (mut a, mut b2) = (Sampler::new(1, 2, 3), Sampler::new(1, 2, 3));
        let exact = Tracker::Regular(&volume).transmittance(&medium, &ray, t_max, &mut a);
        let null = Tracker::Null {
            field: &volume,
            majorants: &majorants,
            lookup: PointLookup::StochasticEmission,
        }
        .transmittance(&medium, &ray, t_max, &mut b2);
        assert_eq!(
            (exact.transmittance.to_bits(), exact.voxel_steps),
            (null.transmittance.to_bits(), null.voxel_steps)
        );
        assert_eq!(a.next_u64(), b2.next_u64(), "null shadow ray drew random numbers");
    }
}

/// The read-ahead walk ([`Recorder`]) asks for every value the real walk reads, in
/// the same order: the real walk's density and emission lookups (point, what is asked,
/// the number a picked read draws) are a prefix of the recorded ones, for the line and
/// point estimators, with and without a needed collision, on a thin and a dense
/// explosion, nearest and trilinear, with exact and stochastic point lookups (which draw
/// a number per read: the recorder must too). Deferred paths (`integrator::deferred`)
/// rely on it: a segment is walked only once every recorded value is there.
#[test]
fn read_ahead_records_the_real_walks_lookups_first() {
    struct Tap<'a, P: PointField> {
        inner: &'a P,
        points: std::cell::RefCell<Vec<Request>>,
    }
    impl<P: PointField> PointField for Tap<'_, P> {
        fn density(&self, p: glam::DVec3) -> f32 {
            self.points.borrow_mut().push(Request { p, ask: Ask::Density, u: 0.0 });
            self.inner.density(p)
        }
        fn emission(&self, p: glam::DVec3) -> [f64; 3] {
            self.points.borrow_mut().push(Request { p, ask: Ask::Emission, u: 0.0 });
            self.inner.emission(p)
        }
        fn sample(&self, p: glam::DVec3, emission: bool) -> PointSample {
            self.inner.sample(p, emission)
        }
        fn picks(&self) -> bool {
            self.inner.picks()
        }
        fn density_picked(&self, p: glam::DVec3, u: f64) -> f32 {
            self.points.borrow_mut().push(Request { p, ask: Ask::DensityPicked, u });
            self.inner.density_picked(p, u)
        }
        fn picks_emission(&self) -> bool {
            self.inner.picks_emission()
        }
        fn emission_picked(&self, p: glam::DVec3, u: f64) -> [f64; 3] {
            self.points.borrow_mut().push(Request { p, ask: Ask::EmissionPicked, u });
            self.inner.emission_picked(p, u)
        }
        fn walks_exactly(&self) -> bool {
            self.inner.walks_exactly()
        }
        fn exact_stretch(
            &self,
            ray: &Ray,
            t0: f64,
            t1: f64,
            kind: crate::medium::tracking::StretchKind,
            sampler: &mut Sampler,
        ) -> Option<crate::medium::tracking::StretchWalk> {
            self.inner.exact_stretch(ray, t0, t1, kind, sampler)
        }
    }
    /// Collisions and lookups compared on 400 rays per density scale.
    fn compare<F: Field>(field: &F, emission: Emission, lookup: PointLookup) -> (usize, usize) {
        let majorants = MajorantGrid::new(field.voxels().unwrap(), 0.0);
        let b = field.world_bounds();
        let mut rng = Sampler::new(11, 0, 0);
        let (mut collided, mut compared) = (0, 0);
        for sigma_t in [0.5, 20.0] {
            let medium = Medium {
                sigma_t,
                albedo: plume_core::color::Rgb::splat(0.8),
                g: 0.0,
                emission,
                extinction: Default::default(),
            };
            for k in 0..400u64 {
                let u = glam::DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64());
                let ray = Ray {
                    origin: b.lo + (b.hi - b.lo) * u,
                    direction: sample_uniform_sphere([rng.next_f64(), rng.next_f64()]),
                };
                let (estimator, need_collision) =
                    [(Estimator::Line, true), (Estimator::Line, false), (Estimator::Point, true)]
                        [(k % 3) as usize];
                let u = rng.next_f64();
                let points = Points::new(field, &medium, None, lookup);
                let tap = Tap { inner: &points, points: std::cell::RefCell::new(Vec::new()) };
                let real = null_track(
                    &majorants,
                    &tap,
                    &medium,
                    &ray,
                    f64::INFINITY,
                    estimator,
                    need_collision,
                    u,
                    &mut Sampler::new(3, k, 0),
                );
                let recorder = Recorder::mirroring(&points, usize::MAX);
                null_track(
                    &majorants,
                    &recorder,
                    &medium,
                    &ray,
                    f64::INFINITY,
                    estimator,
                    need_collision,
                    u,
                    &mut Sampler::new(3, k, 0),
                );
                let (real_points, recorded) = (tap.points.into_inner(), recorder.into_requests());
                let n = real_points.len();
                let bits = |r: &Request| (r.p.to_array().map(f64::to_bits), r.ask, r.u.to_bits());
                assert!(recorded.len() >= n, "ray {k}: fewer recorded lookups than real ones");
                assert!(
                    real_points.iter().map(bits).eq(recorded[..n].iter().map(bits)),
                    "ray {k}, σ_t {sigma_t}, {lookup:?}: recorded lookups differ from the real walk's"
                );
                collided += usize::from(matches!(
                    real.event,
                    crate::medium::DistanceSample::Collided { .. }
                ));
                compared += n;
            }
        }
        (collided, compared)
    }
    let (ex, emission) = hot_explosion();
    let volume =
        || Volume::build(&ex.density, Some(&ex.temperature), |v| emission.map_source(v)).unwrap();
    let linear = Trilinear::new(volume());
    assert!(
        Points::new(
            &linear,
            &Medium {
                sigma_t: 1.0,
                albedo: plume_core::color::Rgb::splat(0.8),
                g: 0.0,
                emission,
                extinction: Default::default()
            },
            None,
            PointLookup::Stochastic
        )
        .picks
    );
    for (collided, compared) in [
        compare(&volume(), emission, PointLookup::Exact),
        compare(&linear, emission, PointLookup::Exact),
        compare(&linear, emission, PointLookup::Stochastic),
        compare(&linear, emission, PointLookup::StochasticEmission),
    ] {
        assert!(
            // Dense stretches (σ_t 20) are walked exactly and look nothing up
            collided > 100 && compared > 1000,
            "{collided} collisions, {compared} lookups compared"
        );
    }
}
