//! External lights: suns, sphere and point lights against single-scattering closed forms
//! in a thin homogeneous slab; light sampling against its own pdf; MIS weights summing to
//! one; environment maps' orientation.
//! Fixed seeds; k·σ tolerances from the samples' own spread.

use crate::common;

use common::{grid, grid_emission, mean_stderr_from_sums};
use glam::{DAffine3, DMat3, DVec3, IVec3};
use plume_core::color::Rgb;
use plume_core::sampling::phase::hg_pdf;
use plume_core::sampling::Sampler;
use plume_engine::camera::Camera;
use plume_engine::integrator::{
    Counters, Integrator, LightSampling, Lights, MisHeuristic, NoTrace, Scene, Tracking,
};
use plume_engine::light::external::{
    Distant, Environment, ExternalLights, Light, Radiance, Sphere,
};
use plume_engine::medium::{Collision, Convention, Emission, EmissionKind, Estimator, Medium};
use plume_volume::field::Ray;
use plume_volume::Volume;

/// Half-width of the slab (world units): wide enough that light entering through its
/// sides does not reach the camera ray's neighbourhood.
const HALF: f64 = 16.0;
/// Thickness of the slab, `z ∈ [0, D]`.
const D: f64 = 0.1;
const SIGMA_T: f64 = 5.0;
const ALBEDO: f32 = 0.8;
const G: f64 = 0.3;

/// A homogeneous slab `[−HALF, HALF]² × [0, D]` of unit density, without emission.
fn slab() -> Volume {
    let n = 8; // leaves a side
    let xf = DAffine3::from_mat3_translation(
        DMat3::from_diagonal(DVec3::new(
            2.0 * HALF / f64::from(8 * n),
            2.0 * HALF / f64::from(8 * n),
            D / 8.0,
        )),
        DVec3::new(-HALF + HALF / f64::from(8 * n), -HALF + HALF / f64::from(8 * n), D / 16.0),
    );
    let leaves: Vec<IVec3> = (0..n * n).map(|i| IVec3::new(i % n, i / n, 0) * 8).collect();
    let e = grid_emission(Convention::Cycles);
    Volume::build(&grid("density", xf, &leaves, |_| 1.0), None, |v| e.map_source(v)).unwrap()
}

fn medium() -> Medium {
    Medium {
        sigma_t: SIGMA_T,
        albedo: plume_core::color::Rgb::splat(ALBEDO),
        g: G,
        emission: Emission { kind: EmissionKind::None, ..grid_emission(Convention::Cycles) },
        extinction: Default::default(),
    }
}

/// The slab seen along +z from below through its centre, lit by `lights`.
fn scene(lights: Vec<Light>) -> Scene<Volume> {
    let cam =
        Camera::look_at(DVec3::new(0.0, 0.0, -1.0), DVec3::ZERO, DVec3::Y, 1.0, 1, 1).unwrap();
    let lights = Lights { external: ExternalLights::new(lights, HALF), ..Lights::default() };
    Scene { field: slab(), medium: medium(), camera: cam, lights, motion: None, majorants: None }
}

/// Mean radiance (red) and its standard error along the camera's central ray, single
/// scattering only (`max_depth = 1`).
fn single_scattering(scene: &Scene<Volume>, estimator: Estimator, n: u64, seed: u64) -> (f64, f64) {
    let integ = Integrator {
        estimator,
        camera_estimator: None,
        light_sampling: LightSampling::None,
        mis: MisHeuristic::Power,
        max_depth: 1,
        tracking: Tracking::Regular,
        split: 1,
        camera_collision: Collision::Analog,
        point_lookup: plume_engine::integrator::PointLookup::Exact,
        split_by: plume_engine::integrator::SplitBy::Uniform,
    };
    let ray = Ray { origin: DVec3::new(0.0, 0.0, -1.0), direction: DVec3::Z };
    let (mut s, mut s2) = (0.0, 0.0);
    let mut c = Counters::default();
    for i in 0..n {
        let mut sampler = Sampler::new(seed, 0, i);
        let l = integ.li(scene, &ray, &mut sampler, &mut c, &mut NoTrace)[0];
        s += l;
        s2 += l * l;
    }
    mean_stderr_from_sums(s, s2, n)
}

/// `∫₀^D σ_s e^{−σ_t s} e^{−σ_t (D − s)/μ} ds` for light arriving at cosine `μ` to the
/// slab's normal through its top face: the slab's single-scattering kernel.
fn kernel(mu: f64) -> f64 {
    let sigma_s = SIGMA_T * f64::from(ALBEDO);
    let k = SIGMA_T * (1.0 - 1.0 / mu);
    let inner = if k.abs() < 1e-12 { D } else { -(-k * D).exp_m1() / k };
    sigma_s * (-SIGMA_T * D / mu).exp() * inner
}

#[test]
fn sun_over_a_thin_slab_matches_single_scattering() {
    // A delta sun at 40° from the normal: L = E f(cos α) K(cos α)
    let alpha = 40f64.to_radians();
    let to_light = DVec3::new(alpha.sin(), 0.0, alpha.cos());
    let e = 3.0;
    for estimator in [Estimator::Line, Estimator::Point, Estimator::RayMarch] {
        let sc = scene(vec![Light::Distant(Distant::new(-to_light, Rgb::splat(e as f32), 0.0))]);
        let expected = e * hg_pdf(G, alpha.cos()) * kernel(alpha.cos());
        let (m, se) = single_scattering(&sc, estimator, 40_000, 7);
        assert!(
            (m - expected).abs() < 4.0 * se + 1e-4 * expected,
            "{estimator:?}: {m} ± {se} vs closed form {expected}"
        );
        assert!(se < 0.05 * expected, "{estimator:?}: noise {se} of {expected}");
    }
}

#[test]
fn wide_distant_light_matches_single_scattering_with_mis() {
    // A disc of 40° diameter centred 50° from the normal: forward paths hit it often, so
    // light sampling and phase sampling both carry it and MIS must split it exactly.
    // Closed form: the kernel integrated over the disc by a midpoint rule.
    let (centre, half) = (50f64.to_radians(), 20f64.to_radians());
    let to_light = DVec3::new(centre.sin(), 0.0, centre.cos());
    let e = 2.0;
    let light = Distant::new(-to_light, Rgb::splat(e as f32), 2.0 * half);
    let radiance = e / (std::f64::consts::PI * half.sin().powi(2));
    let (t1, t2) = (DVec3::new(centre.cos(), 0.0, -centre.sin()), DVec3::Y);
    let (nt, np) = (400, 400);
    let mut expected = 0.0;
    for i in 0..nt {
        let th = (f64::from(i) + 0.5) / f64::from(nt) * half;
        let dth = half / f64::from(nt);
        for j in 0..np {
            let ph = (f64::from(j) + 0.5) / f64::from(np) * std::f64::consts::TAU;
            let w = to_light * th.cos() + (t1 * ph.cos() + t2 * ph.sin()) * th.sin();
            let d_omega = th.sin() * dth * std::f64::consts::TAU / f64::from(np);
            expected += radiance * hg_pdf(G, w.z) * kernel(w.z) * d_omega;
        }
    }
    for mis in [MisHeuristic::Power, MisHeuristic::Balance] {
        let sc = scene(vec![Light::Distant(light.clone())]);
        let integ = Integrator {
            estimator: Estimator::Line,
            camera_estimator: None,
            light_sampling: LightSampling::None,
            mis,
            max_depth: 1,
            tracking: Tracking::Regular,
            split: 1,
            camera_collision: Collision::Analog,
            point_lookup: plume_engine::integrator::PointLookup::Exact,
            split_by: plume_engine::integrator::SplitBy::Uniform,
        };
        let ray = Ray { origin: DVec3::new(0.0, 0.0, -1.0), direction: DVec3::Z };
        let (mut s, mut s2, n) = (0.0, 0.0, 60_000u64);
        let mut c = Counters::default();
        for i in 0..n {
            let l = integ.li(&sc, &ray, &mut Sampler::new(5, 0, i), &mut c, &mut NoTrace)[0];
            s += l;
            s2 += l * l;
        }
        let (m, se) = mean_stderr_from_sums(s, s2, n);
        assert!(
            (m - expected).abs() < 4.0 * se + 1e-4 * expected,
            "{mis:?}: {m} ± {se} vs {expected}"
        );
    }
}

/// Single scattering from a point light at `p` (above the slab) along the camera ray:
/// `∫₀^D σ_s e^{−σ_t s} f(cos θ) I e^{−σ_t ℓ(s)} / r(s)² ds` by a midpoint rule, `ℓ` the
/// path inside the slab.
fn point_light_closed_form(p: DVec3, intensity: f64) -> f64 {
    let sigma_s = SIGMA_T * f64::from(ALBEDO);
    let n = 20_000;
    let mut sum = 0.0;
    for i in 0..n {
        let s = (f64::from(i) + 0.5) / f64::from(n) * D;
        let x = DVec3::new(0.0, 0.0, s);
        let to = p - x;
        let r = to.length();
        let w = to / r;
        let inside = (D - s) / w.z;
        sum +=
            sigma_s * (-SIGMA_T * s).exp() * hg_pdf(G, w.z) * intensity * (-SIGMA_T * inside).exp()
                / (r * r)
                * (D / f64::from(n));
    }
    sum
}

#[test]
fn point_and_small_sphere_lights_match_single_scattering() {
    let p = DVec3::new(0.3, 0.2, 0.6);
    let power = 50.0;
    let intensity = power / (4.0 * std::f64::consts::PI);
    let expected = point_light_closed_form(p, intensity);
    // A point light, and a sphere small enough that it acts as one to 1e-5 (r²/d² ≈ 1e-6)
    for (radius, label) in [(0.0, "point"), (6e-4, "sphere")] {
        let sc = scene(vec![Light::Sphere(Sphere::new(p, radius, Rgb::splat(power as f32)))]);
        let (m, se) = single_scattering(&sc, Estimator::Line, 40_000, 9);
        assert!(
            (m - expected).abs() < 4.0 * se + 1e-4 * expected,
            "{label}: {m} ± {se} vs {expected}"
        );
    }
}

#[test]
fn light_pdfs_agree_with_sampling_and_mis_weights_sum_to_one() {
    // For every light type: the pdf the integrator evaluates for a forward direction is
    // the one light sampling used for that direction, and w_light + w_phase = 1.
    let lights = vec![
        Light::Distant(Distant::new(
            DVec3::new(0.2, -0.3, -1.0).normalize(),
            Rgb::splat(2.0),
            10f64.to_radians(),
        )),
        Light::Distant(Distant::new(DVec3::new(-0.5, 0.1, -1.0).normalize(), Rgb::splat(1.0), 0.0)),
        Light::Sphere(Sphere::new(DVec3::new(1.0, 2.0, 3.0), 0.5, Rgb::splat(100.0))),
        Light::Sphere(Sphere::new(DVec3::new(-1.0, 0.0, 2.0), 0.0, Rgb::splat(10.0))),
        Light::Environment(Environment::new(
            Radiance::Constant(Rgb([0.1, 0.2, 0.3])),
            1.0,
            DVec3::Z,
            0.3,
            true,
        )),
    ];
    let set = ExternalLights::new(lights, 2.0).unwrap();
    let pmf_total: f64 = (0..5).map(|i| set.pmf(i)).sum();
    assert!((pmf_total - 1.0).abs() < 1e-12, "light choice pmfs sum to {pmf_total}");
    let x = DVec3::new(0.1, -0.2, 0.3);
    let mut sampler = Sampler::new(1, 0, 0);
    let mut seen = [0u32; 5];
    for _ in 0..20_000 {
        let (uc, u) = (sampler.next_f64(), [sampler.next_f64(), sampler.next_f64()]);
        let Some(c) = set.sample(x, uc, u) else { continue };
        seen[c.index] += 1;
        let s = c.sample;
        assert!((s.direction.length() - 1.0).abs() < 1e-12);
        let pdf = set.pdf(c.index, x, s.direction);
        if s.pdf == 0.0 {
            assert_eq!(pdf, 0.0, "a delta light has no density for forward paths");
            continue;
        }
        assert!(
            (pdf - c.pmf * s.pdf).abs() <= 1e-9 * pdf,
            "light {}: pdf {pdf} vs sampled {}",
            c.index,
            c.pmf * s.pdf
        );
        let f = hg_pdf(0.4, DVec3::X.dot(s.direction));
        for mis in [MisHeuristic::Power, MisHeuristic::Balance] {
            let sum = mis.weight(pdf, f) + mis.weight(f, pdf);
            assert!((sum - 1.0).abs() < 1e-12, "weights sum to {sum}");
        }
    }
    assert!(seen.iter().all(|&n| n > 0), "every light is chosen: {seen:?}");
}

#[test]
fn sphere_light_intersection_and_cone_are_consistent() {
    let s = Sphere::new(DVec3::new(0.0, 0.0, 5.0), 1.0, Rgb::ONE);
    let x = DVec3::ZERO;
    let mut sampler = Sampler::new(2, 0, 0);
    for _ in 0..10_000 {
        let ls = s.sample(x, [sampler.next_f64(), sampler.next_f64()]).unwrap();
        // Every sampled direction hits the sphere at the distance it reports
        let t = s
            .intersect(&Ray { origin: x, direction: ls.direction })
            .expect("a sampled direction hits the sphere");
        assert!((t - ls.distance).abs() < 1e-9, "{t} vs {}", ls.distance);
        let p = x + ls.direction * t;
        assert!(((p - DVec3::new(0.0, 0.0, 5.0)).length() - 1.0).abs() < 1e-9);
    }
    // Irradiance at x facing the sphere: Φ/(4π d²), by light sampling
    let (mut sum, n) = (0.0, 100_000);
    for _ in 0..n {
        let ls = s.sample(x, [sampler.next_f64(), sampler.next_f64()]).unwrap();
        sum += ls.value[0] * ls.direction.z;
    }
    let e = sum / f64::from(n);
    let expected = 1.0 / (4.0 * std::f64::consts::PI * 25.0);
    assert!((e - expected).abs() < 2e-3 * expected, "sphere irradiance {e} vs {expected}");
    // From inside, nothing; behind the origin, no hit
    assert!(s.sample(DVec3::new(0.0, 0.0, 5.2), [0.5, 0.5]).is_none());
    assert!(s.intersect(&Ray { origin: x, direction: -DVec3::Z }).is_none());
}

#[test]
fn environment_maps_follow_the_up_axis_and_turn_counter_clockwise() {
    use plume_engine::light::envmap::EnvironmentMap;
    // A 16×8 map, bright around its +x direction (u = ½, the equator) and along its top
    // row (the zenith)
    let (w, h) = (16u32, 8u32);
    let pixels: Vec<Rgb> = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            if (x == 7 || x == 8) && (y == 3 || y == 4) {
                Rgb([5.0, 0.0, 0.0])
            } else if y == 0 {
                Rgb([0.0, 0.0, 3.0])
            } else {
                Rgb::splat(0.1)
            }
        })
        .collect();
    let map = || {
        Radiance::Map(Box::new(
            EnvironmentMap::from_pixels(w, h, pixels.clone(), "test map").unwrap(),
        ))
    };
    let red = |e: &Environment, d: DVec3| e.radiance(d.normalize())[0];
    let blue = |e: &Environment, d: DVec3| e.radiance(d.normalize())[2];
    // +z up: +x sees the red patch, +z the blue zenith
    let z_up = Environment::new(map(), 1.0, DVec3::Z, 0.0, true);
    assert_eq!(red(&z_up, DVec3::X), 5.0);
    assert_eq!(red(&z_up, DVec3::Y), f64::from(0.1f32));
    assert_eq!(blue(&z_up, DVec3::Z), 3.0);
    // Turned 90° counter-clockwise seen from above: the patch moves from +x to +y
    let turned = Environment::new(map(), 1.0, DVec3::Z, 90f64.to_radians(), true);
    assert_eq!(red(&turned, DVec3::Y), 5.0);
    assert_eq!(red(&turned, DVec3::X), f64::from(0.1f32));
    // +y up: the zenith is +y, +x still sees the patch; the intensity scales
    let y_up = Environment::new(map(), 2.0, DVec3::Y, 0.0, true);
    assert_eq!(blue(&y_up, DVec3::Y), 6.0);
    assert_eq!(red(&y_up, DVec3::X), 10.0);
    assert_eq!(blue(&y_up, DVec3::Z), 2.0 * f64::from(0.1f32));
    // Sampling follows the frame: a sampled world direction has the radiance and pdf that
    // looking it up gives
    let mut sampler = Sampler::new(4, 0, 0);
    for e in [&z_up, &turned, &y_up] {
        for _ in 0..1000 {
            let Some(ls) = e.sample([sampler.next_f64(), sampler.next_f64()]) else { continue };
            let (l, pdf) = (e.radiance(ls.direction), e.pdf(ls.direction));
            assert!((ls.pdf - pdf).abs() <= 1e-9 * pdf, "pdf {} vs {pdf}", ls.pdf);
            for (v, l) in ls.value.iter().zip(l) {
                assert!((v * ls.pdf - l).abs() <= 1e-9 * l.max(1e-12), "{} vs {l}", v * ls.pdf);
            }
        }
    }
}
