//! AOV layers (`--aovs`): the colour layers sum to the beauty; the beauty is
//! the same bits with and without them; tiles, sample ranges, merges and resumes give
//! the same bits in every layer; the depth layer is the expected distance to the first
//! collision.

use crate::common;

use std::path::Path;

use common::{bits, channels, explosion, grid, grid_emission, mean_stderr, plume, s, tmpdir};
use glam::{DAffine3, DMat3, DVec3, IVec3};
use plume_core::sampling::Sampler;
use plume_engine::camera::Camera;
use plume_engine::integrator::{
    AovLayout, AovSample, Counters, Integrator, Lights, NoTrace, Scene,
};
use plume_engine::medium::{Convention, Emission, EmissionKind, Estimator, Medium};
use plume_volume::field::Ray;
use plume_volume::Volume;

/// A lit, scattering, emitting explosion with two named light groups and a constant
/// environment (the default group `environment`).
const SHOT: [&str; 16] = [
    "--width",
    "24",
    "--height",
    "16",
    "--albedo",
    "0.7",
    "--distant-light",
    "direction = [0.3, -0.2, -1], irradiance = 4, group = \"key\"",
    "--sphere-light",
    "position = [0, 3, 0], radius = 0.3, power = 2000, group = \"fill\"",
    "--environment",
    "0.05,0.05,0.08",
    "--aovs",
    "-q",
    "--threads",
    "2",
];

fn render(ex: &Path, out: &Path, extra: &[&str]) {
    let mut args = vec!["render", s(ex), "-o", s(out)];
    args.extend(SHOT);
    args.extend(extra);
    let o = plume(&args);
    assert!(o.status.success(), "{args:?}: {}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn colour_layers_sum_to_the_beauty_and_the_beauty_does_not_change() {
    let d = tmpdir("aovs", "sum");
    let ex = explosion(&d, 32, None);
    let (with, without) = (d.join("with.exr"), d.join("without.exr"));
    render(&ex, &with, &["--spp", "8"]);
    let mut args = vec!["render", s(&ex), "-o", s(&without), "--spp", "8"];
    args.extend(SHOT.iter().filter(|a| **a != "--aovs"));
    assert!(plume(&args).status.success());
    let c = channels(&with);
    let names: Vec<&String> = c.keys().collect();
    for layer in ["emission", "scattered", "key", "fill", "environment"] {
        for ch in ["R", "G", "B"] {
            assert!(c.contains_key(&format!("{layer}.{ch}")), "no {layer}.{ch} in {names:?}");
        }
    }
    assert!(c.contains_key("alpha.A") && c.contains_key("depth.Z"), "{names:?}");
    let plain = channels(&without);
    for ch in ["R", "G", "B", "A"] {
        assert_eq!(bits(&c)[ch], bits(&plain)[ch], "beauty {ch} changed with --aovs");
    }
    assert_eq!(c["alpha.A"], c["A"]);
    let mut energy = [0.0f64; 5];
    for ch in ["R", "G", "B"] {
        for (i, &beauty) in c[ch].iter().enumerate() {
            let parts: Vec<f64> = ["emission", "scattered", "key", "fill", "environment"]
                .iter()
                .map(|l| f64::from(c[&format!("{l}.{ch}")][i]))
                .collect();
            let sum: f64 = parts.iter().sum();
            assert!(
                (sum - f64::from(beauty)).abs() <= 1e-6 * f64::from(beauty).abs() + 1e-30,
                "{ch} pixel {i}: layers {parts:?} sum {sum}, beauty {beauty}"
            );
            for (e, p) in energy.iter_mut().zip(parts) {
                *e += p;
            }
        }
    }
    // Every layer holds light (the test would not notice a layer left empty otherwise)
    assert!(energy.iter().all(|&e| e > 0.0), "layer energies {energy:?}");
    // Depth lies within the camera's view of the volume (4 m cube, framed automatically)
    let z = &c["depth.Z"];
    assert!(
        z.iter().all(|v| v.is_finite() && *v >= 0.0) && z.iter().any(|v| *v > 0.0),
        "depth {z:?}"
    );
}

#[test]
fn layers_are_bit_identical_across_tiles_sample_ranges_merges_and_resumes() {
    let d = tmpdir("aovs", "split");
    let ex = explosion(&d, 32, None);
    let whole = d.join("whole.exr");
    render(&ex, &whole, &["--spp", "6"]);
    // Four parts: 2 tiles x 2 sample ranges, merged
    let mut parts = Vec::new();
    for tile in ["0/2", "1/2"] {
        for range in ["0..2", "2..6"] {
            let p = d.join(format!("part_{}_{}.exr", &tile[..1], &range[..1]));
            render(&ex, &p, &["--tile", tile, "--sample-range", range]);
            parts.push(p);
        }
    }
    let merged = d.join("merged.exr");
    let mut args = vec!["merge", "-o", s(&merged), "-q"];
    args.extend(parts.iter().map(|p| s(p)));
    let o = plume(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(
        bits(&channels(&whole)),
        bits(&channels(&merged)),
        "merged parts differ from one render"
    );
    // A render of 2 spp with sums, continued to 6
    let resumed = d.join("resumed.exr");
    render(&ex, &resumed, &["--spp", "2", "--sums"]);
    render(&ex, &resumed, &["--spp", "6"]);
    assert_eq!(
        bits(&channels(&whole)),
        bits(&channels(&resumed)),
        "a resumed render differs from one render"
    );
}

#[test]
fn depth_is_the_expected_distance_to_the_first_collision() {
    // A homogeneous slab z ∈ [0, D] of extinction σ seen along +z from z = −1: given a
    // collision, E[t] = 1 + 1/σ − D e^{−σD}/(1 − e^{−σD}).
    let (sigma, depth) = (5.0f64, 0.3f64);
    let n = 8;
    let xf = DAffine3::from_mat3_translation(
        DMat3::from_diagonal(DVec3::new(4.0 / 64.0, 4.0 / 64.0, depth / 8.0)),
        DVec3::new(-2.0 + 2.0 / 64.0, -2.0 + 2.0 / 64.0, depth / 16.0),
    );
    let leaves: Vec<IVec3> = (0..n * n).map(|i| IVec3::new(i % n, i / n, 0) * 8).collect();
    let e = grid_emission(Convention::Cycles);
    let vol =
        Volume::build(&grid("density", xf, &leaves, |_| 1.0), None, |v| e.map_source(v)).unwrap();
    let medium = Medium {
        sigma_t: sigma,
        albedo: plume_core::color::Rgb::splat(0.0),
        g: 0.0,
        emission: Emission { kind: EmissionKind::None, ..e },
        extinction: Default::default(),
    };
    let cam =
        Camera::look_at(DVec3::new(0.0, 0.0, -1.0), DVec3::ZERO, DVec3::Y, 1.0, 1, 1).unwrap();
    let scene = Scene {
        field: vol,
        medium,
        camera: cam,
        lights: Lights::default(),
        motion: None,
        majorants: None,
    };
    let layout = AovLayout { groups: vec![], halves: None };
    let expected =
        1.0 + 1.0 / sigma - depth * (-sigma * depth).exp() / (1.0 - (-sigma * depth).exp());
    let ray = Ray { origin: DVec3::new(0.0, 0.0, -1.0), direction: DVec3::Z };
    for estimator in [Estimator::Line, Estimator::RayMarch, Estimator::Point] {
        let integ = Integrator::emission_only(estimator);
        let mut ts = Vec::new();
        let mut c = Counters::default();
        let mut a = AovSample::new(layout.channels(), layout.half_at().zip(layout.halves));
        for i in 0..20_000u64 {
            a.values.fill(0.0);
            integ.li_aovs(
                &scene,
                &ray,
                None,
                plume_engine::integrator::PathState {
                    sampler: &mut Sampler::new(3, 0, i),
                    counters: &mut c,
                    trace: &mut NoTrace,
                    aovs: &mut a,
                },
            );
            let k = layout.channels();
            if a.values[k - 1] == 1.0 {
                ts.push(a.values[k - 2]);
            }
        }
        let hit_rate = ts.len() as f64 / 20_000.0;
        let p_hit = 1.0 - (-sigma * depth).exp();
        assert!(
            (hit_rate - p_hit).abs() < 4.0 * (p_hit * (1.0 - p_hit) / 20_000.0).sqrt(),
            "{estimator:?}: hit rate {hit_rate} vs {p_hit}"
        );
        let (m, se) = mean_stderr(&ts);
        assert!((m - expected).abs() < 4.0 * se, "{estimator:?}: depth {m} ± {se} vs {expected}");
    }
}
