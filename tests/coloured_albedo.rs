//! A coloured scattering albedo with grey extinction (Cycles' Principled Volume *Color*
//! with a black *Absorption Color*): paths are the grey medium's, their throughput is
//! per channel, so channel `c` of a render with albedo `(a_r, a_g, a_b)` has the mean of
//! channel `c` of a grey render with albedo `a_c`; and a colour of three equal channels is
//! the grey medium, bit for bit. Fixed seeds, means within 4 standard errors of the runs.

use crate::common;

use common::{explosion_emission, explosion_volume, mean_stderr, plume, s, stderr, tmpdir};
use glam::DVec3;
use plume_core::color::Rgb;
use plume_core::sampling::SamplerKind;
use plume_engine::camera::Camera;
use plume_engine::integrator::{Integrator, LightSampling, Lights, Scene};
use plume_engine::medium::{Estimator, Medium};
use plume_engine::render::{render, RenderSettings, SampleBudget};
use plume_scene::Tracking;
use plume_volume::Volume;

/// The explosion of the mean tests (density scale 4, g 0.3) with albedo `albedo`, lit by
/// its FNEE proxy.
fn scene(albedo: Rgb) -> Scene<Volume> {
    let e = explosion_emission();
    let lights = Lights::build(&explosion_volume(), &e, LightSampling::Fnee, 16).unwrap();
    let camera = Camera::look_at(
        DVec3::new(0.0, 0.2, -6.5),
        DVec3::new(0.0, 0.2, 0.0),
        DVec3::Y,
        40.0,
        12,
        10,
    )
    .unwrap();
    Scene {
        field: explosion_volume(),
        medium: Medium {
            sigma_t: 4.0,
            albedo,
            g: 0.3,
            emission: explosion_emission(),
            extinction: Default::default(),
        },
        camera,
        lights,
        motion: None,
        majorants: None,
    }
}

/// Per run, the image mean of each channel and of each channel's left and right halves.
fn channel_means(scene: &Scene<Volume>, integrator: Integrator, seed: u64) -> [f64; 9] {
    let settings = RenderSettings {
        budget: SampleBudget::Spp(8),
        seed,
        sampler: SamplerKind::Sobol,
        threads: 0,
        first_sample: 0,
        adaptive: None,
        integrator,
    };
    let r = render(scene, &settings, &|_, _| {});
    let px = r.film.average();
    let (w, h) = (scene.camera.width as usize, scene.camera.height as usize);
    let mut out = [0.0f64; 9];
    for y in 0..h {
        for x in 0..w {
            for c in 0..3 {
                let v = f64::from(px[y * w + x][c]);
                out[c] += v / (w * h) as f64;
                out[3 + c + 3 * usize::from(x >= w / 2)] += 2.0 * v / (w * h) as f64;
            }
        }
    }
    out
}

#[test]
fn each_channel_scatters_with_its_own_albedo() {
    let colour = [0.9f32, 0.5, 0.2];
    let integrator = Integrator {
        estimator: Estimator::Line,
        camera_estimator: Some(Estimator::RayMarch),
        light_sampling: LightSampling::Fnee,
        mis: plume_engine::integrator::MisHeuristic::Power,
        max_depth: 64,
        tracking: Tracking::Regular,
        split: 2,
        camera_collision: plume_engine::medium::Collision::Forced,
        point_lookup: plume_engine::integrator::PointLookup::Exact,
        split_by: plume_engine::integrator::SplitBy::Uniform,
    };
    let runs = 12u64;
    let stats = |albedo: Rgb, seed0: u64| -> Vec<(f64, f64)> {
        let sc = scene(albedo);
        let per_run: Vec<[f64; 9]> =
            (0..runs).map(|k| channel_means(&sc, integrator, seed0 + k)).collect();
        (0..9).map(|i| mean_stderr(&per_run.iter().map(|r| r[i]).collect::<Vec<_>>())).collect()
    };
    let coloured = stats(Rgb(colour), 100);
    for (c, &a) in colour.iter().enumerate() {
        let grey = stats(Rgb::splat(a), 200);
        // Channel c: the whole image and its two halves
        for i in [c, 3 + c, 6 + c] {
            let ((m, se), (rm, rse)) = (coloured[i], grey[i]);
            let z = (m - rm) / (se * se + rse * rse).sqrt().max(1e-12);
            assert!(
                z.abs() < 4.0,
                "channel {c} (albedo {a}), mean {i}: {m} ± {se} vs grey {rm} ± {rse}, z {z:.2}"
            );
        }
    }
    // The colour shows: the scattered light differs between the channels' grey renders
    let (red, blue) = (stats(Rgb::splat(0.9), 300)[0].0, stats(Rgb::splat(0.2), 300)[0].0);
    assert!(red > blue * 1.05, "albedo 0.9 {red} against 0.2 {blue}");
}

#[test]
fn a_colour_of_equal_channels_is_the_grey_medium_through_the_binary() {
    let dir = tmpdir("albedo", "equal");
    let ex = common::explosion(&dir, 24, Some(2));
    let render = |name: &str, albedo: &str| {
        let out = dir.join(format!("{name}.exr"));
        let o = plume(&[
            "render",
            s(&ex),
            "-o",
            s(&out),
            "--albedo",
            albedo,
            "--spp",
            "4",
            "--width",
            "24",
            "--height",
            "16",
            "-q",
        ]);
        assert!(o.status.success(), "{name}: {}", stderr(&o));
        common::pixel_bits(&common::exr_pixels(&out))
    };
    assert_eq!(render("grey", "0.7"), render("triple", "0.7,0.7,0.7"));
    let o = plume(&["render", s(&ex), "-o", s(&dir.join("x.exr")), "--albedo", "0.9,1.2,0.3"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("--albedo") && stderr(&o).contains("1.2 is not in [0, 1]"),
        "{}",
        stderr(&o)
    );
    let o = plume(&["render", s(&ex), "-o", s(&dir.join("x.exr")), "--albedo", "0.9,0.3"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    // In a scene file: the line and key, and what is expected
    let file = dir.join("two.toml");
    let text = format!("[volume]\nfile = {:?}\n[medium]\nalbedo = [0.5, 0.2]\n", s(&ex));
    std::fs::write(&file, text).unwrap();
    let o = plume(&["render", s(&file), "-o", s(&dir.join("x.exr"))]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("two.toml:4: key `medium.albedo`: expected a number or [r, g, b]"),
        "{}",
        stderr(&o)
    );
}
