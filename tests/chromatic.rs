//! Chromatic extinction (Cycles' Principled Volume with an *Absorption Color*; METHOD.md
//! §15, `medium::extinction`): per-channel closed forms in homogeneous slabs for every
//! estimator (emission, a sun's single scattering, shadow transmittance), the trilinear
//! walk against its own expected value, Cycles' mapping, and through the binary: a black
//! absorption colour is today's grey medium bit for bit, renders are the same bits on any
//! number of threads, parts and resumes, extreme densities stay finite, a channel without
//! extinction is transparent, and what cannot go with it is refused naming the key.
//! Fixed seeds; means within 4 standard errors of the samples' own spread.

use crate::common;

use common::{grid, grid_emission, mean_stderr_from_sums, plume, s, stderr, tmpdir};
use glam::{DAffine3, DMat3, DVec3, IVec3};
use plume_core::color::Rgb;
use plume_core::sampling::phase::hg_pdf;
use plume_core::sampling::Sampler;
use plume_engine::camera::Camera;
use plume_engine::integrator::tracker::Tracker;
use plume_engine::integrator::{
    AnyScene, Counters, Integrator, LightSampling, Lights, MisHeuristic, NoTrace, Scene, Tracking,
};
use plume_engine::light::external::{Distant, ExternalLights, Light};
use plume_engine::medium::{
    Collision, Convention, Emission, EmissionKind, Estimator, Extinction, Medium,
};
use plume_volume::field::{Field, Ray};
use plume_volume::{Interpolation, Volume};

/// Half-width of the slabs: light entering through their sides does not reach the camera
/// ray's neighbourhood.
const HALF: f64 = 16.0;
const SIGMA_T: f64 = 5.0;
const G: f64 = 0.3;
/// Cycles' Color and Absorption Color of the tests' medium.
const COLOR: [f32; 3] = [0.8, 0.6, 0.3];
const ABSORPTION: [f32; 3] = [0.1, 0.5, 0.9];

/// `k_c = C + (1 − C)(1 − √A)`, by hand.
fn k() -> [f64; 3] {
    std::array::from_fn(|c| {
        let (s, a) = (f64::from(COLOR[c]), f64::from(ABSORPTION[c]));
        s + (1.0 - s) * (1.0 - a.sqrt())
    })
}

/// A homogeneous slab `[−HALF, HALF]² × [0, depth]` of unit density, emitting `source`
/// per unit length (Cycles convention: not multiplied by density) where `source > 0`.
fn slab(depth: f64, source: f32) -> Volume {
    let n = 8; // leaves a side
    let xf = DAffine3::from_mat3_translation(
        DMat3::from_diagonal(DVec3::new(
            2.0 * HALF / f64::from(8 * n),
            2.0 * HALF / f64::from(8 * n),
            depth / 8.0,
        )),
        DVec3::new(-HALF + HALF / f64::from(8 * n), -HALF + HALF / f64::from(8 * n), depth / 16.0),
    );
    let leaves: Vec<IVec3> = (0..n * n).map(|i| IVec3::new(i % n, i / n, 0) * 8).collect();
    let e = grid_emission(Convention::Cycles);
    let density = grid("density", xf, &leaves, |_| 1.0);
    let emission = (source > 0.0).then(|| grid("emission", xf, &leaves, |_| source));
    Volume::build(&density, emission.as_ref(), |v| e.map_source(v)).unwrap()
}

fn medium(emits: bool) -> Medium {
    let emission = if emits {
        grid_emission(Convention::Cycles)
    } else {
        Emission { kind: EmissionKind::None, ..grid_emission(Convention::Cycles) }
    };
    Medium::principled(SIGMA_T, COLOR, ABSORPTION, G, emission)
}

fn scene(field: Volume, medium: Medium, lights: Lights) -> Scene<Volume> {
    let cam =
        Camera::look_at(DVec3::new(0.0, 0.0, -1.0), DVec3::ZERO, DVec3::Y, 1.0, 1, 1).unwrap();
    Scene { field, medium, camera: cam, lights, motion: None, majorants: None }
}

fn integrator(estimator: Estimator, max_depth: u32) -> Integrator {
    Integrator {
        estimator,
        camera_estimator: None,
        light_sampling: LightSampling::None,
        mis: MisHeuristic::Power,
        max_depth,
        tracking: Tracking::Regular,
        split: 1,
        camera_collision: Collision::Analog,
        point_lookup: plume_engine::integrator::PointLookup::Exact,
        split_by: plume_engine::integrator::SplitBy::Uniform,
    }
}

/// Mean and standard error of each channel and of alpha along the slab's central ray
/// (`+z` from below).
fn along_the_normal<F: Field>(
    scene: &Scene<F>,
    integ: Integrator,
    n: u64,
    seed: u64,
) -> [(f64, f64); 4] {
    let ray = Ray { origin: DVec3::new(0.0, 0.0, -1.0), direction: DVec3::Z };
    let (mut sum, mut sum2) = ([0.0f64; 4], [0.0f64; 4]);
    let mut c = Counters::default();
    for i in 0..n {
        let mut sampler = Sampler::new(seed, 0, i);
        let l = integ.li(scene, &ray, &mut sampler, &mut c, &mut NoTrace);
        for ch in 0..4 {
            sum[ch] += l[ch];
            sum2[ch] += l[ch] * l[ch];
        }
    }
    std::array::from_fn(|ch| mean_stderr_from_sums(sum[ch], sum2[ch], n))
}

fn assert_close(label: &str, (m, se): (f64, f64), expected: f64) {
    assert!(
        (m - expected).abs() <= 4.0 * se + 1e-9 * expected.abs(),
        "{label}: {m} ± {se} vs closed form {expected}"
    );
}

const ESTIMATORS: [Estimator; 4] =
    [Estimator::Line, Estimator::Point, Estimator::Blend { kappa: 4.0 }, Estimator::RayMarch];

#[test]
fn cycles_inputs_map_to_grey_or_chromatic_extinction() {
    let e = Emission::none();
    // A black absorption colour is the grey medium of the colour, unchanged
    let grey = Medium::principled(2.0, COLOR, [0.0; 3], G, e);
    assert_eq!((grey.sigma_t, grey.albedo, grey.extinction), (2.0, Rgb(COLOR), Extinction::Grey));
    // Equal channels: a grey medium of extinction kσ and albedo C/k
    let same = Medium::principled(2.0, [0.5; 3], [0.25; 3], G, e);
    assert_eq!(same.extinction, Extinction::Grey);
    assert!((same.sigma_t - 2.0 * 0.75).abs() < 1e-15);
    assert!((same.albedo.0[0] - 0.5 / 0.75).abs() < 1e-7);
    // Otherwise chromatic with Cycles' factors
    let m = Medium::principled(2.0, COLOR, ABSORPTION, G, e);
    let Extinction::Chromatic(c) = m.extinction else { panic!("{:?}", m.extinction) };
    for (got, want) in c.factors().iter().zip(k()) {
        assert!((got - want).abs() < 1e-7, "{got} vs {want}");
    }
    assert_eq!((m.sigma_t, m.albedo), (2.0, Rgb(COLOR)));
}

#[test]
fn emission_through_a_chromatic_slab_is_exact_per_channel() {
    // L_c = L_e (1 − e^{−k_c σ_t D}) / (k_c σ_t); alpha = 1 − mean_c e^{−k_c σ_t D}
    let (depth, le) = (0.5, 2.0f32);
    let sc = scene(slab(depth, le), medium(true), Lights::default());
    let taus = k().map(|k| (-k * SIGMA_T * depth).exp());
    let expected: [f64; 4] = [
        f64::from(le) * (1.0 - taus[0]) / (k()[0] * SIGMA_T),
        f64::from(le) * (1.0 - taus[1]) / (k()[1] * SIGMA_T),
        f64::from(le) * (1.0 - taus[2]) / (k()[2] * SIGMA_T),
        1.0 - taus.iter().sum::<f64>() / 3.0,
    ];
    for estimator in ESTIMATORS {
        let got = along_the_normal(&sc, Integrator::emission_only(estimator), 20_000, 3);
        for ch in 0..4 {
            assert_close(&format!("{estimator:?} channel {ch}"), got[ch], expected[ch]);
        }
        if estimator == Estimator::RayMarch {
            // The expected value is exact on constant pieces (no roulette this thin)
            for ch in 0..3 {
                assert!((got[ch].0 - expected[ch]).abs() < 1e-9 * expected[ch], "{got:?}");
            }
        }
    }
}

#[test]
fn shadow_rays_carry_each_channels_exact_transmittance() {
    let depth = 0.5;
    let (field, m) = (slab(depth, 0.0), medium(false));
    let ray = Ray { origin: DVec3::new(0.3, -0.2, -1.0), direction: DVec3::Z };
    let r = Tracker::Regular(&field).transmittance(&m, &ray, 10.0, &mut Sampler::new(1, 0, 0));
    for (c, k) in k().iter().enumerate() {
        let want = (-k * SIGMA_T * depth).exp();
        let got = r.transmittance * r.channels[c];
        assert!((got - want).abs() < 1e-9 * want, "channel {c}: {got} vs {want}");
    }
}

/// `∫₀^D σ_s^c e^{−σ_t^c s} e^{−σ_t^c (D − s)/μ} ds` for channel `c`: light arriving at
/// cosine `μ` to the normal through the slab's top face.
fn kernel(c: usize, depth: f64, mu: f64) -> f64 {
    let (sigma_s, sigma_t) = (SIGMA_T * f64::from(COLOR[c]), SIGMA_T * k()[c]);
    let a = sigma_t * (1.0 - 1.0 / mu);
    let inner = if a.abs() < 1e-12 { depth } else { -(-a * depth).exp_m1() / a };
    sigma_s * (-sigma_t * depth / mu).exp() * inner
}

#[test]
fn a_sun_over_a_chromatic_slab_matches_single_scattering_per_channel() {
    let depth = 0.1;
    let alpha = 40f64.to_radians();
    let to_light = DVec3::new(alpha.sin(), 0.0, alpha.cos());
    let e = 3.0;
    let sun = Light::Distant(Distant::new(-to_light, Rgb::splat(e as f32), 0.0));
    let lights = Lights { external: ExternalLights::new(vec![sun], HALF), ..Lights::default() };
    let sc = scene(slab(depth, 0.0), medium(false), lights);
    for estimator in ESTIMATORS {
        let got = along_the_normal(&sc, integrator(estimator, 1), 40_000, 7);
        for c in 0..3 {
            let expected = e * hg_pdf(G, alpha.cos()) * kernel(c, depth, alpha.cos());
            assert_close(&format!("{estimator:?} channel {c}"), got[c], expected);
            assert!(got[c].1 < 0.05 * expected, "{estimator:?} channel {c}: noise {got:?}");
        }
    }
}

#[test]
fn trilinear_walks_agree_with_their_expected_value_per_channel() {
    // Polynomial pieces (the slab's faces ramp over a voxel): line, point and blend
    // against ray-march's one-point rule, each unbiased for the same integral
    let sc = scene(slab(0.5, 2.0), medium(true), Lights::default());
    let AnyScene::Linear(sc) = AnyScene::new(sc, Interpolation::Linear) else { unreachable!() };
    let reference =
        along_the_normal(&sc, Integrator::emission_only(Estimator::RayMarch), 40_000, 11);
    for estimator in [Estimator::Line, Estimator::Point, Estimator::Blend { kappa: 4.0 }] {
        let got = along_the_normal(&sc, Integrator::emission_only(estimator), 40_000, 13);
        for ch in 0..4 {
            let ((m, se), (rm, rse)) = (got[ch], reference[ch]);
            let z = (m - rm) / (se * se + rse * rse).sqrt().max(1e-300);
            assert!(z.abs() < 4.0, "{estimator:?} channel {ch}: {m} ± {se} vs {rm} ± {rse}");
        }
    }
}

/// The explosion (density scale 4, g 0.3) in `medium`, lit by its own emission through
/// `light_sampling`'s structures.
fn explosion(medium: Medium, light_sampling: LightSampling) -> Scene<Volume> {
    let e = common::explosion_emission();
    let lights = Lights::build(&common::explosion_volume(), &e, light_sampling, 16).unwrap();
    let camera = Camera::look_at(
        DVec3::new(0.0, 0.2, -6.5),
        DVec3::new(0.0, 0.2, 0.0),
        DVec3::Y,
        40.0,
        12,
        10,
    )
    .unwrap();
    let field = common::explosion_volume();
    Scene { field, medium, camera, lights, motion: None, majorants: None }
}

#[test]
fn each_channel_of_a_chromatic_render_is_the_grey_medium_of_that_channel() {
    // Channel c sees extinction k_c σ_t and albedo C_c/k_c: the grey render with those has
    // the same mean in channel c, with multiple scattering, FNEE or classic NEE and MIS
    let e = common::explosion_emission();
    let chromatic = Medium::principled(4.0, COLOR, ABSORPTION, G, e);
    let methods = [
        (Estimator::Line, Some(Estimator::RayMarch), LightSampling::Fnee, Interpolation::Nearest),
        (Estimator::Line, Some(Estimator::RayMarch), LightSampling::Fnee, Interpolation::Linear),
        (Estimator::Point, None, LightSampling::Nee, Interpolation::Nearest),
    ];
    // Either reconstruction of the explosion in `medium`
    let means = |medium, light_sampling, interpolation, integ, seed| {
        let any = AnyScene::new(explosion(medium, light_sampling), interpolation);
        plume_engine::with_scene!(any, s => common::image_means(&s, integ, seed, 64))
    };
    for (estimator, camera_estimator, light_sampling, interpolation) in methods {
        let integ = Integrator {
            camera_estimator,
            light_sampling,
            max_depth: 64,
            split: 2,
            ..integrator(estimator, 64)
        };
        let got = means(chromatic, light_sampling, interpolation, integ, 100);
        for (c, k) in k().iter().enumerate() {
            let albedo = Rgb::splat((f64::from(COLOR[c]) / k) as f32);
            let grey = Medium::principled(4.0 * k, albedo.0, [0.0; 3], G, e);
            let want = means(grey, light_sampling, interpolation, integ, 200)[c];
            let ((m, se), (rm, rse)) = (got[c], want);
            let z = (m - rm) / (se * se + rse * rse).sqrt().max(1e-300);
            assert!(
                z.abs() < 4.0,
                "{light_sampling:?} {interpolation:?} channel {c}: {m} ± {se} vs grey {rm} ± {rse}"
            );
        }
        assert!(got[0].0 > 1.05 * got[2].0, "the colour shows: {got:?}");
    }
}

/// A render of the explosion through the binary, 24×16, coloured albedo, with `extra`
/// flags; every channel's bits.
fn render_bits(
    dir: &std::path::Path,
    name: &str,
    volume: &std::path::Path,
    extra: &[&str],
) -> Bits {
    let out = dir.join(format!("{name}.exr"));
    let mut args = vec!["render", s(volume), "-o", s(&out), "--width", "24", "--height", "16"];
    args.extend_from_slice(&["--albedo", "0.8,0.6,0.3", "--aovs", "-q"]);
    args.extend_from_slice(extra);
    let o = plume(&args);
    assert!(o.status.success(), "{name}: {}", stderr(&o));
    common::bits(&common::channels(&out))
}

type Bits = std::collections::BTreeMap<String, Vec<u32>>;

#[test]
fn through_the_binary_black_is_grey_and_the_bits_hold_across_threads_parts_and_resumes() {
    let dir = tmpdir("chromatic", "binary");
    let ex = common::explosion(&dir, 24, Some(2));
    let spp = ["--spp", "4"];
    assert_eq!(
        render_bits(&dir, "none", &ex, &spp),
        render_bits(&dir, "black", &ex, &[&spp[..], &["--absorption-color", "0"]].concat())
    );
    let coloured = ["--absorption-color", "0.1,0.5,0.9"];
    let with = |extra: &[&'static str]| [&coloured[..], extra].concat();
    let one = render_bits(&dir, "one", &ex, &with(&["--spp", "4", "--threads", "1"]));
    assert_eq!(one, render_bits(&dir, "three", &ex, &with(&["--spp", "4", "--threads", "3"])));
    assert_ne!(one, render_bits(&dir, "grey", &ex, &["--spp", "4", "--threads", "1"]));
    // Two tiles × two sample ranges, merged
    let mut parts = Vec::new();
    for tile in ["0/2", "1/2"] {
        for range in ["0..1", "1..4"] {
            let name = format!("part_{}_{}", &tile[..1], &range[..1]);
            render_bits(&dir, &name, &ex, &with(&["--tile", tile, "--sample-range", range]));
            parts.push(dir.join(format!("{name}.exr")));
        }
    }
    let merged = dir.join("merged.exr");
    let mut args = vec!["merge", "-o", s(&merged), "-q"];
    args.extend(parts.iter().map(|p| s(p)));
    let o = plume(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(one, common::bits(&common::channels(&merged)), "merged parts differ");
    // Two samples with sums, continued to four
    render_bits(&dir, "resumed", &ex, &with(&["--spp", "2", "--sums"]));
    assert_eq!(one, render_bits(&dir, "resumed", &ex, &with(&["--spp", "4"])), "resumed differs");
}

#[test]
fn what_chromatic_extinction_cannot_go_with_is_refused_naming_the_key() {
    let dir = tmpdir("chromatic", "refused");
    let ex = common::explosion(&dir, 16, Some(2));
    let out = dir.join("x.exr");
    let base = ["render", s(&ex), "-o", s(&out), "--absorption-color"];
    for (extra, needle) in [
        (&["0.2,1.5,0.1"][..], "1.5 is not in [0, 1]"),
        (&["0.5", "--albedo-grid", "density"][..], "albedo grid"),
        (&["0.5", "--velocity-grid", "v"][..], "motion blur"),
        (&["0.5", "--tracking", "null"][..], "track regularly"),
    ] {
        let o = plume(&[&base[..], extra].concat());
        assert_eq!(o.status.code(), Some(2), "{extra:?}: {}", stderr(&o));
        let err = stderr(&o);
        assert!(err.contains("--absorption-color") && err.contains(needle), "{extra:?}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(!out.exists());
    }
}

#[test]
fn extremes_stay_finite_and_a_channel_without_extinction_is_transparent() {
    let dir = tmpdir("chromatic", "extremes");
    let ex = common::explosion(&dir, 16, Some(2));
    let render = |name: &str, extra: &[&str]| {
        let out = dir.join(format!("{name}.exr"));
        let mut args = vec!["render", s(&ex), "-o", s(&out), "--width", "16", "--height", "12"];
        args.extend_from_slice(&["--spp", "4", "-q"]);
        args.extend_from_slice(extra);
        let o = plume(&args);
        assert!(o.status.success(), "{name}: {}", stderr(&o));
        common::exr_pixels(&out)
    };
    let coloured = ["--albedo", "0.8,0.5,0.2", "--absorption-color", "0.2,0.5,0.8"];
    for scale in ["1e-6", "1e6"] {
        for method in ["line-fnee", "point-nee", "ray-march"] {
            let px = render(
                "x",
                &[&coloured[..], &["--density-scale", scale, "--method", method]].concat(),
            );
            assert!(px.iter().flatten().all(|v| v.is_finite()), "{scale} {method}");
        }
    }
    // Red: Color 0 and Absorption Color 1 make k = 0, so red is the unattenuated emission,
    // which a nearly empty medium shows too (both camera rays ray-marched: the same points)
    let transparent = render("red", &["--albedo", "0,0.5,0.9", "--absorption-color", "1,0.5,0.1"]);
    let thin = render(
        "thin",
        &["--density-scale", "1e-9", "--albedo", "0", "--camera-estimator", "ray-march"],
    );
    let red = |px: &[[f32; 4]]| px.iter().map(|p| f64::from(p[0])).sum::<f64>();
    let (a, b) = (red(&transparent), red(&thin));
    assert!((a - b).abs() <= 1e-6 * b, "red {a} vs an empty medium's {b}");
}
