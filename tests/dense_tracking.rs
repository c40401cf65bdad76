//! Null-collision tracking through dense stretches (`medium::null_tracking`, "Dense
//! stretches"): where a majorant stretch would cost more tentative points than voxels,
//! the walk tracks it exactly with what is left of its exponential. The free path keeps
//! its law (χ² against regular tracking's optical depth), every estimator keeps its mean
//! (k·σ against regular tracking), and the work of a segment no longer grows with the
//! density: at a million times the density it is bounded by the voxels the ray crosses.
//! Fixed seeds.

use crate::common;

use common::{plume, s, stderr, tmpdir};

use std::cell::Cell;

use common::{chi2_test, mean_stderr};
use glam::DVec3;
use plume_core::sampling::Sampler;
use plume_engine::medium::null_tracking::{
    null_track, PointField, PointSample, DENSE_TENTATIVE_PER_VOXEL,
};
use plume_engine::medium::tracking::{optical_depth, walk_stretch, StretchKind, StretchWalk};
use plume_engine::medium::{
    track, Collision, Convention, DistanceSample, Emission, EmissionKind, Estimator, Medium,
    TemperatureMap, TrackResult,
};
use plume_synth::{explosion, ExplosionParams};
use plume_volume::field::{Field, Ray};
use plume_volume::majorant::MajorantGrid;
use plume_volume::trilinear::Trilinear;
use plume_volume::Volume;

fn volume() -> Volume {
    let ex = explosion(&ExplosionParams { resolution: 32, seed: 3, ..Default::default() });
    let e = medium(1.0).emission;
    Volume::build(&ex.density, Some(&ex.temperature), |v| e.map_source(v)).unwrap()
}

/// The explosion's medium with `sigma_t` (a 4 m cube of 32³ voxels crosses about 8
/// voxels per metre along an axis, so `sigma_t` 30 makes its denser stretches dense and
/// leaves the thinner ones to tentative points).
fn medium(sigma_t: f64) -> Medium {
    let emission = Emission {
        kind: EmissionKind::Blackbody,
        convention: Convention::Physical,
        scale: 1e-3,
        color: plume_core::color::Rgb::ONE,
        temperature_map: TemperatureMap::Kelvin,
        cutoff_kelvin: 500.0,
    };
    Medium {
        sigma_t,
        albedo: plume_core::color::Rgb::splat(0.8),
        g: 0.0,
        emission,
        extinction: Default::default(),
    }
}

/// A still volume as null collisions read it, able to walk its voxels exactly, and
/// counting the tentative points it is asked for.
struct Still<'a, F: Field> {
    field: &'a F,
    medium: &'a Medium,
    tentative: Cell<u64>,
}

impl<'a, F: Field> Still<'a, F> {
    fn new(field: &'a F, medium: &'a Medium) -> Self {
        Still { field, medium, tentative: Cell::new(0) }
    }
}

impl<F: Field> PointField for Still<'_, F> {
    fn density(&self, p: DVec3) -> f32 {
        self.tentative.set(self.tentative.get() + 1);
        self.field.values_at(p).density
    }
    fn emission(&self, p: DVec3) -> [f64; 3] {
        self.field.reconstruct(p, &|d, s| self.medium.emission.le(d, s)).emission
    }
    fn sample(&self, p: DVec3, emission: bool) -> PointSample {
        let v = self.field.reconstruct(p, &|d, s| self.medium.emission.le(d, s));
        let source = self.field.values_at(p).source;
        let emission = if emission { v.emission } else { [0.0; 3] };
        PointSample { density: v.density, source, emission, albedo: 1.0 }
    }
    fn walks_exactly(&self) -> bool {
        true
    }
    fn exact_stretch(
        &self,
        ray: &Ray,
        t0: f64,
        t1: f64,
        kind: StretchKind,
        sampler: &mut Sampler,
    ) -> Option<StretchWalk> {
        Some(walk_stretch(self.field, self.medium, ray, t0, t1, kind, sampler))
    }
}

/// Rays through the explosion's middle, in several directions.
fn ray(i: u32) -> Ray {
    let a = f64::from(i) * 0.9;
    let dir = DVec3::new(a.cos(), 0.3 * (a * 1.7).sin(), a.sin()).normalize();
    Ray { origin: DVec3::new(0.1, 0.4, -0.2) - dir * 3.0, direction: dir }
}

#[test]
fn free_paths_through_dense_stretches_follow_the_exact_law() {
    let vol = volume();
    let tri = Trilinear::new(volume());
    let m = medium(30.0);
    let grid = MajorantGrid::new(&vol, 0.0);
    let check = |name: &str, field: &dyn Fn(&Ray, f64, &mut Sampler) -> TrackResult| {
        let r = ray(1);
        let od = |t: f64| optical_depth(&vol, &m, &r, t, f64::INFINITY).optical_depth;
        // Equal-probability bins of the collision distance, by bisection of the CDF
        let bins = 24u32;
        let p = 1.0 - (-od(f64::INFINITY)).exp();
        let edges: Vec<f64> = (0..bins)
            .map(|k| {
                let target = -(1.0 - p * f64::from(k) / f64::from(bins)).ln();
                let (mut lo, mut hi) = (0.0f64, 10.0f64);
                for _ in 0..60 {
                    let mid = 0.5 * (lo + hi);
                    (lo, hi) = if od(mid) < target { (mid, hi) } else { (lo, mid) };
                }
                0.5 * (lo + hi)
            })
            .collect();
        let n = 40_000u64;
        let mut observed = vec![0.0f64; bins as usize + 1];
        let mut exact_walks = 0u64;
        for i in 0..n {
            let mut s = Sampler::new(7, 0, i);
            let u = s.next_f64();
            let result = field(&r, u, &mut s);
            exact_walks += u64::from(result.voxel_steps > u64::from(result.segments));
            let k = match result.event {
                DistanceSample::Collided { t, .. } => edges.iter().rposition(|&e| t >= e).unwrap(),
                DistanceSample::Escaped => bins as usize,
            };
            observed[k] += 1.0;
        }
        assert!(exact_walks > n / 10, "{name}: {exact_walks} of {n} walks met a dense stretch");
        let mut expected = vec![n as f64 * p / f64::from(bins); bins as usize];
        expected.push(n as f64 * (1.0 - p));
        chi2_test(name, &observed, &expected, 0.01, 2);
    };
    // Nearest: regular tracking's optical depth is the law; the same for the trilinear
    // field against its own
    let still = Still::new(&vol, &m);
    check("dense nearest", &|r, u, s| {
        null_track(&grid, &still, &m, r, f64::INFINITY, Estimator::Line, true, u, s)
    });
    let tri_still = Still::new(&tri, &m);
    let tri_od = |r: &Ray, t: f64| optical_depth(&tri, &m, r, t, f64::INFINITY).optical_depth;
    assert!(tri_od(&ray(1), f64::INFINITY) > 1.0);
    let r = ray(1);
    let n = 20_000u64;
    let (mut escaped_null, mut escaped_exact) = (0.0, 0.0);
    for i in 0..n {
        let mut s = Sampler::new(9, 0, i);
        let u = s.next_f64();
        let a =
            null_track(&grid, &tri_still, &m, &r, f64::INFINITY, Estimator::Line, true, u, &mut s);
        escaped_null += f64::from(u8::from(a.event == DistanceSample::Escaped));
        let mut s = Sampler::new(9, 1, i);
        let u = s.next_f64();
        let b = track(&tri, &m, &r, f64::INFINITY, Estimator::Line, Collision::Analog, u, &mut s);
        escaped_exact += f64::from(u8::from(b.event == DistanceSample::Escaped));
    }
    let (pa, pb) = (escaped_null / n as f64, escaped_exact / n as f64);
    let sigma = (pb * (1.0 - pb) * 2.0 / n as f64).sqrt();
    assert!((pa - pb).abs() < 4.0 * sigma + 1e-9, "trilinear escape: {pa} vs {pb} ± {sigma}");
}

/// One walk per sample index.
type Walk<'a> = &'a dyn Fn(u64) -> TrackResult;

#[test]
fn every_estimator_keeps_its_mean_through_dense_stretches() {
    let vol = volume();
    let tri = Trilinear::new(volume());
    let m = medium(30.0);
    let grid = MajorantGrid::new(&vol, 0.0);
    let n = 30_000u64;
    let r = ray(2);
    for estimator in [Estimator::Line, Estimator::Point, Estimator::RayMarch] {
        let fields: [(&str, Walk<'_>, Walk<'_>); 2] = [
            (
                "nearest",
                &|i| {
                    let mut s = Sampler::new(21, 0, i);
                    let u = s.next_f64();
                    track(&vol, &m, &r, f64::INFINITY, estimator, Collision::Analog, u, &mut s)
                },
                &|i| {
                    let still = Still::new(&vol, &m);
                    let mut s = Sampler::new(21, 1, i);
                    let u = s.next_f64();
                    null_track(&grid, &still, &m, &r, f64::INFINITY, estimator, true, u, &mut s)
                },
            ),
            (
                "trilinear",
                &|i| {
                    let mut s = Sampler::new(22, 0, i);
                    let u = s.next_f64();
                    track(&tri, &m, &r, f64::INFINITY, estimator, Collision::Analog, u, &mut s)
                },
                &|i| {
                    let still = Still::new(&tri, &m);
                    let mut s = Sampler::new(22, 1, i);
                    let u = s.next_f64();
                    null_track(&grid, &still, &m, &r, f64::INFINITY, estimator, true, u, &mut s)
                },
            ),
        ];
        for (name, regular, hybrid) in fields {
            let a: Vec<TrackResult> = (0..n).map(regular).collect();
            let b: Vec<TrackResult> = (0..n).map(hybrid).collect();
            assert!(
                b.iter().filter(|r| r.voxel_steps > u64::from(r.segments)).count() as u64 > n / 10,
                "{estimator:?} {name}: too few walks met a dense stretch"
            );
            for (what, value) in [
                ("emission", &(|r: &TrackResult| r.emission[0]) as &dyn Fn(&TrackResult) -> f64),
                ("escape", &|r: &TrackResult| {
                    f64::from(u8::from(r.event == DistanceSample::Escaped))
                }),
                ("transmittance", &|r: &TrackResult| r.transmittance),
            ] {
                let (ma, sa) = mean_stderr(&a.iter().map(value).collect::<Vec<_>>());
                let (mb, sb) = mean_stderr(&b.iter().map(value).collect::<Vec<_>>());
                assert!(
                    (ma - mb).abs() < 4.0 * (sa * sa + sb * sb).sqrt() + 1e-12,
                    "{estimator:?} {name} {what}: regular {ma} ± {sa} vs dense-aware null {mb} ± {sb}"
                );
            }
        }
    }
}

#[test]
fn the_work_of_a_segment_is_bounded_by_its_voxels_at_any_density() {
    // Tentative points plus voxel steps per walk, averaged over walks, at density scales
    // 1 … 10⁶. The bound: a stretch is left to tentative points only while its majorant
    // is below DENSE_TENTATIVE_PER_VOXEL points per voxel crossed, so tentative points
    // cost at most about that many per voxel of the ray (plus one per stretch for the
    // exponential's overshoot), and an exact stretch costs one step per voxel. So the work
    // is at most (1 + DENSE) × the voxels the whole ray crosses, plus the stretches; and
    // it may not grow by more than 2× from the scale-1 walk to the densest.
    let vol = volume();
    let grid = MajorantGrid::new(&vol, 0.0);
    let r = ray(3);
    // Voxels the whole ray crosses inside the grid (regular tracking's walk, escaping)
    let crossing = optical_depth(&vol, &medium(1.0), &r, f64::INFINITY, f64::INFINITY);
    let voxels = crossing.voxel_steps as f64;
    let stretches = grid.segments(&r, 0.0, f64::INFINITY).count() as f64;
    let bound = (1.0 + DENSE_TENTATIVE_PER_VOXEL) * voxels + stretches;
    let n = 2_000u64;
    let work = |sigma_t: f64, estimator: Estimator| {
        let m = medium(sigma_t);
        let still = Still::new(&vol, &m);
        let (mut steps, mut counted) = (0u64, 0u64);
        for i in 0..n {
            let mut s = Sampler::new(5, 0, i);
            let u = s.next_f64();
            let t = null_track(&grid, &still, &m, &r, f64::INFINITY, estimator, true, u, &mut s);
            steps += t.voxel_steps + t.tentative_points;
            counted += t.tentative_points;
        }
        // The walk counts exactly the density reads it makes
        assert_eq!(counted, still.tentative.get(), "{estimator:?}: counted tentative points");
        steps as f64 / n as f64
    };
    for estimator in [Estimator::Line, Estimator::Point, Estimator::RayMarch] {
        let base = work(3.0, estimator);
        for scale in [1e2, 1e4, 1e6] {
            let w = work(3.0 * scale, estimator);
            assert!(
                w <= bound,
                "{estimator:?} at {scale:e}: {w:.1} tentative points + voxel steps per walk, bound {bound:.1} ({voxels} voxels, {stretches} stretches)"
            );
            assert!(
                w <= 2.0 * base.max(1.0),
                "{estimator:?} at {scale:e}: {w:.1} against {base:.1} at 1"
            );
        }
    }
}

/// The counters of a `plume render` of `ex` at `density_scale` with `method`, albedo 0.8.
fn render_counters(ex: &std::path::Path, method: &str, density_scale: f64) -> serde_json::Value {
    let dir = ex.parent().unwrap();
    let stats = dir.join(format!("{method}-{density_scale:e}.json"));
    let scale = density_scale.to_string();
    let o = plume(&[
        "render",
        s(ex),
        "-o",
        s(&dir.join(format!("{method}-{density_scale:e}.exr"))),
        "--stats",
        s(&stats),
        "--method",
        method,
        "--albedo",
        "0.8",
        "--density-scale",
        &scale,
        "--spp",
        "2",
        "--width",
        "24",
        "--height",
        "24",
        "-q",
    ]);
    assert!(o.status.success(), "{method} at {density_scale:e}: {}", stderr(&o));
    let st: serde_json::Value = serde_json::from_slice(&std::fs::read(&stats).unwrap()).unwrap();
    st["counters"].clone()
}

#[test]
fn a_whole_render_at_a_million_times_the_density_does_bounded_work() {
    // Through the binary with each method's defaults. The bound per walk (a camera or
    // scattered segment, or a shadow ray): in an n³ grid a ray crosses at most 3n voxels;
    // an exact walk steps once per voxel, and pyramid nodes skipped or majorant stretches
    // entered are at most one per voxel crossed; a stretch left to tentative points holds
    // at most DENSE_TENTATIVE_PER_VOXEL of them per voxel on average. So a walk costs at
    // most (2 + DENSE) · 3n tentative points plus voxel steps, on average over walks;
    // before dense stretches were walked exactly, a walk at 10⁶ cost about σ̄·L, millions.
    // And the work per walk may not grow more than 2× from the density as generated.
    let n = 32u32;
    let ex = common::explosion(&tmpdir("dense", "render"), n, Some(4));
    let bound = (2.0 + DENSE_TENTATIVE_PER_VOXEL) * 3.0 * f64::from(n);
    for method in ["line-fnee", "line-nee", "point-nee", "ray-march"] {
        let per_walk = |c: &serde_json::Value| {
            let work = c["voxel_steps"].as_u64().unwrap() + c["tentative_points"].as_u64().unwrap();
            work as f64 / c["walks"].as_u64().unwrap() as f64
        };
        let base = render_counters(&ex, method, 1.0);
        let dense = render_counters(&ex, method, 1e6);
        assert!(dense["collisions"].as_u64().unwrap() > base["collisions"].as_u64().unwrap());
        let (w1, w6) = (per_walk(&base), per_walk(&dense));
        assert!(w6 <= bound, "{method}: {w6:.1} per walk at 1e6, bound {bound:.0}: {dense}");
        assert!(w6 <= 2.0 * w1, "{method}: {w6:.2} per walk at 1e6 against {w1:.2} at 1");
    }
}
