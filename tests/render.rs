//! Render-level checks: determinism across thread counts, the image of a voxel-aligned
//! emissive box against its closed form, and atomic EXR/PNG output.

use crate::common;

use common::{grid, names_in, pixel_bits, tmpdir};
use glam::{DAffine3, DMat3, DVec3, IVec3};
use plume_core::color::Rgb;
use plume_core::sampling::SamplerKind;
use plume_engine::camera::Camera;
use plume_engine::integrator::{
    Counters, Integrator, LightSampling, Lights, MisHeuristic, NoTrace, Scene, Tracking,
};
use plume_engine::medium::{
    Collision, Convention, Emission, EmissionKind, Estimator, Medium, TemperatureMap,
};
use plume_engine::render::{
    pixel_sample, render, render_with, PixelSample, RenderControl, RenderSettings, SampleBudget,
    SampleOrder, StopReason,
};
use plume_volume::Volume;

fn blob_scene(estimator: Estimator) -> (Scene<Volume>, Integrator) {
    let xf = DAffine3::from_mat3(DMat3::from_diagonal(DVec3::splat(0.1)));
    let leaves: Vec<IVec3> = (0..27).map(|i| IVec3::new(i % 3, (i / 3) % 3, i / 9) * 8).collect();
    let centre = IVec3::splat(12);
    let d = grid("density", xf, &leaves, |p| {
        (1.0 - (p - centre).as_vec3().length() / 12.0).max(0.0) * 3.0
    });
    let t = grid("temperature", xf, &leaves, |p| 4000.0 - (p - centre).as_vec3().length() * 300.0);
    let emission = Emission::blackbody(1.0);
    let vol = Volume::build(&d, Some(&t), |v| emission.map_source(v)).unwrap();
    let cam =
        Camera::look_at(DVec3::new(1.2, 1.2, -4.0), DVec3::splat(1.2), DVec3::Y, 40.0, 24, 20)
            .unwrap();
    let scene = Scene {
        field: vol,
        medium: Medium {
            sigma_t: 2.0,
            albedo: plume_core::color::Rgb::splat(0.0),
            g: 0.0,
            emission,
            extinction: Default::default(),
        },
        camera: cam,
        lights: Default::default(),
        motion: None,
        majorants: None,
    };
    (scene, Integrator::emission_only(estimator))
}

#[test]
fn same_seed_gives_identical_images_for_any_thread_count() {
    for (est, sampler) in [Estimator::Point, Estimator::Line, Estimator::RayMarch]
        .into_iter()
        .flat_map(|e| [(e, SamplerKind::Sobol), (e, SamplerKind::Random)])
    {
        let (scene, integrator) = blob_scene(est);
        let run = |threads| {
            let s = RenderSettings {
                budget: SampleBudget::Spp(6),
                seed: 42,
                sampler,
                threads,
                first_sample: 0,
                adaptive: None,
                integrator,
            };
            render(&scene, &s, &|_, _| {})
        };
        let (a, b) = (run(1), run(2));
        let (pa, pb) = (a.film.average(), b.film.average());
        assert!(pa.iter().any(|p| p[0] > 0.0), "{est:?}: image not black");
        assert_eq!(
            pixel_bits(&pa),
            pixel_bits(&pb),
            "{est:?} {sampler}: bit-identical across thread counts"
        );
        assert_eq!(a.counters, b.counters);
        let other = render(
            &scene,
            &RenderSettings {
                budget: SampleBudget::Spp(6),
                seed: 43,
                sampler,
                threads: 2,
                first_sample: 0,
                adaptive: None,
                integrator,
            },
            &|_, _| {},
        );
        assert_ne!(pa, other.film.average(), "a different seed changes the image");
    }
}

/// The blob, scattering (albedo 0.8) and lit by FNEE: paths with light segments.
fn scattering_blob() -> (Scene<Volume>, Integrator) {
    let (mut scene, _) = blob_scene(Estimator::Line);
    scene.medium.albedo = plume_core::color::Rgb::splat(0.8);
    scene.medium.sigma_t = 6.0;
    scene.lights =
        Lights::build(&scene.field, &scene.medium.emission, LightSampling::Fnee, 8).unwrap();
    (
        scene,
        Integrator {
            estimator: Estimator::Line,
            camera_estimator: None,
            light_sampling: LightSampling::Fnee,
            mis: MisHeuristic::Power,
            max_depth: 16,
            tracking: Tracking::Regular,
            split: 1,
            camera_collision: Collision::Analog,
            point_lookup: plume_engine::integrator::PointLookup::Exact,
            split_by: plume_engine::integrator::SplitBy::Uniform,
        },
    )
}

#[test]
fn sample_ranges_merge_and_replays_equal_the_render_for_both_samplers() {
    let (scene, one_path) = scattering_blob();
    // One path per camera collision, and split 4 ways (`Sampler::split`)
    for (sampler, split) in
        [SamplerKind::Sobol, SamplerKind::Random].into_iter().flat_map(|k| [(k, 1), (k, 4)])
    {
        let integrator = Integrator { split, ..one_path };
        let settings = RenderSettings {
            budget: SampleBudget::Spp(7),
            seed: 5,
            sampler,
            threads: 2,
            first_sample: 0,
            adaptive: None,
            integrator,
        };
        let whole = render(&scene, &settings, &|_, _| {});
        assert!(whole.counters.fnee_samples > 0, "light segments were sampled");
        // Samples 0..3 and 3..7 rendered apart and added: the same sums
        let a = render(
            &scene,
            &RenderSettings { budget: SampleBudget::Spp(3), ..settings },
            &|_, _| {},
        );
        let b = render(
            &scene,
            &RenderSettings {
                budget: SampleBudget::Spp(4),
                first_sample: 3,
                adaptive: None,
                threads: 1,
                ..settings
            },
            &|_, _| {},
        );
        for ((t, ta), tb) in whole.film.tiles.iter().zip(&a.film.tiles).zip(&b.film.tiles) {
            let added: Vec<[i128; 4]> = ta
                .sums
                .iter()
                .zip(&tb.sums)
                .map(|(x, y)| std::array::from_fn(|c| x[c] + y[c]))
                .collect();
            assert_eq!(t.sums, added, "{sampler} split {split}: ranges 0..3 + 3..7 = 0..7");
        }
        // Sample 5 of every pixel, replayed as --debug-pixel does, is the 1-spp render of 5..6
        let one = render(
            &scene,
            &RenderSettings { budget: SampleBudget::Spp(1), first_sample: 5, ..settings },
            &|_, _| {},
        );
        let px = one.film.average();
        let width = scene.camera.width;
        let mut scattered = 0;
        for (i, p) in px.iter().enumerate() {
            let (x, y) = (i as u32 % width, i as u32 / width);
            let PixelSample { ray, mut sampler, .. } = pixel_sample(&scene, sampler, 5, x, y, 5);
            let mut c = Counters::default();
            let l = integrator.li(&scene, &ray, &mut sampler, &mut c, &mut NoTrace);
            scattered += c.collisions;
            // One sample's fixed-point value is exact to 2^-65: as f32, the value itself
            for ch in 0..4 {
                assert!(
                    l[ch] < 1e-12 || l[ch] as f32 == p[ch],
                    "pixel {x},{y} channel {ch}: replay {} vs render {}",
                    l[ch],
                    p[ch]
                );
            }
        }
        assert!(scattered > 0, "replays went through scattering vertices");
    }
}

fn bits(film: &plume_engine::film::Film) -> Vec<u32> {
    pixel_bits(&film.average())
}

#[test]
fn tile_major_order_gives_the_same_image_and_a_stop_keeps_nothing_of_the_pass() {
    let (scene, integrator) = blob_scene(Estimator::Line);
    let settings = RenderSettings {
        budget: SampleBudget::Spp(5),
        seed: 42,
        sampler: SamplerKind::Sobol,
        threads: 2,
        first_sample: 0,
        adaptive: None,
        integrator,
    };
    let progressive = render(&scene, &settings, &|_, _| {});
    let tile_major = render_with(
        &scene,
        &settings,
        RenderControl { order: SampleOrder::TileMajor, ..Default::default() },
        &|_, _| {},
    );
    assert_eq!((tile_major.spp, tile_major.stopped), (5, StopReason::Finished));
    assert_eq!(bits(&progressive.film), bits(&tile_major.film), "same image in either order");
    assert_eq!(progressive.counters, tile_major.counters);

    // Continue that image by 3 spp, stopped after two tiles (the 24×20 image has four):
    // the pass is abandoned and the film handed back exactly as it came in
    let calls = std::sync::atomic::AtomicUsize::new(0);
    let stop = || calls.fetch_add(1, std::sync::atomic::Ordering::SeqCst) >= 3;
    let continued = RenderSettings { budget: SampleBudget::Spp(3), first_sample: 5, ..settings };
    let control = RenderControl {
        film: Some(progressive.film.clone()),
        stop: Some(&stop),
        order: SampleOrder::TileMajor,
        ..Default::default()
    };
    let stopped = render_with(&scene, &continued, control, &|_, _| {});
    assert_eq!((stopped.spp, stopped.stopped), (0, StopReason::Interrupted));
    assert!(
        calls.load(std::sync::atomic::Ordering::SeqCst) > 3,
        "tiles were rendered before the stop"
    );
    assert_eq!(
        bits(&stopped.film),
        bits(&progressive.film),
        "nothing of the abandoned pass is kept"
    );

    // Unstopped, the continuation equals 8 spp rendered at once
    let control = RenderControl {
        film: Some(progressive.film.clone()),
        order: SampleOrder::TileMajor,
        ..Default::default()
    };
    let resumed = render_with(&scene, &continued, control, &|_, _| {});
    let whole =
        render(&scene, &RenderSettings { budget: SampleBudget::Spp(8), ..settings }, &|_, _| {});
    assert_eq!(bits(&resumed.film), bits(&whole.film));
}

#[test]
fn voxel_aligned_box_image_matches_closed_form() {
    // An orthographic-like setting: camera far away looking along +z at a constant
    // emissive box 1 unit deep; the centre pixel sees L_e (1 − e^{−μ d}) / μ.
    let leaves = [IVec3::ZERO];
    let xf = DAffine3::from_mat3_translation(
        DMat3::from_diagonal(DVec3::splat(1.0 / 8.0)),
        DVec3::splat(1.0 / 16.0),
    );
    let d = grid("density", xf, &leaves, |_| 2.0);
    let s = grid("emission", xf, &leaves, |_| 5.0);
    let emission = Emission {
        kind: EmissionKind::Grid,
        convention: Convention::Cycles,
        scale: 1.0,
        color: Rgb::ONE,
        temperature_map: TemperatureMap::Kelvin,
        cutoff_kelvin: 0.0,
    };
    let vol = Volume::build(&d, Some(&s), |v| emission.map_source(v)).unwrap();
    // Box spans [0, 1]³ in world space.
    let cam = Camera::look_at(
        DVec3::new(0.5, 0.5, -1000.0),
        DVec3::new(0.5, 0.5, 0.0),
        DVec3::Y,
        0.01,
        9,
        9,
    )
    .unwrap();
    let sigma_t = 1.5;
    let scene = Scene {
        field: vol,
        medium: Medium {
            sigma_t,
            albedo: plume_core::color::Rgb::splat(0.0),
            g: 0.0,
            emission,
            extinction: Default::default(),
        },
        camera: cam,
        lights: Default::default(),
        motion: None,
        majorants: None,
    };
    let mu = sigma_t * 2.0;
    let expected = 5.0 * (1.0 - (-mu * 1.0f64).exp()) / mu;
    for est in [Estimator::RayMarch, Estimator::Line, Estimator::Point] {
        let integrator = Integrator::emission_only(est);
        let r = render(
            &scene,
            &RenderSettings {
                budget: SampleBudget::Spp(4000),
                seed: 1,
                sampler: SamplerKind::Sobol,
                threads: 0,
                first_sample: 0,
                adaptive: None,
                integrator,
            },
            &|_, _| {},
        );
        let px = r.film.average()[4 * 9 + 4];
        // Per-sample σ of line/point here is below 0.7·expected: 4σ/√4000 < 0.045·expected.
        let tol = if est == Estimator::RayMarch { 1e-5 } else { 0.045 } * expected;
        assert!((f64::from(px[0]) - expected).abs() < tol, "{est:?}: {} vs {expected}", px[0]);
        let alpha = 1.0 - (-mu).exp();
        assert!(
            (f64::from(px[3]) - alpha).abs() < if est == Estimator::RayMarch { 1e-5 } else { 0.03 },
            "{est:?} alpha {}",
            px[3]
        );
    }
}

#[test]
fn exr_roundtrip_keeps_pixels_and_metadata_and_writes_atomically() {
    let dir = tmpdir("render-test", "exr");
    let path = dir.join("img.exr");
    let px: Vec<[f32; 4]> = (0..12).map(|i| [i as f32, 0.5, 1e9, 0.25]).collect();
    plume::output::write_exr(&path, 4, 3, &px, &[("plume:spp".into(), "7".into())]).unwrap();
    let plume::output::RgbaImage { width: w, height: h, pixels: back } =
        plume::output::read_exr(&path).unwrap();
    assert_eq!((w, h), (4, 3));
    assert_eq!(back, px);
    let leftovers = names_in(&dir, |n| n.contains(".tmp"));
    assert!(leftovers.is_empty(), "temporary files left behind");
    // An unwritable destination is an error naming the file, and leaves nothing.
    let bad = dir.join("missing-dir").join("x.exr");
    let err = plume::output::write_exr(&bad, 4, 3, &px, &[]).unwrap_err();
    assert!(err.to_string().contains("x.exr"), "{err}");
    assert!(!bad.exists());
    plume::output::write_png(&dir.join("p.png"), 4, 3, &px, 1.0).unwrap();
    assert!(std::fs::metadata(dir.join("p.png")).unwrap().len() > 0);
    std::fs::remove_dir_all(&dir).unwrap();
}
