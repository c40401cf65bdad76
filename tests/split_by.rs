//! Splitting by brightness (`--split-by brightness`, `integrator::split_map`, `pilot`):
//! the per-pixel counts keep the image's mean (any count fixed before the paths are
//! drawn is unbiased), the image stays a pure function of (seed, pixel, sample) for any
//! thread count, sample range and crop, a replayed sample equals the rendered one, and the
//! choice is a flag, a scene key and part of the settings hash.

use crate::common;

use common::{
    assert_same_means, explosion, explosion_emission, explosion_volume, pixel_bits,
    region_means_with, s, tmpdir,
};
use glam::DVec3;
use plume_core::sampling::SamplerKind;
use plume_engine::film::Crop;
use plume_engine::integrator::split_map::pixel_integrator;
use plume_engine::integrator::{
    AnyScene, Counters, Integrator, LightSampling, Lights, MisHeuristic, NoTrace, PointLookup,
    SplitBy, Tracking,
};
use plume_engine::medium::{Collision, Estimator, Medium};
use plume_engine::render::{
    pixel_sample, render, render_with, PixelSample, RenderControl, RenderSettings, SampleBudget,
};
use plume_volume::Interpolation;

/// The test explosion (32³) filling a 40×32 image (5×4 pilot blocks), albedo 0.8, lit by
/// FNEE, so the pilot sees bright and dim smoke.
fn scene() -> AnyScene {
    let vol = explosion_volume();
    let e = explosion_emission();
    let lights = Lights::build(&vol, &e, LightSampling::Fnee, 8).unwrap();
    let camera = plume_engine::camera::Camera::look_at(
        DVec3::new(0.0, 0.2, -4.5),
        DVec3::new(0.0, 0.2, 0.0),
        DVec3::Y,
        40.0,
        40,
        32,
    )
    .unwrap();
    let medium = Medium {
        sigma_t: 4.0,
        albedo: plume_core::color::Rgb::splat(0.8),
        g: 0.3,
        emission: e,
        extinction: Default::default(),
    };
    AnyScene::new(
        plume_engine::integrator::Scene {
            field: vol,
            medium,
            camera,
            lights,
            motion: None,
            majorants: None,
        },
        Interpolation::Linear,
    )
}

/// line-fnee with a ray-marched, forced camera collision and `split` paths from it.
fn integrator(split: u32, split_by: SplitBy) -> Integrator {
    Integrator {
        estimator: Estimator::Line,
        camera_estimator: Some(Estimator::RayMarch),
        light_sampling: LightSampling::Fnee,
        mis: MisHeuristic::Power,
        max_depth: 16,
        tracking: Tracking::Regular,
        split,
        split_by,
        camera_collision: Collision::Forced,
        point_lookup: PointLookup::Exact,
    }
}

fn settings(spp: u32, seed: u64, integrator: Integrator) -> RenderSettings {
    RenderSettings {
        budget: SampleBudget::Spp(spp),
        seed,
        sampler: SamplerKind::Sobol,
        threads: 2,
        first_sample: 0,
        adaptive: None,
        integrator,
    }
}

#[test]
fn the_pilot_gives_varied_counts_and_the_image_mean_is_kept() {
    let scene = scene();
    let brightness = integrator(4, SplitBy::Brightness);
    // The map is not uniform here (else the mean test below could not fail)
    let map = plume_engine::with_scene!(&scene, s => plume_engine::pilot::split_map(s, &settings(1, 0, brightness))).expect("a pilot map");
    let counts = map.counts();
    let (lo, hi) = (counts.iter().min().unwrap(), counts.iter().max().unwrap());
    assert!(*lo < 4 && *hi > 4, "counts {counts:?}");
    // Uniform splitting builds no map
    assert!(plume_engine::with_scene!(&scene, s => plume_engine::pilot::split_map(s, &settings(1, 0, integrator(4, SplitBy::Uniform)))).is_none());
    // Image and quadrant means over 12 independent runs each (5 comparisons, |z| < 4)
    let uniform =
        region_means_with(SamplerKind::Sobol, &scene, integrator(4, SplitBy::Uniform), 4, 12, 100);
    let by_brightness = region_means_with(SamplerKind::Sobol, &scene, brightness, 4, 12, 200);
    assert_same_means("split by brightness against uniform", &by_brightness, &uniform, 4.0);
}

#[test]
fn splitting_by_brightness_is_deterministic_over_threads_ranges_crops_and_replays() {
    let scene = scene();
    let integ = integrator(4, SplitBy::Brightness);
    plume_engine::with_scene!(&scene, sc => {
        let whole = render(sc, &settings(5, 7, integ), &|_, _| {});
        let one_thread = render(sc, &RenderSettings { threads: 1, ..settings(5, 7, integ) }, &|_, _| {});
        assert_eq!(pixel_bits(&whole.film.average()), pixel_bits(&one_thread.film.average()), "threads");
        // Samples 0..2 and 2..5 apart, added: the same sums (each range runs its own pilot)
        let a = render(sc, &settings(2, 7, integ), &|_, _| {});
        let b = render(sc, &RenderSettings { first_sample: 2, ..settings(3, 7, integ) }, &|_, _| {});
        for ((t, ta), tb) in whole.film.tiles.iter().zip(&a.film.tiles).zip(&b.film.tiles) {
            let added: Vec<[i128; 4]> = ta.sums.iter().zip(&tb.sums).map(|(x, y)| std::array::from_fn(|c| x[c] + y[c])).collect();
            assert_eq!(t.sums, added, "ranges 0..2 + 2..5 = 0..5");
        }
        // A crop is the whole image's pixels there (its pilot still covers the frame)
        let crop = Crop { x0: 13, y0: 9, x1: 31, y1: 23 };
        let cropped = render_with(sc, &settings(5, 7, integ), RenderControl { crop: Some(crop), ..Default::default() }, &|_, _| {});
        let full = whole.film.average();
        let part = cropped.film.average();
        let width = sc.camera.width;
        for (i, p) in part.iter().enumerate() {
            let (x, y) = (crop.x0 + i as u32 % crop.width(), crop.y0 + i as u32 / crop.width());
            assert_eq!(p.map(f32::to_bits), full[(y * width + x) as usize].map(f32::to_bits), "cropped pixel {x},{y}");
        }
        // Sample 3 of every pixel replayed as --debug-pixel does (the pilot's map, then the
        // pixel's integrator) is the 1-spp render of sample 3
        let one = render(sc, &RenderSettings { first_sample: 3, ..settings(1, 7, integ) }, &|_, _| {});
        let px = one.film.average();
        let map = plume_engine::pilot::split_map(sc, &settings(1, 7, integ));
        assert!(map.is_some());
        let mut split_paths = 0;
        for (i, p) in px.iter().enumerate() {
            let (x, y) = (i as u32 % width, i as u32 / width);
            let PixelSample { ray, mut sampler, .. } = pixel_sample(sc, SamplerKind::Sobol, 7, x, y, 3);
            let mut c = Counters::default();
            let pixel = pixel_integrator(&integ, map.as_ref(), x, y);
            split_paths += u64::from(pixel.split != integ.split);
            let l = pixel.li(sc, &ray, &mut sampler, &mut c, &mut NoTrace);
            for ch in 0..4 {
                assert!(l[ch] < 1e-12 || l[ch] as f32 == p[ch], "pixel {x},{y} channel {ch}: replay {} vs render {}", l[ch], p[ch]);
            }
        }
        assert!(split_paths > 0, "some pixels split other than --split");
    });
}

#[test]
fn split_by_is_a_flag_a_scene_key_and_hashed_when_not_uniform() {
    let dir = tmpdir("split_by", "cli");
    let vdb = explosion(&dir, 32, Some(3));
    let base = [
        "render",
        s(&vdb),
        "--width",
        "48",
        "--height",
        "32",
        "--spp",
        "4",
        "--albedo",
        "0.8",
        "--stats",
    ];
    let values =
        [("default", None), ("uniform", Some("uniform")), ("brightness", Some("brightness"))];
    let hashes = common::settings_hashes(&dir, &base, "--split-by", &values);
    let pixels = |name: &str| common::exr_pixels(&dir.join(format!("{name}.exr")));
    // Uniform is the default and adds nothing to the hash; brightness changes both
    assert_eq!(pixels("default"), pixels("uniform"));
    assert_eq!(hashes[0], hashes[1]);
    assert_ne!(pixels("brightness"), pixels("uniform"));
    assert_ne!(hashes[2], hashes[1]);
    // The scene key gives the flag's image
    assert_eq!(
        common::render_integrator_keys(&dir, &vdb, "split_by = \"brightness\"", (48, 32)),
        pixels("brightness")
    );
    // A bad value is refused naming the flag
    common::plume_exits(
        &["render", s(&vdb), "--split-by", "luck", "-o", s(&dir.join("bad.exr"))],
        2,
        &["--split-by"],
    );
}
