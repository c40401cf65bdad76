//! Stochastic point lookups (`--point-lookup`, `integrator::tracker::PointLookup`): one
//! voxel picked with its trilinear weight is an unbiased estimate of the interpolated
//! value (exactly, over a stratified `u`; for emission points in `integrator::tracker`'s
//! tests); camera segments keep exact emission points; and the choice is a flag, a scene
//! key and part of the settings hash where it changes pixels (trilinear), and nothing
//! where it does not (nearest). That images tracked by null collisions with it have the
//! means of regular tracking, for every estimator and light strategy null collisions
//! serve, is tested in `tests/tracking.rs` (`stochastic`, the default, and `stochastic-emission`)
//! and, with motion blur, in `tests/motion_blur.rs`.

use crate::common;

use common::{explosion, explosion_volume, s, tmpdir};
use glam::DVec3;
use plume_core::sampling::Sampler;
use plume_volume::field::Field;
use plume_volume::trilinear::Trilinear;

#[test]
fn a_picked_voxel_is_an_unbiased_estimate_of_the_interpolated_one() {
    // The pick splits [0, 1) into 8 intervals of lengths w_c (axis by axis), so over N
    // stratified u every corner is picked w_c·N times to within 1: the mean of any
    // function of the picked voxel is its trilinear interpolation to within 8/N of the
    // corners' range. Checked for density, source and their product (not linear in the
    // interpolated values, as a corner's L_e is not), at points inside the volume, on
    // its edges (half the corners outside, read as 0) and on exact voxel centres.
    let linear = Trilinear::new(explosion_volume());
    let b = linear.world_bounds();
    let mut rng = Sampler::new(3, 0, 0);
    let n = 4096;
    let (mut checked, mut mixed) = (0, 0);
    for k in 0..600 {
        let u = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64());
        let mut p = b.lo + (b.hi - b.lo) * (u * 1.1 - 0.05);
        if k % 50 == 0 {
            // A voxel centre: weight 1 on one corner
            let index = linear.volume().index_from_world().transform_point3(p).round();
            p = linear.volume().world_from_index().transform_point3(index);
        }
        let it = linear.interpolate_world(p);
        let exact = [
            it.density(),
            it.source(),
            it.corners
                .iter()
                .zip(&it.weights)
                .map(|(v, w)| w * f64::from(v.density) * f64::from(v.source))
                .sum(),
        ];
        let mut sum = [0.0f64; 3];
        let mut distinct = std::collections::BTreeSet::new();
        for i in 0..n {
            let v = linear.values_picked(p, (f64::from(i) + 0.5) / f64::from(n));
            assert!(it.corners.contains(&v), "at {p}: picked {v:?}, not one of the corners");
            distinct.insert((v.density.to_bits(), v.source.to_bits()));
            for (s, x) in sum.iter_mut().zip([
                f64::from(v.density),
                f64::from(v.source),
                f64::from(v.density) * f64::from(v.source),
            ]) {
                *s += x;
            }
        }
        let range = |g: &dyn Fn(&plume_volume::field::VoxelValues) -> f64| {
            let vals: Vec<f64> = it.corners.iter().map(g).collect();
            vals.iter().copied().fold(f64::MIN, f64::max)
                - vals.iter().copied().fold(f64::MAX, f64::min)
        };
        let ranges = [
            range(&|v| f64::from(v.density)),
            range(&|v| f64::from(v.source)),
            range(&|v| f64::from(v.density) * f64::from(v.source)),
        ];
        for c in 0..3 {
            let mean = sum[c] / f64::from(n);
            assert!(
                (mean - exact[c]).abs() <= 8.0 / f64::from(n) * ranges[c] + 1e-6 * exact[c].abs(),
                "at {p}, quantity {c}: picked mean {mean} against {}",
                exact[c]
            );
        }
        checked += 1;
        mixed += usize::from(distinct.len() > 2);
    }
    assert!(checked == 600 && mixed > 40, "only {mixed} points with corners of several values");
    // Nearest has one voxel per point: the pick is the voxel
    let nearest = explosion_volume();
    for k in 0..200 {
        let p = b.lo + (b.hi - b.lo) * DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64());
        assert_eq!(nearest.values_picked(p, f64::from(k) / 200.0), nearest.values_at(p));
    }
    assert!(!nearest.picks_fewer() && linear.picks_fewer());
}

#[test]
fn the_point_lookup_is_a_flag_a_scene_key_and_hashed_where_it_changes_pixels() {
    let dir = tmpdir("point_lookup", "cli");
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
    let values = [
        ("default", None),
        ("stochastic-emission", Some("stochastic-emission")),
        ("stochastic", Some("stochastic")),
        ("exact", Some("exact")),
    ];
    let linear = common::settings_hashes(&dir, &base, "--point-lookup", &values);
    let pixels = |name: &str| common::exr_pixels(&dir.join(format!("{name}.exr")));
    // Stochastic is the default; each kind changes a trilinear render's pixels and its hash
    assert_eq!(pixels("default"), pixels("stochastic"));
    assert_eq!(linear[0], linear[2]);
    for (a, b) in [(1, 2), (1, 3), (2, 3)] {
        assert_ne!(pixels(values[a].0), pixels(values[b].0), "{} and {}", values[a].0, values[b].0);
        assert_ne!(linear[a], linear[b], "{} and {}", values[a].0, values[b].0);
    }
    let exact = pixels("exact");
    // A scene file's key
    assert_eq!(
        common::render_integrator_keys(&dir, &vdb, "point_lookup = \"exact\"", (24, 16)),
        exact
    );
    assert_eq!(
        common::render_integrator_keys(&dir, &vdb, "point_lookup = \"stochastic\"", (24, 16)),
        pixels("stochastic")
    );
    // Nearest: one voxel per point either way; the same pixels and the same hash
    let nearest_base = [
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
        "--interpolation",
        "nearest",
        "--stats",
    ];
    let nearest = common::settings_hashes(&dir, &nearest_base, "--point-lookup", &values);
    assert!(
        pixels("exact") == pixels("stochastic-emission")
            && pixels("stochastic") == pixels("stochastic-emission")
    );
    assert!(nearest.iter().all(|h| *h == nearest[0]), "nearest hashes differ: {nearest:?}");
    // A bad value is refused naming the flag
    common::plume_exits(
        &["render", s(&vdb), "--point-lookup", "sometimes", "-o", s(&dir.join("bad.exr"))],
        2,
        &["--point-lookup"],
    );
}

#[test]
fn camera_segments_keep_exact_emission_points() {
    // Null collisions on the camera segment (`--tracking null`): without scattering the
    // only emission points are the camera rays', which `stochastic-emission` reads exactly,
    // so it renders `stochastic`'s pixels; with scattering its paths pick their emission
    // points and the pixels differ
    let dir = tmpdir("point_lookup", "camera");
    let vdb = explosion(&dir, 32, Some(3));
    let render = |albedo: &str, lookup: &str| {
        let out = dir.join(format!("{albedo}-{lookup}.exr"));
        let o = common::plume(&[
            "render",
            s(&vdb),
            "--width",
            "24",
            "--height",
            "16",
            "--spp",
            "4",
            "--albedo",
            albedo,
            "--tracking",
            "null",
            "--point-lookup",
            lookup,
            "-o",
            s(&out),
            "-q",
        ]);
        assert!(o.status.success(), "albedo {albedo}, {lookup}: {}", common::stderr(&o));
        common::exr_pixels(&out)
    };
    assert_eq!(render("0", "stochastic-emission"), render("0", "stochastic"));
    assert_ne!(render("0", "stochastic"), render("0", "exact"));
    assert_ne!(render("0.8", "stochastic-emission"), render("0.8", "stochastic"));
}
