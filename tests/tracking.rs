//! Tracking (`--tracking`, `integrator::tracker`): null collisions through a still volume,
//! after scattering (`mixed`, the default where it applies) or on every segment (`null`),
//! give the image regular tracking gives, in the mean, for every estimator and light
//! strategy that can use them, on thin and dense explosions, nearest and trilinear; the
//! majorants bound every lookup; the choice is a key of scenes, flags and the settings
//! hash, and combinations null collisions cannot serve are refused with one line. Fixed
//! seeds; k·σ tolerances from independent runs.

use crate::common;

use common::{explosion, explosion_volume, plume, plume_exits, region_means_with, s, tmpdir};
use glam::DVec3;
use plume_core::sampling::{Sampler, SamplerKind};
use plume_engine::integrator::{
    AnyScene, Integrator, LightSampling, Lights, MisHeuristic, PointLookup, Tracking,
};
use plume_engine::medium::{Collision, Estimator};
use plume_scene::TrackingChoice;
use plume_volume::field::{Field, Ray};
use plume_volume::majorant::{MajorantGrid, MAX_CELLS};
use plume_volume::Interpolation;

/// The generated explosion, with majorants for null collisions.
fn scene(sigma_t: f64, ls: LightSampling, interpolation: Interpolation) -> AnyScene {
    common::explosion_scene(sigma_t, interpolation, true, |vol, e| {
        Lights::build(vol, e, ls, 8).unwrap()
    })
}

fn integrator(
    estimator: Estimator,
    light_sampling: LightSampling,
    tracking: Tracking,
) -> Integrator {
    Integrator {
        estimator,
        camera_estimator: None,
        light_sampling,
        mis: MisHeuristic::Power,
        max_depth: 64,
        tracking,
        split: 1,
        camera_collision: Collision::Analog,
        point_lookup: PointLookup::Exact,
        split_by: plume_engine::integrator::SplitBy::Uniform,
    }
}

#[test]
fn null_collisions_give_the_image_means_of_regular_tracking() {
    // Per reconstruction and density: a regular line-fnee reference, then every estimator
    // × light strategy null collisions serve, mixed and null; trilinear with the default
    // point lookups (picked densities) and with emission points picked too
    // (`tests/point_lookup.rs`; exact lookups: `tests/motion_blur.rs`). 3 × 2 × 6 × 2 × 5 regions
    // = 330 comparisons (line + classic NEE only in the thin ones); Šidák at α = 0.01
    // gives |z| < 4.3 per test. Null collisions draw their tentative points from the
    // hashed stream (not Sobol), so their run means have heavier tails: 24 runs of 16 spp
    // keep the spread an honest standard error.
    let combos = [
        (Estimator::Line, LightSampling::Fnee),
        (Estimator::Line, LightSampling::None),
        (Estimator::Point, LightSampling::Fnee),
        (Estimator::RayMarch, LightSampling::None),
        (Estimator::RayMarch, LightSampling::Fnee),
        (Estimator::Line, LightSampling::Nee),
    ];
    let reconstructions = [
        (Interpolation::Nearest, PointLookup::Exact),
        (Interpolation::Linear, PointLookup::Stochastic),
        (Interpolation::Linear, PointLookup::StochasticEmission),
    ];
    for ((interpolation, lookup), sigma_t) in
        reconstructions.into_iter().flat_map(|r| [(r, 1.5), (r, 25.0)])
    {
        let reference_scene = scene(sigma_t, LightSampling::Fnee, interpolation);
        let reference = region_means_with(
            SamplerKind::Sobol,
            &reference_scene,
            integrator(Estimator::Line, LightSampling::Fnee, Tracking::Regular),
            16,
            32,
            1000,
        );
        assert!(reference[0].0 > 0.0);
        for (est, ls) in combos {
            // Line + classic NEE in dense emitters has infinite variance (tests/path.rs)
            if sigma_t > 10.0 && ls == LightSampling::Nee {
                continue;
            }
            let sc = scene(sigma_t, ls, interpolation);
            for tracking in [Tracking::Mixed, Tracking::Null] {
                let integ = Integrator { point_lookup: lookup, ..integrator(est, ls, tracking) };
                let got = region_means_with(SamplerKind::Sobol, &sc, integ, 16, 24, 7);
                common::assert_same_means(&format!("{interpolation} {lookup:?} σ_t={sigma_t} {est:?}/{ls:?}, {tracking:?} vs regular"), &got, &reference, 4.3);
            }
        }
    }
}

#[test]
fn still_majorants_bound_every_reconstructed_density() {
    // Random rays through the explosion: at points along every majorant stretch the field
    // (nearest and trilinear) is at most the stretch's density bound; on the brick level,
    // and on the coarser levels a large volume's grid moves to (here forced by limits of
    // 27, 8 and 1 cells: a level of n³ nodes takes (n + 1)³ cells)
    let vol = explosion_volume();
    let linear = plume_volume::trilinear::Trilinear::new(explosion_volume());
    let b = vol.world_bounds();
    for (max_cells, edge) in [(MAX_CELLS, 8), (27, 16), (8, 32), (1, 32)] {
        let grid = MajorantGrid::with_max_cells(&vol, 0.0, max_cells);
        assert_eq!(grid.cell_edge_voxels(), edge, "limit {max_cells}");
        assert!(
            grid.memory_bytes() as i64 <= 8 * (max_cells.min(1 << 16) + 1) * 27,
            "limit {max_cells}: {} bytes",
            grid.memory_bytes()
        );
        let mut rng = Sampler::new(41, 0, 0);
        let mut checked = 0;
        for _ in 0..300 {
            let origin = b.lo
                + (b.hi - b.lo) * DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 1.4
                - (b.hi - b.lo) * 0.2;
            let direction = plume_core::sampling::phase::sample_uniform_sphere([
                rng.next_f64(),
                rng.next_f64(),
            ]);
            let ray = Ray { origin, direction };
            for seg in grid.segments(&ray, 0.0, f64::INFINITY) {
                for k in 0..8 {
                    let p =
                        ray.at(seg.t0 + (seg.t1 - seg.t0) * (f64::from(k) + rng.next_f64()) / 8.0);
                    for d in [vol.values_at(p).density, linear.values_at(p).density] {
                        assert!(
                            d <= seg.bounds.density,
                            "limit {max_cells}: density {d} above the bound {} at {p}",
                            seg.bounds.density
                        );
                        checked += 1;
                    }
                }
            }
        }
        assert!(checked > 2_000, "limit {max_cells}: only {checked} lookups checked");
    }
}

#[test]
fn auto_resolves_to_mixed_where_null_collisions_apply() {
    let mixed = [
        (Estimator::Line, LightSampling::Fnee),
        (Estimator::Point, LightSampling::Fnee),
        (Estimator::RayMarch, LightSampling::None),
        (Estimator::Line, LightSampling::Nee),
    ];
    for (est, ls) in mixed {
        assert_eq!(TrackingChoice::Auto.resolve(est, ls), Tracking::Mixed, "{est:?}/{ls:?}");
    }
    for (est, ls) in [
        (Estimator::Blend { kappa: 4.0 }, LightSampling::Fnee),
        (Estimator::Point, LightSampling::Nee),
    ] {
        assert_eq!(TrackingChoice::Auto.resolve(est, ls), Tracking::Regular, "{est:?}/{ls:?}");
        assert_eq!(TrackingChoice::Null.resolve(est, ls), Tracking::Null);
    }
    assert_eq!(
        TrackingChoice::Regular.resolve(Estimator::Line, LightSampling::Fnee),
        Tracking::Regular
    );
}

#[test]
fn tracking_is_a_flag_a_scene_key_and_part_of_the_settings_hash() {
    let dir = tmpdir("tracking", "cli");
    let vdb = explosion(&dir, 32, Some(3));
    let base = [
        "render",
        s(&vdb),
        "--width",
        "24",
        "--height",
        "16",
        "--spp",
        "4",
        "--albedo",
        "0.8",
        "--stats",
    ];
    let values = ["auto", "regular", "mixed", "null"].map(|v| (v, Some(v)));
    let hashes = common::settings_hashes(&dir, &base, "--tracking", &values);
    // auto is mixed here (line-fnee), so its pixels are mixed's; every named value is hashed
    assert_eq!(
        common::exr_pixels(&dir.join("auto.exr")),
        common::exr_pixels(&dir.join("mixed.exr"))
    );
    assert_ne!(
        common::exr_pixels(&dir.join("regular.exr")),
        common::exr_pixels(&dir.join("mixed.exr"))
    );
    for (i, a) in hashes.iter().enumerate() {
        for b in &hashes[i + 1..] {
            assert_ne!(a, b, "two trackings share a settings hash");
        }
    }
    // A scene file's key
    assert_eq!(
        common::render_integrator_keys(&dir, &vdb, "tracking = \"null\"", (24, 16)),
        common::exr_pixels(&dir.join("null.exr"))
    );
}

#[test]
fn combinations_null_collisions_cannot_serve_are_refused() {
    let dir = tmpdir("tracking", "refused");
    let vdb = explosion(&dir, 32, Some(3));
    let out = dir.join("x.exr");
    for (tracking, method) in
        [("mixed", ["--method", "point-nee"]), ("null", ["--estimator", "blend"])]
    {
        plume_exits(
            &[
                "render",
                s(&vdb),
                "--albedo",
                "0.8",
                "--tracking",
                tracking,
                method[0],
                method[1],
                "-o",
                s(&out),
            ],
            2,
            &["--tracking", "regular or auto"],
        );
        assert!(!out.exists(), "{tracking} {method:?} wrote an image");
    }
    // A blend camera segment cannot be tracked by null collisions either (`null`; `mixed`
    // tracks camera rays exactly and takes it)
    plume_exits(
        &[
            "render",
            s(&vdb),
            "--albedo",
            "0.8",
            "--tracking",
            "null",
            "--camera-estimator",
            "blend",
            "-o",
            s(&out),
        ],
        2,
        &["--camera-estimator", "ray-march"],
    );
    assert!(!out.exists(), "a blend camera segment under null tracking wrote an image");
    let o = plume(&[
        "render",
        s(&vdb),
        "--albedo",
        "0.8",
        "--width",
        "16",
        "--height",
        "12",
        "--spp",
        "2",
        "--camera-estimator",
        "blend",
        "-o",
        s(&out),
    ]);
    assert!(
        o.status.success(),
        "blend camera segment, mixed tracking: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    // The summary line names both estimators
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("spp, Line, camera Blend"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    // auto falls back to regular tracking for them
    for method in [["--method", "point-nee"], ["--estimator", "blend"]] {
        let o = plume(&[
            "render",
            s(&vdb),
            "--albedo",
            "0.8",
            "--width",
            "16",
            "--height",
            "12",
            "--spp",
            "2",
            method[0],
            method[1],
            "-o",
            s(&out),
            "--overwrite",
        ]);
        assert!(o.status.success(), "{method:?}: {}", String::from_utf8_lossy(&o.stderr));
    }
    // Unknown values name the flag and the choices
    plume_exits(
        &["render", s(&vdb), "--tracking", "delta", "-o", s(&out)],
        2,
        &["--tracking", "regular", "mixed", "null"],
    );
}
