//! Scattered paths traced in rounds (`--defer-paths`, `integrator::deferred`): the image is
//! the direct render's bit for bit, for any thread count, split, point lookup and estimator
//! that defers; paths that cannot be deferred are traced where they scatter; and a
//! cache that fits in memory defers only when asked (one larger than a cgroup limit defers
//! by default: `memory_limits`).

use crate::common;

use std::path::Path;

use common::{explosion, plume, s, stderr, tmpdir};

/// Render `input` with `extra` flags; the pixels' bits and the stats' counters.
fn render(input: &Path, dir: &Path, name: &str, extra: &[&str]) -> (Vec<u32>, serde_json::Value) {
    let (out, stats) = (dir.join(format!("{name}.exr")), dir.join(format!("{name}.json")));
    // A stats file gains a line per render
    let _ = std::fs::remove_file(&stats);
    let mut args = vec![
        "render",
        s(input),
        "-o",
        s(&out),
        "--overwrite",
        "--stats",
        s(&stats),
        "--spp",
        "4",
        "--width",
        "40",
        "--height",
        "30",
        "--seed",
        "5",
        "-q",
    ];
    args.extend_from_slice(extra);
    let o = plume(&args);
    assert!(o.status.success(), "{name}: {}", stderr(&o));
    let pixels = common::exr_pixels(&out);
    assert!(
        pixels.iter().any(|p| p[0] > 0.0),
        "{name}: the image is black, the test proves nothing"
    );
    let stats: serde_json::Value = serde_json::from_slice(&std::fs::read(&stats).unwrap()).unwrap();
    (pixels.iter().flatten().map(|v| v.to_bits()).collect(), stats["counters"].clone())
}

fn counter(c: &serde_json::Value, key: &str) -> u64 {
    c[key].as_u64().unwrap_or_else(|| panic!("counters lack {key}: {c}"))
}

#[test]
fn deferred_paths_give_the_direct_images_bit_for_bit() {
    let dir = tmpdir("deferred", "bits");
    let ex = explosion(&dir, 32, Some(3));
    let tile_major = ["--sample-order", "tile-major"];
    for (name, flags) in [
        ("line-fnee, one path", &["--albedo", "0.8", "--split", "1", "--threads", "1"][..]),
        (
            "line-fnee, 3 split paths, 3 threads",
            &["--albedo", "0.8", "--g", "0.3", "--split", "3", "--threads", "3"],
        ),
        ("exact point lookups", &["--albedo", "0.9", "--point-lookup", "exact", "--threads", "2"]),
        ("picked emission points", &["--albedo", "0.9", "--point-lookup", "stochastic-emission"]),
        (
            "no light sampling, deep paths",
            &["--albedo", "0.95", "--light-sampling", "none", "--max-depth", "32"],
        ),
        ("ray-march after scattering", &["--albedo", "0.8", "--estimator", "ray-march"]),
        ("nearest", &["--albedo", "0.8", "--interpolation", "nearest"]),
    ] {
        let progressive = render(&ex, &dir, "progressive", flags);
        let direct = render(
            &ex,
            &dir,
            "direct",
            &[flags, &tile_major[..], &["--defer-paths", "never"]].concat(),
        );
        let deferred = render(
            &ex,
            &dir,
            "deferred",
            &[flags, &tile_major[..], &["--defer-paths", "always"]].concat(),
        );
        assert!(progressive.0 == direct.0, "{name}: tile-major differs from progressive");
        assert!(deferred.0 == direct.0, "{name}: deferred paths change the image");
        let c = &deferred.1;
        assert!(counter(c, "deferred_samples") > 0, "{name}: nothing was deferred: {c}");
        assert!(
            counter(c, "deferred_rounds") >= 2 && counter(c, "deferred_lookups") > 0,
            "{name}: no round read values: {c}"
        );
        assert_eq!(
            counter(&direct.1, "deferred_samples"),
            0,
            "{name}: --defer-paths never deferred"
        );
        // The paths' own counters are those of the direct render: each path is counted
        // once, from the run that committed it
        for key in ["samples", "segments", "collisions", "fnee_samples", "voxel_steps"] {
            assert_eq!(counter(c, key), counter(&direct.1, key), "{name}: {key}");
        }
    }
}

#[test]
fn paths_that_need_exact_walks_are_traced_where_they_scatter() {
    let dir = tmpdir("deferred", "refused");
    let ex = explosion(&dir, 32, Some(4));
    let always = ["--sample-order", "tile-major", "--defer-paths", "always"];
    for (name, flags) in [
        ("classic NEE (exact shadow rays)", &["--method", "point-nee", "--albedo", "0.8"][..]),
        ("regular tracking after scattering", &["--albedo", "0.8", "--tracking", "regular"]),
        (
            "a distant light (exact shadow rays)",
            &["--albedo", "0.8", "--distant-light", "direction = [0.3, -0.2, -1], irradiance = 5"],
        ),
    ] {
        let direct = render(&ex, &dir, "direct", flags);
        let asked = render(&ex, &dir, "asked", &[flags, &always[..]].concat());
        assert!(asked.0 == direct.0, "{name}: the image changed");
        assert_eq!(counter(&asked.1, "deferred_samples"), 0, "{name}: deferred");
    }
}

/// `auto` defers only a cache larger than the memory available (tested in a cgroup by
/// `memory_limits::a_cache_larger_than_the_cgroup_limit_defers_one_path_per_collision`);
/// this one fits, so its renders defer only when asked to.
#[test]
fn a_mapped_cache_that_fits_in_memory_defers_only_when_asked() {
    let dir = tmpdir("deferred", "cache");
    let ex = explosion(&dir, 32, Some(5));
    let cache = dir.join("ex.plume");
    let o = plume(&["prepare", s(&ex), "-o", s(&cache), "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let flags = ["--albedo", "0.8", "--threads", "2", "--split", "1"];
    let in_core = render(&ex, &dir, "core", &flags);
    let tile_major = [&flags[..], &["--sample-order", "tile-major"]].concat();
    let mapped = render(&cache, &dir, "mapped", &tile_major);
    assert_eq!(
        counter(&mapped.1, "deferred_samples"),
        0,
        "auto deferred a cache that fits: {}",
        mapped.1
    );
    let asked = render(
        &cache,
        &dir,
        "mapped-always",
        &[&tile_major[..], &["--defer-paths", "always"]].concat(),
    );
    assert!(counter(&asked.1, "deferred_samples") > 0, "always did not defer: {}", asked.1);
    for (name, r) in [("auto", &mapped), ("always", &asked)] {
        assert!(
            r.0 == in_core.0,
            "the mapped tile-major render ({name}) differs from the in-core one"
        );
    }
    let progressive = render(
        &cache,
        &dir,
        "mapped-progressive",
        &[&flags[..], &["--defer-paths", "always"]].concat(),
    );
    assert_eq!(counter(&progressive.1, "deferred_samples"), 0, "progressive order deferred");
}

/// A stop (or a deadline) abandons a tile-major pass also while its deferred paths are in
/// rounds: nothing of the pass is kept. In process, one worker, one 16×16 tile: the stop is
/// asked before the pass (1), before and after the tile (2, 3), then before the first round
/// (4), where it says stop.
#[test]
fn a_stop_during_the_rounds_keeps_nothing_of_the_pass() {
    use plume_engine::integrator::{
        Integrator, LightSampling, Lights, MisHeuristic, PointLookup, SplitBy, Tracking,
    };
    use plume_engine::medium::{Collision, Estimator};
    use plume_engine::render::{
        render_with, RenderControl, RenderSettings, SampleBudget, SampleOrder, StopReason,
    };
    use plume_scene::DeferPaths;
    use std::sync::atomic::{AtomicUsize, Ordering};

    let scene =
        common::explosion_scene(4.0, plume_volume::Interpolation::Linear, true, |vol, e| {
            Lights::build(vol, e, LightSampling::Fnee, 8).unwrap()
        });
    let integrator = Integrator {
        estimator: Estimator::Line,
        camera_estimator: None,
        light_sampling: LightSampling::Fnee,
        mis: MisHeuristic::Power,
        max_depth: 16,
        tracking: Tracking::Mixed,
        split: 1,
        split_by: SplitBy::Uniform,
        camera_collision: Collision::Analog,
        point_lookup: PointLookup::Stochastic,
    };
    let settings = RenderSettings {
        budget: SampleBudget::Spp(4),
        seed: 3,
        sampler: plume_core::sampling::SamplerKind::Sobol,
        threads: 1,
        first_sample: 0,
        adaptive: None,
        integrator,
    };
    plume_engine::with_scene!(&scene, s => {
        let control = |defer_paths| RenderControl { order: SampleOrder::TileMajor, defer_paths, ..Default::default() };
        let direct = render_with(s, &settings, control(DeferPaths::Never), &|_, _| {});
        let deferred = render_with(s, &settings, control(DeferPaths::Always), &|_, _| {});
        assert!(deferred.counters.deferred_samples > 0 && deferred.counters.deferred_rounds >= 2, "{:?}", deferred.counters);
        let sums = |f: &plume_engine::film::Film| f.tiles.iter().map(|t| t.sums.clone()).collect::<Vec<_>>();
        assert_eq!(sums(&direct.film), sums(&deferred.film), "deferred paths change the sums");
        assert!(sums(&direct.film).iter().flatten().any(|p| p[0] != 0), "the image is black");
        let calls = AtomicUsize::new(0);
        let stop = || calls.fetch_add(1, Ordering::SeqCst) >= 3;
        let stopped = render_with(s, &settings, RenderControl { stop: Some(&stop), ..control(DeferPaths::Always) }, &|_, _| {});
        assert_eq!(calls.load(Ordering::SeqCst), 4, "the stop was asked before the first round");
        assert_eq!((stopped.spp, stopped.stopped), (0, StopReason::Interrupted));
        assert!(sums(&stopped.film).iter().flatten().all(|p| *p == [0; 4]), "the abandoned pass left sums");
    });
}
