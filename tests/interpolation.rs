//! Trilinear reconstruction (`--interpolation`, `volume.interpolation`; METHOD.md §12) seen
//! from outside: close-ups are continuous with `linear` and blocky with `nearest`; both give
//! the same image means on smooth data up to the boundary band; the flag and the scene key
//! choose it, are recorded and hashed; and every bit-identity plume promises (threads,
//! sample order, automatic caches) holds with `linear` and scattering. Fixed seeds.

use crate::common;

use std::path::Path;

use common::{
    explosion, exr_pixels, grid, grid_emission, mean_stderr, pixel_bits, plume, plume_exits, s,
    stderr, tmpdir,
};
use glam::{DAffine3, DVec3, IVec3};
use plume_core::sampling::SamplerKind;
use plume_engine::camera::Camera;
use plume_engine::integrator::{
    AnyScene, Integrator, LightSampling, Lights, MisHeuristic, Scene, Tracking,
};
use plume_engine::medium::{Collision, Convention, Emission, EmissionKind, Estimator, Medium};
use plume_engine::render::{render, RenderSettings, SampleBudget};
use plume_volume::{Interpolation, Volume};

/// Render `scene` with `spp` samples and `seed`; the averaged RGBA pixels.
fn pixels(
    scene: &AnyScene,
    integrator: Integrator,
    spp: u32,
    seed: u64,
    threads: usize,
) -> Vec<[f32; 4]> {
    let settings = RenderSettings {
        budget: SampleBudget::Spp(spp),
        seed,
        sampler: SamplerKind::Sobol,
        threads,
        first_sample: 0,
        adaptive: None,
        integrator,
    };
    let r = plume_engine::with_scene!(scene, s => render(s, &settings, &|_, _| {}));
    r.film.average()
}

// ---------------------------------------------------------------------------------------
// Continuity of close-ups

/// Emission of voxel `(i, j, k)` of the 4³ block: 64 distinct values in [1, 2], scrambled
/// (index × 37 mod 64) so that neighbours differ by 27/63 or 37/63 along x.
fn block_value(p: IVec3) -> f32 {
    if p.cmplt(IVec3::ZERO).any() || p.cmpge(IVec3::splat(4)).any() {
        return 0.0;
    }
    let index = p.x + 4 * p.y + 16 * p.z;
    1.0 + ((index * 37) % 64) as f32 / 63.0
}

#[test]
fn linear_close_ups_are_continuous_and_nearest_ones_are_not() {
    // A 4³ block of distinct emission values (voxel (i,j,k) centred at world (i,j,k), 1 m
    // voxels), seen along +z through a nearly orthographic camera (1 km away), 240 pixels
    // across 6 m: 40 pixels per voxel. Cycles' grid emission (L_e = source, independent of
    // density) and σ_t = 1e-10 /m: the line estimator is then ∫ L_e ds along the jittered
    // camera ray, exactly, unless a collision happens (odds ≈ 5e-10 per sample; the alpha
    // channel, 1 − the escape indicator, proves there was none).
    let leaf = [IVec3::ZERO];
    let density = grid("density", DAffine3::IDENTITY, &leaf, |_| 1.0);
    let emission = grid("emission", DAffine3::IDENTITY, &leaf, block_value);
    let e = grid_emission(Convention::Cycles);
    let (width, distance, span) = (240u32, 1000.0f64, 6.0);
    let centre = DVec3::splat(1.5);
    let fov = 2.0 * (0.5 * span / distance).atan().to_degrees();
    let camera =
        Camera::look_at(centre - DVec3::Z * distance, centre, DVec3::Y, fov, width, width).unwrap();
    let scene = |interpolation| {
        let vol = Volume::build(&density, Some(&emission), |v| e.map_source(v)).unwrap();
        let medium = Medium {
            sigma_t: 1e-10,
            albedo: plume_core::color::Rgb::splat(0.0),
            g: 0.0,
            emission: e,
            extinction: Default::default(),
        };
        AnyScene::new(
            Scene {
                field: vol,
                medium,
                camera,
                lights: Lights::default(),
                motion: None,
                majorants: None,
            },
            interpolation,
        )
    };
    let w = width as usize;

    // The bound. Let I(X, Y) = ∫ L_e ds along the ray through (X, Y) of the plane z = 1.5
    // facing the camera. Trilinear L_e = Σ_ijk v_ijk h_i(x) h_j(y) h_k(z) with unit tents
    // h, so |∂L_e/∂x| ≤ D Σ_k h_k(z) (Σ_j h_j(y) ≤ 1), D = the largest difference of two
    // neighbouring voxels, the zero voxels around the block included, and ∫ Σ_k h_k dz = 4
    // (4 layers, each tent integrates to 1). Along the ray x moves by λ(z) ≤ (1000 + 2.5)/
    // 1000 per unit of X (the support ends 2.5 m behind the plane), and ds = sec θ dz with
    // sec θ − 1 < 1e-5 and ∂ sec θ/∂X < 3e-6 /m (× I ≤ 8: 3e-5, against 4D ≥ 8): so
    // |∂I/∂X| ≤ L = 4 D × 1.01, and the same in Y.
    // A pixel's value is the mean of I at its jittered sample points (no collision), and
    // two neighbouring pixels lie in a 2Δ × Δ box of the plane (Δ = pixel size there), so
    // they differ by at most L (2Δ + Δ) = 3 L Δ, whatever the seed: no noise term is
    // needed, only rounding (f32 pixels of values ≤ 8: 1e-4 is ample).
    let mut d_max = 0.0f32;
    for x in -1..4 {
        for y in -1..4 {
            for z in -1..4 {
                let p = IVec3::new(x, y, z);
                for axis in [IVec3::X, IVec3::Y, IVec3::Z] {
                    d_max = d_max.max((block_value(p + axis) - block_value(p)).abs());
                }
            }
        }
    }
    let pixel = span / f64::from(width);
    let lipschitz = 4.0 * f64::from(d_max) * 1.01;
    let bound = 3.0 * lipschitz * pixel + 1e-4;

    // The largest jump between horizontal or vertical neighbours
    let max_jump = |px: &[[f32; 4]]| {
        let v = |x: usize, y: usize| f64::from(px[y * w + x][0]);
        let mut jump = 0.0f64;
        for y in 0..w {
            for x in 0..w {
                if x + 1 < w {
                    jump = jump.max((v(x + 1, y) - v(x, y)).abs());
                }
                if y + 1 < w {
                    jump = jump.max((v(x, y + 1) - v(x, y)).abs());
                }
            }
        }
        jump
    };
    let integrator = Integrator::emission_only(Estimator::Line);
    let mut jumps = Vec::new();
    for interpolation in [Interpolation::Linear, Interpolation::Nearest] {
        let px = pixels(&scene(interpolation), integrator, 2, 17, 0);
        assert!(
            px.iter().all(|p| p[3] == 0.0),
            "{interpolation}: a sample collided; the line estimate is no longer ∫ L_e ds"
        );
        // At the column through voxel centres (x, y) = (1, 2) both reconstructions give
        // Σ_k v_1,2,k (unit tents and boxes); a pixel whose centre is within Δ/2 of it on
        // both axes (its footprint within Δ) is within L·2Δ of that.
        let column: f64 = (0..4).map(|k| f64::from(block_value(IVec3::new(1, 2, k)))).sum();
        // (the image's x runs along world −x, its y along −y: `right` = forward × up)
        let (cx, cy) = (
            (0.5 * w as f64 + (centre.x - 1.0) / pixel) as usize,
            (0.5 * w as f64 + (centre.y - 2.0) / pixel) as usize,
        );
        let ray = camera.ray(cx as f64 + 0.5, cy as f64 + 0.5);
        let hit = ray.origin + ray.direction * ((centre.z - ray.origin.z) / ray.direction.z);
        let off = 0.5 * pixel * (1.0 + 1e-6);
        assert!(
            (hit.x - 1.0).abs() < off && (hit.y - 2.0).abs() < off,
            "pixel ({cx}, {cy}) looks at {hit}, not at the column (1, 2)"
        );
        let at_column = f64::from(px[cy * w + cx][0]);
        let near = if interpolation == Interpolation::Linear {
            2.0 * lipschitz * pixel * (1.0 + 1e-6) + 1e-4
        } else {
            1e-4
        };
        assert!(
            (at_column - column).abs() <= near,
            "{interpolation}: pixel ({cx}, {cy}) = {at_column}, column sum {column}"
        );
        jumps.push(max_jump(&px));
    }
    let (linear, nearest) = (jumps[0], jumps[1]);
    println!("largest neighbour jump: linear {linear:.4}, nearest {nearest:.4}; bound 3 L Δ = {bound:.4} (D = {d_max:.3}, Δ = {pixel:.4} m)");
    assert!(linear <= bound, "linear: a jump of {linear} between neighbouring pixels exceeds the continuity bound {bound}");
    assert!(nearest >= 5.0 * bound, "nearest: the largest jump {nearest} is not 5× the bound {bound}; the test could not tell blocks from a smooth image");
}

// ---------------------------------------------------------------------------------------
// Smooth data: the same image means up to the boundary band

/// Side of the smooth block in voxels (2³ leaves), its emission `A + B i` (ramp in x), and
/// the optical depth `C` across it.
const N: i32 = 16;
const A: f64 = 1.0;
const B: f64 = 0.1;
const C: f64 = 1.5;

/// The trapezoid profile of the trilinear block along one axis: 1 on [0, N−1], tapering to
/// 0 at −1 and N (the block's voxels are 1, the inactive ones around it 0).
fn trapezoid(t: f64) -> f64 {
    (t + 1.0).min(f64::from(N) - t).clamp(0.0, 1.0)
}

/// ∫∫ I dX dY over the plane for both reconstructions, from the closed forms (see the test).
fn band_integrals() -> (f64, f64) {
    let n = f64::from(N);
    let sigma = C / n;
    // Nearest: Σ_i s_i per unit Y, over N units of Y, each column (1 − e^−C)/σ × s
    let nearest = (n * A + B * n * (n - 1.0) / 2.0) * n * (1.0 - (-C).exp()) / sigma;
    // Linear: r(X)/σ (1 − e^{−C p(X) p(Y)}), r(X) = A + B clamp(X, 0, N−1); p, r are
    // linear on every unit interval, so a composite midpoint rule on them (200 points per
    // unit) is accurate to ~1e-6 relative.
    let per_unit = 200;
    let cells = (N + 1) * per_unit;
    let at = |k: i32| -1.0 + (f64::from(k) + 0.5) / f64::from(per_unit);
    let profile: Vec<f64> = (0..cells).map(|k| trapezoid(at(k))).collect();
    let mut linear = 0.0;
    for (kx, px) in profile.iter().enumerate() {
        let r = A + B * at(kx as i32).clamp(0.0, n - 1.0);
        let column: f64 = profile.iter().map(|py| 1.0 - (-C * px * py).exp()).sum();
        linear += r * column;
    }
    linear /= sigma * f64::from(per_unit * per_unit);
    (linear, nearest)
}

#[test]
fn nearest_and_linear_agree_on_smooth_data_up_to_the_boundary_band() {
    // A 16³ block (voxel = 1 m), density 1, Cycles grid emission s_i = A + B i (a ramp in
    // x), σ_t = C/N, seen along +z from 1000 km (80² pixels over 20 m: the block and a
    // margin), so the camera rays are parallel to 1e-5.
    //
    // Trilinear of the ramp is exactly the ramp inside [0, N−1]³; with the zero voxels
    // around, each axis tapers to 0 over one voxel: ρ = p(X) p(Y) p(z) with the trapezoid p
    // (∫ p = N), L_e = q(X) p(Y) p(z) = r(X) ρ with r(X) = A + B clamp(X, 0, N−1). So L_e ∝
    // μ_t along each column and I_lin = r(X)/σ_t (1 − e^{−C p(X) p(Y)}). Nearest: I_near =
    // s(round X)/σ_t (1 − e^{−C}) on (−½, N−½)². Hence:
    // 1. Over [0, N−1]² (pixels 10..70, edges on the 0.25 m pixel grid) the two agree in
    //    the mean: p = box = 1 there, and ∫₀^{N−1} round(X) dX = ∫₀^{N−1} X dX = (N−1)²/2.
    // 2. The whole images differ only by the band of one voxel at the block's faces:
    //    (∫∫ I_lin − ∫∫ I_near)/area from the closed forms (≈ 3 % of the mean here).
    // Perspective: at depth z the rays are spread by λ = 1 + (z − 7.5 m)/1000 km, so a
    // slab's share of the image mean is weighted by 1/λ² = 1 ± 1.7e-5 over the block's
    // 17 m: the closed forms hold to 2e-5 relative (`slack`), the obliquity (sec θ − 1 <
    // 1e-10) and the quadrature (1e-6) included.
    let n = f64::from(N);
    let leaves: Vec<IVec3> = (0..8).map(|i| IVec3::new(i & 1, (i >> 1) & 1, i >> 2) * 8).collect();
    let density = grid("density", DAffine3::IDENTITY, &leaves, |_| 1.0);
    let emission =
        grid("emission", DAffine3::IDENTITY, &leaves, |p| (A + B * f64::from(p.x)) as f32);
    let e = grid_emission(Convention::Cycles);
    let (width, distance, span) = (80u32, 1e6f64, 20.0);
    let centre = DVec3::splat(0.5 * (n - 1.0));
    let fov = 2.0 * (0.5 * span / distance).atan().to_degrees();
    let camera =
        Camera::look_at(centre - DVec3::Z * distance, centre, DVec3::Y, fov, width, width).unwrap();
    let scene = |interpolation| {
        let vol = Volume::build(&density, Some(&emission), |v| e.map_source(v)).unwrap();
        let medium = Medium {
            sigma_t: C / n,
            albedo: plume_core::color::Rgb::splat(0.0),
            g: 0.0,
            emission: e,
            extinction: Default::default(),
        };
        AnyScene::new(
            Scene {
                field: vol,
                medium,
                camera,
                lights: Lights::default(),
                motion: None,
                majorants: None,
            },
            interpolation,
        )
    };
    let (linear, nearest) = (scene(Interpolation::Linear), scene(Interpolation::Nearest));
    let w = width as usize;
    let inner = 10..70;
    // Per run (one seed, both reconstructions): whole-image and interior-region means
    let runs = 16u64;
    let mut per_run: [Vec<f64>; 4] = Default::default();
    for run in 0..runs {
        for (k, any) in [&linear, &nearest].into_iter().enumerate() {
            let px = pixels(any, Integrator::emission_only(Estimator::Line), 4, 100 + run, 0);
            let (px, whole) =
                (&px, px.iter().map(|p| f64::from(p[0])).sum::<f64>() / px.len() as f64);
            let region: f64 = inner
                .clone()
                .flat_map(|y| inner.clone().map(move |x| f64::from(px[y * w + x][0])))
                .sum();
            per_run[k].push(whole);
            per_run[2 + k].push(region / (inner.len() * inner.len()) as f64);
        }
    }
    let (integral_lin, integral_near) = band_integrals();
    let area = span * span;
    let predicted = [integral_lin / area, integral_near / area];
    let band = predicted[0] - predicted[1];
    // Both reconstructions render with the same seeds, so their difference is tested on the
    // paired per-run differences (runs are independent). 16 runs: t with 15 degrees of
    // freedom, P(|t| > 5) ≈ 1.6e-4, for each of the 4 comparisons.
    let k = 5.0;
    let diff = |a: &[f64], b: &[f64]| {
        mean_stderr(&a.iter().zip(b).map(|(x, y)| x - y).collect::<Vec<_>>())
    };
    let (lw, nw) = (mean_stderr(&per_run[0]), mean_stderr(&per_run[1]));
    let (dw, di) = (diff(&per_run[0], &per_run[1]), diff(&per_run[2], &per_run[3]));
    println!("whole image: linear {lw:?}, nearest {nw:?}, closed forms {predicted:?}; difference {dw:?}, band {band}; interior difference {di:?}");
    let slack = 2e-5 * predicted[0];
    // Each image mean is its closed form
    for ((m, se), p, what) in [(lw, predicted[0], "linear"), (nw, predicted[1], "nearest")] {
        assert!((m - p).abs() < k * se + slack, "{what}: image mean {m} ± {se}, closed form {p}");
    }
    // Interior: no structural difference at all
    assert!(
        di.0.abs() < k * di.1 + slack,
        "interior region means differ by {} ± {} between linear and nearest",
        di.0,
        di.1
    );
    // Whole image: exactly the boundary band's difference, resolved by these samples (a
    // reconstruction that changed the interior, or lost the band, fails here)
    assert!(
        (dw.0 - band).abs() < k * dw.1 + slack,
        "whole-image means differ by {} ± {}, the band predicts {band}",
        dw.0,
        dw.1
    );
    assert!(
        band.abs() > 10.0 * (k * dw.1 + slack),
        "the band difference {band} is not resolved by this many samples ({dw:?})"
    );
}

// ---------------------------------------------------------------------------------------
// Bit-identity with linear and scattering (library)

#[test]
fn linear_scattering_renders_are_bit_identical_for_any_thread_count() {
    let ex = plume_synth::explosion(&plume_synth::ExplosionParams {
        resolution: 32,
        seed: 5,
        ..Default::default()
    });
    let e = Emission {
        kind: EmissionKind::Blackbody,
        scale: 1e-3,
        cutoff_kelvin: 500.0,
        ..grid_emission(Convention::Physical)
    };
    let camera = Camera::look_at(
        DVec3::new(0.0, 0.2, -6.5),
        DVec3::new(0.0, 0.2, 0.0),
        DVec3::Y,
        40.0,
        24,
        16,
    )
    .unwrap();
    for ls in [LightSampling::Fnee, LightSampling::Nee] {
        let vol = Volume::build(&ex.density, Some(&ex.temperature), |v| e.map_source(v)).unwrap();
        let lights = Lights::build(&vol, &e, ls, 8).unwrap();
        let medium = Medium {
            sigma_t: 4.0,
            albedo: plume_core::color::Rgb::splat(0.8),
            g: 0.3,
            emission: e,
            extinction: Default::default(),
        };
        let scene = AnyScene::new(
            Scene { field: vol, medium, camera, lights, motion: None, majorants: None },
            Interpolation::Linear,
        );
        assert_eq!(scene.interpolation(), Interpolation::Linear);
        let estimator = if ls == LightSampling::Nee { Estimator::Point } else { Estimator::Line };
        let integrator = Integrator {
            estimator,
            camera_estimator: None,
            light_sampling: ls,
            mis: MisHeuristic::Power,
            max_depth: 8,
            tracking: Tracking::Regular,
            split: 1,
            camera_collision: Collision::Analog,
            point_lookup: plume_engine::integrator::PointLookup::Exact,
            split_by: plume_engine::integrator::SplitBy::Uniform,
        };
        let one = pixels(&scene, integrator, 3, 21, 1);
        let two = pixels(&scene, integrator, 3, 21, 2);
        assert!(one.iter().any(|p| p[0] > 0.0), "{ls:?}: the image is black");
        assert_eq!(pixel_bits(&one), pixel_bits(&two), "{ls:?}: 1 and 2 threads give other bits");
    }
}

// ---------------------------------------------------------------------------------------
// The command line and scene files

/// Flags of the small renders below (a generated 32³ explosion, scattering).
const SMALL: [&str; 9] =
    ["--width", "24", "--height", "16", "--density-scale", "3", "--albedo", "0.8", "-q"];

/// `plume render input -o out` with `SMALL` and `extra`, which must succeed.
#[track_caller]
fn render_cli(input: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec!["render", s(input), "-o", s(out)];
    args.extend(SMALL);
    args.extend_from_slice(extra);
    let o = plume(&args);
    assert!(o.status.success(), "{args:?}: {}", stderr(&o));
    o
}

fn header(p: &Path, key: &str) -> String {
    plume::output::read_exr_contents(p)
        .unwrap()
        .metadata
        .get(&format!("plume:{key}"))
        .cloned()
        .unwrap_or_default()
}

fn bits(p: &Path) -> Vec<u32> {
    pixel_bits(&exr_pixels(p))
}

#[test]
fn the_flag_and_the_scene_key_choose_the_reconstruction_and_the_image_records_it() {
    let d = tmpdir("interp", "choose");
    let ex = explosion(&d, 32, Some(2));
    let image = |name: &str| d.join(name);
    render_cli(&ex, &image("linear.exr"), &["--spp", "2", "--interpolation", "linear"]);
    render_cli(&ex, &image("nearest.exr"), &["--spp", "2", "--interpolation", "nearest"]);
    render_cli(&ex, &image("default.exr"), &["--spp", "2"]);
    assert!(exr_pixels(&image("linear.exr")).iter().any(|p| p[0] > 0.0), "the explosion emits");
    assert_eq!(bits(&image("default.exr")), bits(&image("linear.exr")), "linear is the default");
    assert_ne!(
        bits(&image("nearest.exr")),
        bits(&image("linear.exr")),
        "nearest and linear are different volumes"
    );
    // The header's scene says which, and the settings hash tells them apart
    for (name, value) in
        [("linear.exr", "linear"), ("nearest.exr", "nearest"), ("default.exr", "linear")]
    {
        let scene = header(&image(name), "scene");
        assert!(scene.contains(&format!("interpolation = \"{value}\"")), "{name}: {scene}");
    }
    assert_eq!(
        header(&image("default.exr"), "settingsHash"),
        header(&image("linear.exr"), "settingsHash")
    );
    assert_ne!(
        header(&image("nearest.exr"), "settingsHash"),
        header(&image("linear.exr"), "settingsHash")
    );

    // The scene key is honoured, a flag beside the file overrides it
    let shot = d.join("shot.toml");
    std::fs::write(
        &shot,
        "[volume]\nfile = \"ex.vdb\"\ninterpolation = \"nearest\"\n[medium]\ndensity_scale = 3\nalbedo = 0.8\n\
         [camera]\nwidth = 24\nheight = 16\n[render]\nspp = 2\nquiet = true\n",
    )
    .unwrap();
    let o = plume(&["render", s(&shot), "-o", s(&image("file.exr"))]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        bits(&image("file.exr")),
        bits(&image("nearest.exr")),
        "volume.interpolation = \"nearest\""
    );
    let o = plume(&[
        "render",
        s(&shot),
        "-o",
        s(&image("file-linear.exr")),
        "--interpolation",
        "linear",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        bits(&image("file-linear.exr")),
        bits(&image("linear.exr")),
        "--interpolation beside the file"
    );

    // --write-scene writes the resolved choice
    for (extra, value) in [(&[][..], "linear"), (&["--interpolation", "nearest"][..], "nearest")] {
        let written = d.join("written.toml");
        let unused = image("unused.exr");
        let mut args = vec!["render", s(&ex), "-o", s(&unused), "--write-scene", s(&written)];
        args.extend_from_slice(extra);
        let o = plume(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        let text = std::fs::read_to_string(&written).unwrap();
        assert!(text.contains(&format!("\ninterpolation = \"{value}\"\n")), "{extra:?}: {text}");
    }
    let o = plume(&[
        "render",
        s(&shot),
        "-o",
        s(&image("unused.exr")),
        "--write-scene",
        s(&d.join("over.toml")),
        "--interpolation",
        "linear",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(std::fs::read_to_string(d.join("over.toml"))
        .unwrap()
        .contains("interpolation = \"linear\""));
}

#[test]
fn a_bad_interpolation_is_refused_naming_the_flag_or_the_file_line_and_key() {
    let d = tmpdir("interp", "bad");
    let ex = explosion(&d, 32, Some(2));
    let out = d.join("o.exr");
    let err = plume_exits(
        &["render", s(&ex), "-o", s(&out), "--interpolation", "cubic"],
        2,
        &["--interpolation", "cubic"],
    );
    assert_eq!(err.lines().filter(|l| l.contains("error")).count(), 1, "one error line: {err}");
    let shot = d.join("bad.toml");
    std::fs::write(
        &shot,
        "[volume]\nfile = \"ex.vdb\"\ninterpolation = \"cubic\"\n[output]\nimage = \"o.exr\"\n",
    )
    .unwrap();
    let at = format!("{}:3:", shot.display());
    let err = plume_exits(&["render", s(&shot)], 2, &[&at, "volume.interpolation", "cubic"]);
    assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
    assert!(!out.exists(), "nothing rendered");
}

#[test]
fn parts_and_resumed_renders_never_mix_nearest_and_linear() {
    let d = tmpdir("interp", "mix");
    let ex = explosion(&d, 32, Some(4));
    let part = |name: &str, range: &str, interpolation: &str| {
        let p = d.join(name);
        render_cli(&ex, &p, &["--sample-range", range, "--interpolation", interpolation]);
        p
    };
    let near_a = part("near.a.exr", "0..2", "nearest");
    let lin_a = part("lin.a.exr", "0..2", "linear");
    let lin_b = part("lin.b.exr", "2..4", "linear");
    let merged = d.join("merged.exr");
    let err = plume_exits(
        &["merge", "-o", s(&merged), s(&near_a), s(&lin_b)],
        3,
        &["settings hash", s(&lin_b)],
    );
    assert_eq!(err.lines().filter(|l| l.contains("error")).count(), 1, "{err}");
    assert!(!merged.exists());
    // The same parts rendered linear merge, to the bits of one linear render
    let o = plume(&["merge", "-o", s(&merged), s(&lin_a), s(&lin_b)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let whole = d.join("whole.exr");
    render_cli(&ex, &whole, &["--spp", "4", "--interpolation", "linear"]);
    assert_eq!(bits(&merged), bits(&whole));

    // A render with sums is continued only by the same reconstruction
    let resumed = d.join("resumed.exr");
    render_cli(&ex, &resumed, &["--spp", "2", "--sums", "--interpolation", "nearest"]);
    let o = render_cli(&ex, &resumed, &["--spp", "4", "--sums", "--interpolation", "linear"]);
    assert!(
        stderr(&o).contains("other settings") && !stderr(&o).contains("continuing"),
        "{}",
        stderr(&o)
    );
    assert_eq!(bits(&resumed), bits(&whole), "rendered again from sample 0, linear");
}

#[test]
fn linear_renders_through_an_automatic_cache_tile_by_tile_equal_in_core_ones() {
    // A 64 KiB budget sends the .vdb (≈ 100 KB of leaves) through an automatic cache, and
    // tile-major order reads it ahead tile by tile: the image is the in-core one, bit for bit
    let d = tmpdir("interp", "ooc");
    let ex = explosion(&d, 32, Some(6));
    let cache_dir = d.join("cache");
    let flags = ["--spp", "3", "--interpolation", "linear", "--seed", "8"];
    render_cli(&ex, &d.join("core.exr"), &flags);
    let out_of_core = [
        &flags[..],
        &["--memory-budget", "64KiB", "--cache-dir", s(&cache_dir), "--sample-order", "tile-major"],
    ]
    .concat();
    render_cli(&ex, &d.join("ooc.exr"), &out_of_core);
    let caches = common::names_in(&cache_dir, |n| n.ends_with(".plume"));
    assert_eq!(caches.len(), 1, "an automatic cache was made: {caches:?}");
    assert!(exr_pixels(&d.join("core.exr")).iter().any(|p| p[0] > 0.0), "the image is black");
    assert_eq!(bits(&d.join("ooc.exr")), bits(&d.join("core.exr")));
}

// ---------------------------------------------------------------------------------------
// Emission between voxel centres in Cycles' convention

/// `--convention cycles` with blackbody emission interpolates each voxel's emission,
/// `L_e(x) = Σ_c w_c le(T_c)`, as the physical convention does: Cycles 5.0.1 looks OpenVDB
/// grids up by stochastic one-tap sampling (one corner voxel drawn with probability
/// `w_c`), whose expected value is that same per-voxel rule (`scripts/compare-cycles.sh`
/// checks it against Cycles; interpolating the temperature first is darker). Along a ray through a temperature ramp with no
/// absorption to speak of (σ_t = 10⁻⁹: no collision, τ = 1), the line estimator is the
/// closed form, so every path returns `∫ Σ w_c le(T_c) ds` of a 10⁵-step midpoint march
/// to 10⁻⁶; the temperature-interpolated integral is far from it, so the test can fail.
#[test]
fn cycles_convention_interpolates_each_voxels_emission() {
    let xf = DAffine3::IDENTITY;
    let leaves = [IVec3::ZERO];
    let density = grid("density", xf, &leaves, |_| 1.0);
    // 300 K … 3800 K along x: the T⁴-like blackbody is far from linear across a voxel
    let temperature = grid("temperature", xf, &leaves, |p| 300.0 + 500.0 * p.x as f32);
    let emission = Emission {
        kind: EmissionKind::Blackbody,
        convention: Convention::Cycles,
        scale: 1.0,
        color: plume_core::color::Rgb::ONE,
        temperature_map: plume_engine::medium::TemperatureMap::Kelvin,
        cutoff_kelvin: 0.0,
    };
    let volume = Volume::build(&density, Some(&temperature), |v| emission.map_source(v)).unwrap();
    let medium = Medium {
        sigma_t: 1e-9,
        albedo: plume_core::color::Rgb::splat(0.0),
        g: 0.0,
        emission,
        extinction: Default::default(),
    };
    let field = plume_volume::trilinear::Trilinear::new(volume);
    let ray = plume_volume::field::Ray { origin: DVec3::new(-2.0, 3.3, 4.6), direction: DVec3::X };
    // Reference: midpoint march over the support x ∈ [−1, 8] of both rules
    let steps = 100_000;
    let (x0, x1) = (-1.0, 8.0);
    let h = (x1 - x0) / f64::from(steps);
    let (mut of_temperature, mut per_voxel) = (0.0, 0.0);
    for k in 0..steps {
        let p = DVec3::new(x0 + (f64::from(k) + 0.5) * h, ray.origin.y, ray.origin.z);
        let v = plume_volume::Field::values_at(&field, p);
        of_temperature += f64::from(emission.le(v.density, v.source).0[0]) * h;
        per_voxel +=
            plume_volume::Field::reconstruct(&field, p, &|d, s| emission.le(d, s)).emission[0] * h;
    }
    for i in 0..16u64 {
        let mut sampler = plume_core::sampling::Sampler::new(77, 0, i);
        let u = sampler.next_f64();
        let r = plume_engine::medium::track(
            &field,
            &medium,
            &ray,
            f64::INFINITY,
            Estimator::Line,
            Collision::Skip,
            u,
            &mut sampler,
        );
        let line = r.emission[0];
        assert!(
            (line - per_voxel).abs() <= 1e-6 * per_voxel,
            "path {i}: line estimator {line}, per-voxel rule {per_voxel}"
        );
    }
    assert!(
        (per_voxel - of_temperature).abs() > 0.01 * per_voxel,
        "per-voxel {per_voxel} too close to the temperature-interpolated {of_temperature}"
    );
    println!("per-voxel rule: ∫L_e = {per_voxel:.6e}; temperature interpolated first {of_temperature:.6e}");
}
