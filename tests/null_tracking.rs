//! Null-collision tracking (METHOD.md §13): majorants bound every lookup,
//! delta-tracked free paths follow the exact law (χ² against regular tracking's optical
//! depth, nearest and trilinear), ratio tracking averages to τ, and every estimator's
//! emission agrees in mean with regular tracking. Fixed seeds; k·σ tolerances.

use crate::common;

use common::{chi2_test, mean_stderr};
use glam::DVec3;
use plume_core::sampling::Sampler;
use plume_engine::medium::null_tracking::{null_track, ratio_transmittance, PointSample};
use plume_engine::medium::tracking::optical_depth;
use plume_engine::medium::{
    track, Collision, Convention, DistanceSample, Emission, EmissionKind, Estimator, Medium,
    TemperatureMap,
};
use plume_synth::{explosion, ExplosionParams};
use plume_volume::field::{Field, Ray};
use plume_volume::majorant::{MajorantGrid, MAX_CELLS};
use plume_volume::trilinear::Trilinear;
use plume_volume::Volume;

fn volume() -> Volume {
    let ex = explosion(&ExplosionParams { resolution: 32, seed: 3, ..Default::default() });
    let e = medium().emission;
    Volume::build(&ex.density, Some(&ex.temperature), |v| e.map_source(v)).unwrap()
}

fn medium() -> Medium {
    let emission = Emission {
        kind: EmissionKind::Blackbody,
        convention: Convention::Physical,
        scale: 1e-3,
        color: plume_core::color::Rgb::ONE,
        temperature_map: TemperatureMap::Kelvin,
        cutoff_kelvin: 500.0,
    };
    Medium {
        sigma_t: 3.0,
        albedo: plume_core::color::Rgb::splat(0.8),
        g: 0.0,
        emission,
        extinction: Default::default(),
    }
}

/// The field at a point as the tracker reads it (no motion).
fn sampler_of<'a, F: Field>(field: &'a F, m: &'a Medium) -> impl Fn(DVec3) -> PointSample + 'a {
    move |p| {
        let v = field.reconstruct(p, &|d, s| m.emission.le(d, s));
        let source = field.values_at(p).source;
        PointSample { density: v.density, source, emission: v.emission, albedo: 1.0 }
    }
}

/// Rays through the explosion's middle, in several directions.
fn rays() -> Vec<Ray> {
    (0..6)
        .map(|i| {
            let a = f64::from(i) * 0.9;
            let dir = DVec3::new(a.cos(), 0.3 * (a * 1.7).sin(), a.sin()).normalize();
            Ray { origin: DVec3::new(0.1, 0.4, -0.2) - dir * 3.0, direction: dir }
        })
        .collect()
}

#[test]
fn majorants_bound_every_displaced_lookup() {
    let vol = volume();
    let tri = Trilinear::new(volume());
    let voxel = 4.0 / 32.0;
    // The finest level (5³ cells), and coarser ones as a large volume would take them
    for (displacement, max_cells) in
        [(0.0, MAX_CELLS), (2.5, MAX_CELLS), (11.0, MAX_CELLS), (0.0, 30), (2.5, 30), (0.0, 1)]
    {
        let grid = MajorantGrid::with_max_cells(&vol, displacement, max_cells);
        let mut s = Sampler::new(1, 0, 0);
        let mut checked = 0;
        for ray in rays() {
            for seg in grid.segments(&ray, 0.0, f64::INFINITY) {
                for _ in 0..80 {
                    let t = seg.t0 + s.next_f64() * (seg.t1 - seg.t0);
                    let offset =
                        DVec3::new(s.next_f64() - 0.5, s.next_f64() - 0.5, s.next_f64() - 0.5)
                            * (2.0 * displacement * voxel);
                    let p = ray.at(t) + offset;
                    let (dn, dt) = (
                        vol.values_at(p).density,
                        tri.reconstruct(p, &|_, _| plume_core::color::Rgb::ZERO).density,
                    );
                    assert!(
                        dn <= seg.bounds.density && dt <= seg.bounds.density,
                        "D {displacement}, {max_cells} cells: {dn}/{dt} above {:?}",
                        seg.bounds
                    );
                    checked += 1;
                }
            }
        }
        assert!(
            checked > 400,
            "D {displacement}, {max_cells} cells: too few points checked: {checked}"
        );
    }
}

/// A still volume's majorant on level 0 is the dual pyramid's node of the cell: the
/// union of the 8 bricks its points read (module docs of `volume::majorant`), not of the
/// 27 around a brick; and the dual nodes are strictly tighter than that somewhere here.
#[test]
fn majorants_are_the_dual_cells_bounds() {
    let vol = volume();
    let tri = Trilinear::new(volume());
    let grid = MajorantGrid::new(&vol, 0.0);
    assert_eq!(grid.cell_edge_voxels(), 8);
    let dual = &tri.dual_pyramid_levels()[0];
    let level0 = &vol.pyramid_levels()[0];
    let base = vol.index_bounds().lo + 0.5 - 8.0; // 8(brick_lo − 1)
    let world_from_index = vol.world_from_index();
    let mut looser = 0;
    for z in 0..dual.dims.z {
        for y in 0..dual.dims.y {
            for x in 0..dual.dims.x {
                let c = glam::IVec3::new(x, y, z);
                // A short ray inside the cell, away from its faces
                let p = base + c.as_dvec3() * 8.0 + DVec3::new(3.3, 4.1, 2.7);
                let ray = Ray {
                    origin: world_from_index.transform_point3(p),
                    direction: world_from_index.transform_vector3(DVec3::X).normalize(),
                };
                let segs: Vec<_> = grid.segments(&ray, 0.0, 1e-6).collect();
                assert_eq!(segs.len(), 1, "cell {c}: {segs:?}");
                let node = dual.get(c);
                assert_eq!(
                    (segs[0].bounds.density, segs[0].bounds.source),
                    (node.density_max, node.source_max),
                    "cell {c}"
                );
                // The bound the point had before: its brick's cell, the 27 bricks around
                // brick c − 1 (relative to the table), which hold the 8 of the dual cell
                let mut old = 0.0f32;
                for n in 0..27 {
                    let q = c - 1 + glam::IVec3::new(n % 3, (n / 3) % 3, n / 9) - 1;
                    if q.cmpge(glam::IVec3::ZERO).all() && q.cmplt(level0.dims).all() {
                        old = old.max(level0.get(q).density_max);
                    }
                }
                assert!(
                    old >= node.density_max,
                    "cell {c}: the dual bound {} above the old {old}",
                    node.density_max
                );
                looser += usize::from(old > node.density_max);
            }
        }
    }
    assert!(looser > 10, "the dual cells' bounds are tighter in only {looser} cells");
}

/// χ² of delta-tracked collision distances against the exact law `1 − e^{−OD(t)}` (OD by
/// regular tracking): 24 equal-probability bins of the collision distance plus escape.
fn free_path_chi2<F: Field>(name: &str, field: &F, vol: &Volume) {
    let m = medium();
    let grid = MajorantGrid::new(vol, 0.0);
    let eval = sampler_of(field, &m);
    let ray = rays()[1];
    let od = |t: f64| optical_depth(field, &m, &ray, t, f64::INFINITY).optical_depth;
    let total = od(f64::INFINITY);
    assert!(total > 1.0, "{name}: the ray is too thin to test ({total})");
    // Bin edges at equal probability: invert the CDF by bisection
    let bins = 24;
    let p_collide = 1.0 - (-total).exp();
    let mut edges = vec![0.0f64];
    for k in 1..bins {
        let target = -(1.0 - p_collide * f64::from(k) / f64::from(bins)).ln();
        let (mut lo, mut hi) = (0.0f64, 10.0f64);
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if od(mid) < target {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        edges.push(0.5 * (lo + hi));
    }
    let n = 60_000u64;
    let mut observed = vec![0.0f64; bins as usize + 1];
    for i in 0..n {
        let mut s = Sampler::new(7, 0, i);
        let u = s.next_f64();
        let r = null_track(&grid, &eval, &m, &ray, f64::INFINITY, Estimator::Line, true, u, &mut s);
        let k = match r.event {
            DistanceSample::Collided { t, .. } => edges.iter().rposition(|&e| t >= e).unwrap(),
            DistanceSample::Escaped => bins as usize,
        };
        observed[k] += 1.0;
    }
    let mut expected = vec![n as f64 * p_collide / f64::from(bins); bins as usize];
    expected.push(n as f64 * (1.0 - p_collide));
    chi2_test(name, &observed, &expected, 0.01, 2);
}

#[test]
fn delta_tracked_free_paths_follow_the_exact_law_nearest() {
    let vol = volume();
    free_path_chi2("delta tracking, nearest", &volume(), &vol);
}

#[test]
fn delta_tracked_free_paths_follow_the_exact_law_trilinear() {
    let vol = volume();
    free_path_chi2("delta tracking, trilinear (cubic cells)", &Trilinear::new(volume()), &vol);
}

#[test]
fn ratio_tracking_averages_to_the_transmittance() {
    let vol = volume();
    let tri = Trilinear::new(volume());
    let m = medium();
    let grid = MajorantGrid::new(&vol, 0.0);
    for (name, eval, exact) in [
        (
            "nearest",
            Box::new(sampler_of(&vol, &m)) as Box<dyn Fn(DVec3) -> PointSample>,
            Box::new(|r: &Ray, t: f64| optical_depth(&vol, &m, r, t, f64::INFINITY).optical_depth)
                as Box<dyn Fn(&Ray, f64) -> f64>,
        ),
        (
            "trilinear",
            Box::new(sampler_of(&tri, &m)),
            Box::new(|r: &Ray, t: f64| optical_depth(&tri, &m, r, t, f64::INFINITY).optical_depth),
        ),
    ] {
        for ray in rays().iter().take(3) {
            let tau = (-exact(ray, f64::INFINITY)).exp();
            let values: Vec<f64> = (0..20_000u64)
                .map(|i| {
                    ratio_transmittance(
                        &grid,
                        &eval,
                        &m,
                        ray,
                        f64::INFINITY,
                        &mut Sampler::new(11, 0, i),
                    )
                    .transmittance
                })
                .collect();
            let (mean, se) = mean_stderr(&values);
            assert!(
                (mean - tau).abs() < 4.0 * se + 1e-9,
                "{name}: ratio tracking {mean} ± {se} vs τ {tau}"
            );
        }
    }
}

#[test]
fn every_estimator_agrees_with_regular_tracking_in_mean() {
    // The same ray, nearest and trilinear: line, point and ray-march emission estimates
    // and the escape probability, null collisions against regular tracking
    let vol = volume();
    let tri = Trilinear::new(volume());
    let m = medium();
    let grid = MajorantGrid::new(&vol, 0.0);
    let ray = rays()[2];
    let n = 40_000u64;
    let check = |name: &str, regular: &dyn Fn(u64) -> [f64; 2], null: &dyn Fn(u64) -> [f64; 2]| {
        for c in 0..2 {
            let a: Vec<f64> = (0..n).map(|i| regular(i)[c]).collect();
            let b: Vec<f64> = (0..n).map(|i| null(i)[c]).collect();
            let ((ma, sa), (mb, sb)) = (mean_stderr(&a), mean_stderr(&b));
            assert!(
                (ma - mb).abs() < 4.0 * (sa * sa + sb * sb).sqrt() + 1e-12,
                "{name} {}: regular {ma} ± {sa} vs null {mb} ± {sb}",
                ["emission", "escape"][c]
            );
        }
    };
    for estimator in [Estimator::Line, Estimator::Point, Estimator::RayMarch] {
        let run_regular = |f: &dyn Fn(&mut Sampler, f64) -> plume_engine::medium::TrackResult,
                           i: u64| {
            let mut s = Sampler::new(21, 0, i);
            let u = s.next_f64();
            let r = f(&mut s, u);
            [r.emission[0], r.transmittance]
        };
        let (en, et) = (sampler_of(&vol, &m), sampler_of(&tri, &m));
        check(
            &format!("{estimator:?} nearest"),
            &|i| {
                run_regular(
                    &|s, u| {
                        track(&vol, &m, &ray, f64::INFINITY, estimator, Collision::Analog, u, s)
                    },
                    i,
                )
            },
            &|i| {
                run_regular(
                    &|s, u| null_track(&grid, &en, &m, &ray, f64::INFINITY, estimator, true, u, s),
                    i + n,
                )
            },
        );
        check(
            &format!("{estimator:?} trilinear"),
            &|i| {
                run_regular(
                    &|s, u| {
                        track(&tri, &m, &ray, f64::INFINITY, estimator, Collision::Analog, u, s)
                    },
                    i,
                )
            },
            &|i| {
                run_regular(
                    &|s, u| null_track(&grid, &et, &m, &ray, f64::INFINITY, estimator, true, u, s),
                    i + n,
                )
            },
        );
    }
}

#[test]
fn a_collision_record_holds_what_its_estimator_reads() {
    // The point estimator scores `L_e/μ` at the collision, so its record has the exact
    // density and source there; line and ray-march read only the albedo factor (their
    // record's density and source are NaN, by contract: nothing downstream reads them)
    let (vol, m) = (volume(), medium());
    let grid = MajorantGrid::new(&vol, 0.0);
    let exact = sampler_of(&vol, &m);
    let field = |p: DVec3| PointSample { albedo: 0.37, ..exact(p) };
    let ray = rays()[2];
    for estimator in [Estimator::Point, Estimator::Line, Estimator::RayMarch] {
        let mut collided = 0;
        for i in 0..200u64 {
            let mut s = Sampler::new(5, 0, i);
            let u = s.next_f64();
            let r = null_track(&grid, &field, &m, &ray, f64::INFINITY, estimator, true, u, &mut s);
            let DistanceSample::Collided { t, density, source, albedo, .. } = r.event else {
                continue;
            };
            collided += 1;
            assert_eq!(albedo, 0.37, "{estimator:?}: the albedo factor at the collision");
            if estimator == Estimator::Point {
                let v = vol.values_at(ray.at(t));
                assert_eq!((density, source), (v.density, v.source), "{estimator:?} at t = {t}");
                assert!(density > 0.0, "{estimator:?}: a collision where the density is 0");
            } else {
                assert!(
                    density.is_nan() && source.is_nan(),
                    "{estimator:?}: read {density}, {source} it does not use"
                );
            }
        }
        assert!(collided > 50, "{estimator:?}: only {collided} of 200 paths collided");
    }
}
