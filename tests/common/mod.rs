//! Shared test harness of the one test binary (`tests/suite.rs`): chi-square goodness of
//! fit in the style of Mitsuba 3's `chi2.py` (cells pooled to ≥ 5 expected counts, `f64`
//! statistics, Šidák correction for the number of tests, histograms dumped on failure),
//! synthetic grid builders, the sampling tier's chi² family and direction bins, the
//! `plume` binary as a child process, scratch directories, data paths, VDB grid reads, EXR
//! pixels, Monte Carlo statistics, and the region means of in-process renders that the
//! path-integrator tiers compare.

use std::f64::consts::PI;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Output;
use std::time::Duration;

use glam::{DAffine3, DVec3, IVec3};
use plume::vdb::{leaf_offset, read_float_grid, FloatGrid, ReadLimits, LEAF_VOXELS};
use plume_core::color::Rgb;
use plume_core::sampling::{Sampler, SamplerKind};
use plume_engine::integrator::{AnyScene, Integrator};
use plume_engine::medium::{Convention, Emission, EmissionKind, TemperatureMap};
use plume_engine::render::{render, RenderSettings, SampleBudget};
use statrs::distribution::{ChiSquared, ContinuousCDF};

/// Fewest expected counts a cell may have before it is pooled with others.
pub const MIN_EXPECTED: f64 = 5.0;

/// Result of one chi-square test (tests print it with `{:?}`, which the dead-code lint does
/// not count as reading its fields).
#[derive(Clone, Copy, Debug)]
#[allow(dead_code)]
pub struct Chi2Outcome {
    /// Pearson's statistic Σ (o − e)²/e over pooled cells.
    pub statistic: f64,
    /// Degrees of freedom: pooled cells − 1.
    pub dof: usize,
    /// Probability of a statistic at least this large under the null hypothesis.
    pub p_value: f64,
    /// Per-test significance level after the Šidák correction.
    pub significance: f64,
}

/// Per-test level that keeps the family-wise false-failure rate at `alpha` over
/// `test_count` independent tests: `1 − (1 − α)^(1/n)`.
#[must_use]
pub fn sidak(alpha: f64, test_count: usize) -> f64 {
    -((-alpha).ln_1p() / test_count as f64).exp_m1()
}

/// Where failing histograms go: `$CARGO_TARGET_DIR/chi2` or `<crate>/target/chi2`.
fn dump_dir() -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR")
        .map_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target"), PathBuf::from)
        .join("chi2")
}

fn dump(name: &str, observed: &[f64], expected: &[f64], why: &str) -> PathBuf {
    let dir = dump_dir();
    let path = dir.join(format!("{name}.tsv"));
    let mut text = format!("# {why}\n# cell\tobserved\texpected\t(o-e)/sqrt(e)\n");
    for (i, (&o, &e)) in observed.iter().zip(expected).enumerate() {
        let z = if e > 0.0 { (o - e) / e.sqrt() } else { f64::NAN };
        let _ = writeln!(text, "{i}\t{o}\t{e}\t{z:.3}");
    }
    let _ = std::fs::create_dir_all(&dir).and_then(|()| std::fs::write(&path, &text));
    path
}

/// Chi-square goodness-of-fit test of `observed` counts against `expected` counts (same
/// cell order, same total up to the distribution's mass), at family-wise level `alpha`
/// over `test_count` tests.
///
/// Cells are sorted by expected count; cells below [`MIN_EXPECTED`] are pooled until the
/// pool reaches it. A sample in a cell of zero expected count fails at once.
///
/// # Panics
/// When the test fails, after printing a summary and dumping both histograms to
/// `target/chi2/<name>.tsv`.
pub fn chi2_test(
    name: &str,
    observed: &[f64],
    expected: &[f64],
    alpha: f64,
    test_count: usize,
) -> Chi2Outcome {
    assert_eq!(observed.len(), expected.len(), "{name}: histogram sizes differ");
    let significance = sidak(alpha, test_count);
    let mut order: Vec<usize> = (0..expected.len()).collect();
    order.sort_by(|&a, &b| expected[a].total_cmp(&expected[b]));
    let (mut statistic, mut cells) = (0.0f64, 0usize);
    let (mut pool_o, mut pool_e) = (0.0f64, 0.0f64);
    for &i in &order {
        let (o, e) = (observed[i], expected[i]);
        assert!(e.is_finite() && e >= 0.0, "{name}: expected count {e} in cell {i}");
        if e == 0.0 {
            if o > 0.0 {
                let path = dump(name, observed, expected, "samples in a cell of zero probability");
                panic!(
                    "{name}: {o} samples in cell {i} of zero expected count; histograms in {}",
                    path.display()
                );
            }
        } else if e < MIN_EXPECTED {
            pool_o += o;
            pool_e += e;
            if pool_e >= MIN_EXPECTED {
                statistic += (pool_o - pool_e).powi(2) / pool_e;
                cells += 1;
                pool_o = 0.0;
                pool_e = 0.0;
            }
        } else {
            statistic += (o - e).powi(2) / e;
            cells += 1;
        }
    }
    if pool_e > 0.0 {
        statistic += (pool_o - pool_e).powi(2) / pool_e;
        cells += 1;
    }
    assert!(cells >= 2, "{name}: only {cells} cells after pooling; use more samples or bins");
    let dof = cells - 1;
    let p_value = ChiSquared::new(dof as f64).expect("dof > 0").sf(statistic);
    let outcome = Chi2Outcome { statistic, dof, p_value, significance };
    println!("chi2 {name}: statistic {statistic:.2}, dof {dof}, p = {p_value:.4} (reject below {significance:.2e})");
    if p_value.is_nan() || p_value < significance {
        let path = dump(name, observed, expected, &format!("{outcome:?}"));
        panic!(
            "{name}: chi-square rejected the sampler, {outcome:?}; histograms in {}",
            path.display()
        );
    }
    outcome
}

/// A float grid with the given 8³ leaves; each leaf's values from `f(voxel ijk)`.
pub fn grid(name: &str, xf: DAffine3, leaves: &[IVec3], f: impl Fn(IVec3) -> f32) -> FloatGrid {
    let mut values = Vec::with_capacity(leaves.len() * LEAF_VOXELS);
    for &o in leaves {
        let mut block = vec![0.0f32; LEAF_VOXELS];
        for x in 0..8 {
            for y in 0..8 {
                for z in 0..8 {
                    block[leaf_offset(x, y, z)] = f(o + IVec3::new(x, y, z));
                }
            }
        }
        values.extend(block);
    }
    FloatGrid {
        name: name.into(),
        world_from_index: xf,
        background: 0.0,
        origins: leaves.to_vec(),
        values,
    }
}

/// A deterministic 32-bit hash of a voxel and a seed.
#[must_use]
pub fn hash(p: IVec3, seed: u32) -> u32 {
    let mut h = (p.x as u32).wrapping_mul(0x8da6_b343)
        ^ (p.y as u32).wrapping_mul(0xd816_3841)
        ^ (p.z as u32).wrapping_mul(0xcb1a_b31f)
        ^ seed.wrapping_mul(0x9e37_79b9);
    h ^= h >> 15;
    h = h.wrapping_mul(0x2c1b_3c6d);
    h ^ (h >> 12)
}

/// Mean and standard error of the mean of `n` samples from their sum and sum of squares
/// (the population variance, clamped at 0 against rounding).
#[must_use]
pub fn mean_stderr_from_sums(sum: f64, sum_sq: f64, n: u64) -> (f64, f64) {
    let mean = sum / n as f64;
    let var = (sum_sq / n as f64 - mean * mean).max(0.0);
    (mean, (var / n as f64).sqrt())
}

/// Mean and standard error of the mean of independent estimates (the sample variance,
/// divided by `n − 1`).
#[must_use]
pub fn mean_stderr(values: &[f64]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let variance = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (variance / n).sqrt())
}

/// Grid emission in `convention`: `L_e` = source (grey), unscaled, no cutoff.
#[must_use]
pub fn grid_emission(convention: Convention) -> Emission {
    Emission {
        kind: EmissionKind::Grid,
        convention,
        scale: 1.0,
        color: Rgb::ONE,
        temperature_map: TemperatureMap::Kelvin,
        cutoff_kelvin: 0.0,
    }
}

// ---------------------------------------------------------------------------------------
// The sampling tier: `tests/sampling.rs` and `tests/light_sampling.rs`

/// Family-wise significance level of the sampling tier's chi² tests, both files together.
pub const SAMPLING_ALPHA: f64 = 0.01;
/// Number of chi² tests in the sampling tier: HG ×5, alias (`sampling.rs`); proxy cells ×2,
/// FNEE ×3, NEE in voxel boxes and from the trilinear hat, each with a voxel and a brick
/// table (`light_sampling.rs`).
pub const SAMPLING_TESTS: usize = 5 + 1 + 2 + 3 + 2 * 2;

/// The sampler of the sampling tier's tests: `seed`, pixel 0, sample 0. The i.i.d. hashed
/// stream (`Sampler::new`, the `random` kind): chi² counts assume independent draws.
pub fn rng(seed: u64) -> Sampler {
    Sampler::new(seed, 0, 0)
}

/// A unit-sphere frame `(t1, t2)` around `pole`, built independently of the library.
pub fn frame(pole: DVec3) -> (DVec3, DVec3) {
    let helper = if pole.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    let t1 = pole.cross(helper).normalize();
    (t1, pole.cross(t1))
}

/// Bin of direction `w` in a (cos θ, φ) grid around `pole` covering `cos θ ∈ [c_min, 1]`,
/// or `None` below `c_min`.
pub fn direction_bin(
    w: DVec3,
    pole: DVec3,
    (t1, t2): (DVec3, DVec3),
    c_min: f64,
    nc: usize,
    nphi: usize,
) -> Option<usize> {
    let c = w.dot(pole);
    if c < c_min {
        return None;
    }
    let ic = (((c - c_min) / (1.0 - c_min) * nc as f64) as usize).min(nc - 1);
    let phi = w.dot(t2).atan2(w.dot(t1)).rem_euclid(2.0 * PI);
    let ip = ((phi / (2.0 * PI) * nphi as f64) as usize).min(nphi - 1);
    Some(ic * nphi + ip)
}

// ---------------------------------------------------------------------------------------
// The `plume` binary, files and directories

/// The `plume` binary under test.
pub const PLUME: &str = env!("CARGO_BIN_EXE_plume");

/// The real-data smoke file (one half-float `density` grid), relative to the crate root.
pub const SMOKE: &str = "../shared/data/smoke/openvdb_org_smoke1.vdb";

/// Run the `plume` binary under test.
pub fn plume(args: &[&str]) -> Output {
    std::process::Command::new(PLUME).args(args).output().expect("run plume")
}

/// The `[r, g, b, alpha]` a `--debug-pixel` run prints on stdout.
///
/// # Panics
/// If stdout is not a bracketed list of numbers.
#[must_use]
pub fn replayed_values(o: &Output) -> Vec<f64> {
    let printed = String::from_utf8_lossy(&o.stdout);
    printed
        .trim()
        .trim_matches(|c| c == '[' || c == ']')
        .split(',')
        .map(|v| v.trim().parse().unwrap())
        .collect()
}

/// A run's stderr as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Run the `plume` binary with `args`, expecting exit `code` and every one of `needles` in
/// its stderr; returns the stderr.
#[track_caller]
pub fn plume_exits(args: &[&str], code: i32, needles: &[&str]) -> String {
    let o = plume(args);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(code), "{args:?}: {err}");
    for needle in needles {
        assert!(err.contains(needle), "{args:?}: {err:?} lacks {needle:?}");
    }
    err
}

/// [`plume_exits`] for bad input: the error is one line, and `out` was not written.
pub fn refused_in_one_line(args: &[&str], code: i32, needles: &[&str], out: &Path) {
    let err = plume_exits(args, code, needles);
    assert_eq!(err.trim().lines().count(), 1, "{args:?}: one line, got {err:?}");
    assert!(!out.exists(), "{args:?}: wrote {}", out.display());
}

/// Say loudly why `test` did not run (a machine without root, packages or cgroups),
/// straight to stderr: `std::io::stderr()` is not the harness's captured output (an
/// `eprintln!` of a passing test would be hidden).
pub fn skip(test: &str, reason: &str) {
    use std::io::Write as _;
    let _ = writeln!(
        std::io::stderr(),
        "\n**********\nSKIPPED: {test} did not run: {reason}\n**********"
    );
}

/// A fresh, empty temporary directory `plume-<tier>-<name>-<pid>` for one test.
pub fn tmpdir(tier: &str, name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("plume-{tier}-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("create temp dir");
    d
}

/// A fresh, empty scratch directory `<tier>/<name>` under Cargo's per-target temp dir.
pub fn scratch_dir(tier: &str, name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(tier).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create scratch dir");
    dir
}

/// A path as `&str` (test paths are UTF-8).
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A file of the real data set (`../shared/data`, see its PROVENANCE.md), absolute.
pub fn data(relative: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data").join(relative)
}

/// plume's own tiny fixtures, written by OpenVDB (`data/fixtures/make_fixtures.cc`).
pub fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/fixtures").join(name)
}

/// A grid of a real data file (`../shared/data/<relative>`) by selector, default limits.
pub fn read(relative: &str, selector: &str) -> plume::Result<FloatGrid> {
    read_float_grid(&data(relative), &selector.parse().unwrap(), &ReadLimits::default())
}

/// The leaves of `grid` keyed by origin.
pub fn leaves_by_origin(grid: &FloatGrid) -> std::collections::HashMap<IVec3, Vec<f32>> {
    (0..grid.leaf_count()).map(|i| (grid.origins[i], grid.leaf_values(i).to_vec())).collect()
}

/// `plume synth explosion --resolution <resolution> [--seed <seed>] -o <path>`, which must
/// succeed.
#[track_caller]
pub fn synth_explosion(path: &Path, resolution: u32, seed: Option<i64>) {
    let resolution = resolution.to_string();
    let seed = seed.map(|v| v.to_string());
    let mut args = vec!["synth", "explosion", "--resolution", &resolution];
    if let Some(seed) = &seed {
        args.extend(["--seed", seed]);
    }
    args.extend(["-o", s(path)]);
    let o = plume(&args);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// A generated explosion `dir/ex.vdb` (see [`synth_explosion`]).
#[track_caller]
pub fn explosion(dir: &Path, resolution: u32, seed: Option<i64>) -> PathBuf {
    let p = dir.join("ex.vdb");
    synth_explosion(&p, resolution, seed);
    p
}

/// The RGBA pixels of an EXR file.
pub fn exr_pixels(p: &Path) -> Vec<[f32; 4]> {
    plume::output::read_exr(p).unwrap().pixels
}

/// Every float channel of an EXR by name.
pub fn channels(path: &Path) -> std::collections::BTreeMap<String, Vec<f32>> {
    plume::output::read_exr_channels(path).unwrap().channels.into_iter().collect()
}

/// The bits of every value of every channel of [`channels`].
pub fn bits(
    c: &std::collections::BTreeMap<String, Vec<f32>>,
) -> std::collections::BTreeMap<String, Vec<u32>> {
    c.iter().map(|(k, v)| (k.clone(), v.iter().map(|x| x.to_bits()).collect())).collect()
}

/// The bits of every channel of every pixel (the comparison for "bit-identical").
pub fn pixel_bits(pixels: &[[f32; 4]]) -> Vec<u32> {
    pixels.iter().flatten().map(|v| v.to_bits()).collect()
}

/// Names of the entries of `dir` for which `keep` holds.
pub fn names_in(dir: &Path, keep: impl Fn(&str) -> bool) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| keep(n))
        .collect()
}

// ---------------------------------------------------------------------------------------
// Stand-in VDB readers

/// An executable `#!/bin/sh` script `name` running `body`, in `<tier>` under Cargo's
/// per-target temp dir (created if missing, not emptied).
pub fn shell_script(tier: &str, name: &str, body: &str) -> PathBuf {
    use std::os::unix::fs::PermissionsExt;
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(tier);
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, format!("#!/bin/sh\n{body}\n")).unwrap();
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).unwrap();
    path
}

/// Runs `attempt`, which spawns `reader`, again while the spawn fails with ETXTBSY: another
/// test thread's fork still holds the freshly written script open for writing. Up to 50
/// tries, 20 ms apart.
pub fn retry_while_busy<T>(
    reader: &Path,
    mut attempt: impl FnMut() -> plume::Result<T>,
) -> plume::Result<T> {
    for _ in 0..50 {
        match attempt() {
            Err(plume::Error::ReaderSpawn { source, .. })
                if source.raw_os_error() == Some(libc::ETXTBSY) =>
            {
                std::thread::sleep(Duration::from_millis(20));
            }
            other => return other,
        }
    }
    panic!("{} stayed busy", reader.display());
}

/// The generated explosion's physical blackbody emission.
pub fn explosion_emission() -> Emission {
    Emission::blackbody(1e-3)
}

/// The generated explosion (32³, seed 5) with [`explosion_emission`]'s blackbody as its
/// source: the path-integrator tiers' test volume.
pub fn explosion_volume() -> plume_volume::Volume {
    let ex = plume_synth::explosion(&plume_synth::ExplosionParams {
        resolution: 32,
        seed: 5,
        ..Default::default()
    });
    let e = explosion_emission();
    plume_volume::Volume::build(&ex.density, Some(&ex.temperature), |v| e.map_source(v)).unwrap()
}

/// [`explosion_volume`] seen by the 10×8 camera of the mean tests, albedo 0.8, g 0.3,
/// density scale `sigma_t`, reconstructed by `interpolation`, with the lights `lights`
/// builds for it and, when `majorants`, its majorants for null collisions.
pub fn explosion_scene(
    sigma_t: f64,
    interpolation: plume_volume::Interpolation,
    majorants: bool,
    lights: impl FnOnce(&plume_volume::Volume, &Emission) -> plume_engine::integrator::Lights,
) -> AnyScene {
    let vol = explosion_volume();
    let e = explosion_emission();
    let lights = lights(&vol, &e);
    let majorants = majorants.then(|| plume_volume::majorant::MajorantGrid::new(&vol, 0.0));
    let camera = plume_engine::camera::Camera::look_at(
        DVec3::new(0.0, 0.2, -6.5),
        DVec3::new(0.0, 0.2, 0.0),
        DVec3::Y,
        40.0,
        10,
        8,
    )
    .unwrap();
    let medium = plume_engine::medium::Medium {
        sigma_t,
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
            majorants,
        },
        interpolation,
    )
}

/// Mean of `r + g + b` over the whole image and over its 4 quadrants (in that order) of
/// one in-process render of `spp` samples per pixel under `seed`.
pub fn regions(
    scene: &AnyScene,
    integrator: Integrator,
    sampler: SamplerKind,
    spp: u32,
    seed: u64,
) -> [f64; 5] {
    let settings = RenderSettings {
        budget: SampleBudget::Spp(spp),
        seed,
        sampler,
        threads: 0,
        first_sample: 0,
        adaptive: None,
        integrator,
    };
    let r = plume_engine::with_scene!(scene, s => render(s, &settings, &|_, _| {}));
    let px = r.film.average();
    let (w, h) = (scene.camera().width as usize, scene.camera().height as usize);
    let (mut acc, mut cnt) = ([0.0f64; 5], [0.0f64; 5]);
    for y in 0..h {
        for x in 0..w {
            let v = f64::from(px[y * w + x][0] + px[y * w + x][1] + px[y * w + x][2]);
            let q = 1 + usize::from(x >= w / 2) + 2 * usize::from(y >= h / 2);
            for k in [0, q] {
                acc[k] += v;
                cnt[k] += 1.0;
            }
        }
    }
    std::array::from_fn(|k| acc[k] / cnt[k])
}

/// Per-region means ([`regions`]) over `runs` independent renders (seeds `seed0…`), with
/// standard errors from the spread of the runs.
///
/// Runs differ in seed, so with Sobol each run has its own per-pixel scrambles: run means
/// are independent and unbiased (randomized quasi-Monte Carlo), and their spread is an
/// honest standard error even though the samples within a run are not independent.
pub fn region_means_with(
    sampler: SamplerKind,
    scene: &AnyScene,
    integrator: Integrator,
    spp: u32,
    runs: u64,
    seed0: u64,
) -> Vec<(f64, f64)> {
    let per_run: Vec<[f64; 5]> =
        (0..runs).map(|run| regions(scene, integrator, sampler, spp, seed0 + run)).collect();
    (0..5).map(|k| mean_stderr(&per_run.iter().map(|r| r[k]).collect::<Vec<_>>())).collect()
}

/// Asserts that every region's mean in `got` agrees with `reference`'s within `z_max`
/// combined standard errors (`|m − r| / √(se_m² + se_r²)`), naming `label` and the region.
pub fn assert_same_means(label: &str, got: &[(f64, f64)], reference: &[(f64, f64)], z_max: f64) {
    for (k, ((m, se), (rm, rse))) in got.iter().zip(reference).enumerate() {
        let z = (m - rm) / (se * se + rse * rse).sqrt().max(1e-12);
        assert!(z.abs() < z_max, "{label} region {k}: {m} ± {se} vs {rm} ± {rse} (z = {z:.2})");
    }
}

/// Renders `base` (a `plume render` command line ending in `--stats`) once per
/// `(name, value)`: with `flag value`, or without the flag where `value` is `None`, to
/// `dir/name.exr` with its stats in `dir/name.json`. Returns each render's settings hash.
///
/// # Panics
/// If a render fails or its stats have no settings hash.
pub fn settings_hashes(
    dir: &Path,
    base: &[&str],
    flag: &str,
    values: &[(&str, Option<&str>)],
) -> Vec<String> {
    values
        .iter()
        .map(|&(name, value)| {
            let (out, stats) = (dir.join(format!("{name}.exr")), dir.join(format!("{name}.json")));
            let mut args = base.to_vec();
            args.extend([s(&stats), "-o", s(&out)]);
            if let Some(value) = value {
                args.extend([flag, value]);
            }
            let o = plume(&args);
            assert!(o.status.success(), "{name}: {}", String::from_utf8_lossy(&o.stderr));
            let json: serde_json::Value = serde_json::from_str(
                std::fs::read_to_string(&stats).unwrap().lines().last().unwrap(),
            )
            .unwrap();
            json["settings_hash"].as_str().expect("a settings hash").to_string()
        })
        .collect()
}

/// Renders `vdb` from a scene file `dir/scene.toml` whose `[integrator]` section holds
/// `keys` (TOML lines), albedo 0.8, `width × height`, at 4 spp, to `dir/scene.exr`, and
/// returns its pixels: a scene key's image, to compare with its flag's.
///
/// # Panics
/// If the file cannot be written or the render fails.
pub fn render_integrator_keys(
    dir: &Path,
    vdb: &Path,
    keys: &str,
    (width, height): (u32, u32),
) -> Vec<[f32; 4]> {
    let scene_file = dir.join("scene.toml");
    let text = format!("[volume]\nfile = {:?}\n[integrator]\n{keys}\n[medium]\nalbedo = 0.8\n[camera]\nwidth = {width}\nheight = {height}\n", s(vdb));
    std::fs::write(&scene_file, text).unwrap();
    let out = dir.join("scene.exr");
    let o = plume(&["render", s(&scene_file), "--spp", "4", "-o", s(&out)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    exr_pixels(&out)
}

/// Mean and standard error, over 12 renders of `spp` samples with seeds `seed0 + k`, of
/// each channel's image mean.
pub fn image_means<F: plume_volume::Field>(
    scene: &plume_engine::integrator::Scene<F>,
    integrator: Integrator,
    seed0: u64,
    spp: u32,
) -> [(f64, f64); 3] {
    let per_run: Vec<[f64; 3]> = (0..12u64)
        .map(|k| {
            let settings = RenderSettings {
                budget: SampleBudget::Spp(spp),
                seed: seed0 + k,
                sampler: SamplerKind::Sobol,
                threads: 0,
                first_sample: 0,
                adaptive: None,
                integrator,
            };
            let px = render(scene, &settings, &|_, _| {}).film.average();
            std::array::from_fn(|c| {
                px.iter().map(|p| f64::from(p[c])).sum::<f64>() / px.len() as f64
            })
        })
        .collect();
    std::array::from_fn(|c| mean_stderr(&per_run.iter().map(|r| r[c]).collect::<Vec<_>>()))
}

/// Writes `text` to `dir/name` and returns the path.
pub fn write_file(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// The small fire of the real data set (OpenUSD's, 75 KB, about 16 × 16 × 30 world units),
/// absolute.
pub fn fire() -> PathBuf {
    data("fire/openusd_densityAndHeat.vdb")
}
