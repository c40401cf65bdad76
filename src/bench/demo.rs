//! `plume bench demo`: the "clean first picture", measured. The README's main
//! command (`scripts/demo.sh`) renders the sample scene file `data/explosion.toml`; this
//! bench renders that same file as the user would, one `plume render` process per seed,
//! and judges each image against a converged render:
//!
//! - **time**: the wall seconds of the whole process (reading, the pilot, the render,
//!   denoising, the EXR, PNG and statistics written), and its CPU seconds;
//! - **error**: relRMSE over the pixels the smoke covers (the references' mean alpha
//!   above [`COVERED_ALPHA`]), on luminance, against the mean of `R` long renders with
//!   other seeds and no denoising. Their own noise is estimated from their spread and
//!   subtracted: with per-pixel reference mean `r̄` and variance of that mean `v`,
//!
//!   ```text
//!   relRMSE = √max(0, mean(x − r̄)² − mean v) / mean r̄
//!   ```
//!
//!   so a reference's noise does not count against the image;
//! - **specks**: the largest ratio of a covered pixel's luminance to the median of its
//!   5×5 neighbourhood (floored at [`SPECK_FLOOR`] of the mean), where a denoised image
//!   shows a firefly the filter left.
//!
//! The references are kept in the work directory under their settings hash and spp, so a
//! second run renders only the demo. The bench judges; it does not fail: its targets
//! (by default: under a minute, relRMSE ≤ 0.03) are printed as met or not.

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;

use crate::output::{read_exr, read_exr_contents, ExrContents, RgbaImage};
use plume_core::color::rec709_luminance;
use plume_core::error::{Error, Result};
use plume_scene::file::SceneFile;
use plume_scene::Shot;

/// Pixels whose reference alpha exceeds this are the ones the smoke covers.
pub const COVERED_ALPHA: f32 = 0.05;

/// Floor of the neighbourhood median in the speck ratio, as a fraction of the covered
/// pixels' mean luminance (so a pixel beside the background is not a speck of ∞).
pub const SPECK_FLOOR: f64 = 0.01;

/// What `plume bench demo` measures.
#[derive(Clone, Debug)]
pub struct DemoConfig {
    /// The `plume` binary that renders (the running one).
    pub exe: PathBuf,
    /// The scene file (`data/explosion.toml`).
    pub scene: PathBuf,
    /// Seeds of the timed demo renders.
    pub seeds: Vec<u64>,
    /// Samples per pixel of each reference render.
    pub reference_spp: u32,
    /// Seeds of the reference renders (at least 2, to estimate their noise; none of the
    /// demo's).
    pub reference_seeds: Vec<u64>,
    /// Converged renders of the same scene with other seeds, made elsewhere (at least 2):
    /// used instead of rendering `reference_seeds`.
    pub references: Vec<PathBuf>,
    /// Where the renders and the kept references go.
    pub work_dir: PathBuf,
    /// The directory relative paths are relative to: the scene files written for the
    /// renders have their paths made absolute against it.
    pub working_dir: PathBuf,
    /// The time target, wall seconds.
    pub target_seconds: f64,
    /// The error target, relRMSE.
    pub target_rel_rmse: f64,
}

/// One timed demo render.
#[derive(Clone, Debug, Serialize)]
pub struct DemoRun {
    /// Its seed.
    pub seed: u64,
    /// Wall seconds of the whole `plume render` process.
    pub wall_seconds: f64,
    /// CPU seconds (user + system of all threads) the render reported.
    pub cpu_seconds: f64,
    /// The image's error against the references.
    pub error: ImageError,
}

/// An image against the references ([`image_error`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ImageError {
    /// relRMSE over the covered pixels, the references' noise subtracted.
    pub rel_rmse: f64,
    /// Mean luminance over the covered pixels ÷ the references'.
    pub mean_ratio: f64,
    /// The references' own relative RMS noise (of their mean), which was subtracted.
    pub reference_noise: f64,
    /// The largest speck ratio ([`largest_speck`]) and its pixel.
    pub speck: Speck,
}

/// A covered pixel against its 5×5 neighbourhood's median.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Speck {
    /// Column.
    pub x: usize,
    /// Row.
    pub y: usize,
    /// Its luminance ÷ max(median of the 5×5 around it, floor).
    pub ratio: f64,
}

/// The whole bench's result.
#[derive(Clone, Debug, Serialize)]
pub struct DemoReport {
    /// The scene file rendered.
    pub scene: PathBuf,
    /// The machine: logical CPUs and model.
    pub cpus: usize,
    /// CPU model name.
    pub cpu_model: String,
    /// Samples per pixel of each reference.
    pub reference_spp: u32,
    /// Reference seeds (rendered by the bench), or none.
    pub reference_seeds: Vec<u64>,
    /// Reference images given instead (`--references`), or none.
    pub references: Vec<PathBuf>,
    /// The timed renders.
    pub runs: Vec<DemoRun>,
    /// The time target, wall seconds.
    pub target_seconds: f64,
    /// The error target.
    pub target_rel_rmse: f64,
}

impl DemoReport {
    /// The table and the verdict, as printed.
    #[must_use]
    pub fn table(&self) -> String {
        let refs = if self.references.is_empty() {
            format!(
                "{} × {} spp (seeds {:?})",
                self.reference_seeds.len(),
                self.reference_spp,
                self.reference_seeds
            )
        } else {
            self.references.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", ")
        };
        let mut s = format!(
            "demo: {} on {} logical CPUs ({}); references: {refs}, noise {:.4} of the mean, subtracted\n\n",
            self.scene.display(),
            self.cpus,
            self.cpu_model,
            self.runs.first().map_or(0.0, |r| r.error.reference_noise)
        );
        s += "| seed | wall s | CPU s | relRMSE | mean ÷ reference | largest speck (pixel) |\n|---|---|---|---|---|---|\n";
        for r in &self.runs {
            let e = &r.error;
            s += &format!(
                "| {} | {:.1} | {:.1} | {:.4} | {:.4} | {:.1}× ({}, {}) |\n",
                r.seed,
                r.wall_seconds,
                r.cpu_seconds,
                e.rel_rmse,
                e.mean_ratio,
                e.speck.ratio,
                e.speck.x,
                e.speck.y
            );
        }
        let yes = |b: bool| if b { "yes" } else { "no" };
        let fast = self.runs.iter().all(|r| r.wall_seconds < self.target_seconds);
        let clean = self.runs.iter().all(|r| r.error.rel_rmse <= self.target_rel_rmse);
        s += &format!(
            "\nunder {} s on every seed: {}; relRMSE ≤ {} on every seed: {}\n",
            self.target_seconds,
            yes(fast),
            self.target_rel_rmse,
            yes(clean)
        );
        s
    }
}

/// Run the bench: the references (rendered once, then kept), then the timed renders.
///
/// # Errors
/// The scene file's errors; [`Error::InvalidArgument`] for fewer than 2 reference seeds
/// or a reference seed among the demo's; a render that fails (its stderr's last line);
/// images of different sizes.
pub fn run(config: &DemoConfig) -> Result<DemoReport> {
    if config.references.len() == 1 {
        return Err(Error::invalid(
            "--references",
            "needs at least 2 images (their spread is the references' noise)",
        ));
    }
    if config.references.is_empty() && config.reference_seeds.len() < 2 {
        return Err(Error::invalid(
            "--reference-seeds",
            "needs at least 2 seeds (their spread is the references' noise)",
        ));
    }
    if let Some(s) = config
        .seeds
        .iter()
        .find(|s| config.references.is_empty() && config.reference_seeds.contains(s))
    {
        return Err(Error::invalid(
            "--reference-seeds",
            format!("seed {s} is also a demo seed: the reference would share its noise"),
        ));
    }
    let (shot, _) = SceneFile::read(&config.scene)?;
    std::fs::create_dir_all(&config.work_dir)
        .map_err(|e| Error::invalid("--work-dir", format!("{}: {e}", config.work_dir.display())))?;
    let mut references = Vec::new();
    if config.references.is_empty() {
        for &seed in &config.reference_seeds {
            references.push(reference(config, &shot, seed)?);
        }
    } else {
        for path in &config.references {
            references.push(read_exr(path)?);
        }
    }
    if let Some(r) = references
        .iter()
        .find(|r| (r.width, r.height) != (references[0].width, references[0].height))
    {
        return Err(Error::invalid(
            "--references",
            format!(
                "images of different sizes: {}×{} and {}×{}",
                references[0].width, references[0].height, r.width, r.height
            ),
        ));
    }
    let refs: Vec<&[[f32; 4]]> = references.iter().map(|r| r.pixels.as_slice()).collect();
    let (width, height) = (references[0].width as usize, references[0].height as usize);
    let mut runs = Vec::new();
    for &seed in &config.seeds {
        let dir = &config.work_dir;
        let image = dir.join(format!("demo-seed{seed}.exr"));
        let stats = dir.join(format!("demo-seed{seed}.json"));
        let mut demo = shot.clone();
        demo.settings.render.seed = Some(seed);
        demo.settings.output.image.clone_from(&image);
        demo.settings.output.preview = Some(dir.join(format!("demo-seed{seed}.png")));
        demo.settings.output.stats = Some(stats.clone());
        // Rendered afresh each time (a complete image of the same shot would be kept)
        demo.settings.farm.overwrite = true;
        let (wall_seconds, cpu_seconds) =
            render(config, &demo, &dir.join(format!("demo-seed{seed}.toml")), &stats)?;
        let x = read_exr(&image)?;
        if (x.width as usize, x.height as usize) != (width, height) {
            return Err(Error::Scene(format!(
                "{} is {}×{}, the references {width}×{height}",
                image.display(),
                x.width,
                x.height
            )));
        }
        log::info!("demo seed {seed}: {wall_seconds:.1} s wall, {cpu_seconds:.1} CPU s");
        runs.push(DemoRun {
            seed,
            wall_seconds,
            cpu_seconds,
            error: image_error(&x.pixels, &refs, width, height),
        });
    }
    let machine = super::machine();
    Ok(DemoReport {
        scene: config.scene.clone(),
        cpus: machine.cpus,
        cpu_model: machine.model,
        reference_spp: config.reference_spp,
        reference_seeds: if config.references.is_empty() {
            config.reference_seeds.clone()
        } else {
            Vec::new()
        },
        references: config.references.clone(),
        runs,
        target_seconds: config.target_seconds,
        target_rel_rmse: config.target_rel_rmse,
    })
}

/// The reference of `seed`: the scene at `reference_spp`, not denoised, kept in the work
/// directory under its settings hash (which covers the seed and every setting that
/// changes pixels) and spp, and rendered when missing or incomplete (an interrupted
/// render's partial image, which `plume render` then continues).
fn reference(config: &DemoConfig, shot: &Shot, seed: u64) -> Result<RgbaImage> {
    let mut r = shot.clone();
    r.settings.render.seed = Some(seed);
    r.settings.render.spp = Some(config.reference_spp);
    r.settings.render.time = None;
    r.settings.output.denoise = false;
    r.settings.output.preview = None;
    let hash = crate::farm::fingerprint::settings_hash(&r, seed);
    let name = format!("reference-{hash}-{}spp", config.reference_spp);
    let image = config.work_dir.join(format!("{name}.exr"));
    // A kept reference is read once: for its status and, when complete, its pixels
    let complete =
        |c: &ExrContents| c.metadata.get("plume:status").is_some_and(|s| s == "complete");
    if let Some(kept) = read_exr_contents(&image).ok().filter(complete) {
        return Ok(RgbaImage {
            width: kept.crop.x1 - kept.crop.x0,
            height: kept.crop.y1 - kept.crop.y0,
            pixels: kept.pixels,
        });
    }
    log::info!(
        "rendering reference seed {seed} ({} spp) to {}",
        config.reference_spp,
        image.display()
    );
    let stats = config.work_dir.join(format!("{name}.json"));
    r.settings.output.image.clone_from(&image);
    r.settings.output.stats = Some(stats.clone());
    render(config, &r, &config.work_dir.join(format!("{name}.toml")), &stats)?;
    read_exr(&image)
}

/// Render `shot` in a `plume render` process from the scene file written to `toml`:
/// (wall seconds of the process, CPU seconds from its statistics).
fn render(config: &DemoConfig, shot: &Shot, toml: &Path, stats: &Path) -> Result<(f64, f64)> {
    let mut shot = shot.clone();
    shot.settings.render.quiet = true;
    plume_scene::file::write(toml, &shot, &config.working_dir)?;
    // A statistics file gets a line per render: start afresh
    let _ = std::fs::remove_file(stats);
    let start = Instant::now();
    let out = std::process::Command::new(&config.exe)
        .arg("render")
        .arg(toml)
        .output()
        .map_err(|e| Error::Scene(format!("cannot run {}: {e}", config.exe.display())))?;
    let wall = start.elapsed().as_secs_f64();
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        return Err(Error::Scene(format!(
            "rendering {} failed: {}",
            toml.display(),
            err.trim().lines().last().unwrap_or("no message")
        )));
    }
    let text = std::fs::read_to_string(stats)
        .map_err(|source| Error::Open { path: stats.to_path_buf(), source })?;
    let cpu = text
        .lines()
        .last()
        .and_then(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .and_then(|v| v.get("cpu_seconds").and_then(serde_json::Value::as_f64))
        .ok_or_else(|| Error::Scene(format!("{}: no cpu_seconds", stats.display())))?;
    Ok((wall, cpu))
}

/// Luminance of a pixel ([`rec709_luminance`] of its colour).
fn luminance(p: &[f32; 4]) -> f64 {
    rec709_luminance([f64::from(p[0]), f64::from(p[1]), f64::from(p[2])])
}

/// `x` against the references `refs` (all `width × height`): see the module docs.
///
/// # Panics
/// If fewer than 2 references are given or the images differ in size.
#[must_use]
pub fn image_error(
    x: &[[f32; 4]],
    refs: &[&[[f32; 4]]],
    width: usize,
    height: usize,
) -> ImageError {
    assert!(refs.len() >= 2, "invariant: two references or more");
    assert!(
        refs.iter().all(|r| r.len() == x.len()) && x.len() == width * height,
        "invariant: images of one size"
    );
    let n = refs.len() as f64;
    let covered: Vec<bool> = (0..x.len())
        .map(|i| refs.iter().map(|r| r[i][3]).sum::<f32>() / refs.len() as f32 > COVERED_ALPHA)
        .collect();
    let lum: Vec<f64> = x.iter().map(luminance).collect();
    let (mut sum_ref, mut sum_x, mut sq, mut var, mut count) = (0.0, 0.0, 0.0, 0.0, 0usize);
    for i in (0..x.len()).filter(|&i| covered[i]) {
        let l: Vec<f64> = refs.iter().map(|r| luminance(&r[i])).collect();
        let mean = l.iter().sum::<f64>() / n;
        // Variance of the references' mean: the sample variance over n renders, ÷ n
        var += l.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0) / n;
        let lx = lum[i];
        sq += (lx - mean).powi(2);
        sum_ref += mean;
        sum_x += lx;
        count += 1;
    }
    if count == 0 {
        return ImageError {
            rel_rmse: 0.0,
            mean_ratio: 1.0,
            reference_noise: 0.0,
            speck: Speck { x: 0, y: 0, ratio: 0.0 },
        };
    }
    let c = count as f64;
    let mean = sum_ref / c;
    ImageError {
        rel_rmse: (sq / c - var / c).max(0.0).sqrt() / mean,
        mean_ratio: sum_x / sum_ref,
        reference_noise: (var / c).sqrt() / mean,
        speck: largest_speck(&lum, &covered, width, height, SPECK_FLOOR * mean),
    }
}

/// The covered pixel with the largest `lum ÷ max(median of its 5×5, floor)` (the window
/// clipped at the image's edges).
#[must_use]
pub fn largest_speck(
    lum: &[f64],
    covered: &[bool],
    width: usize,
    height: usize,
    floor: f64,
) -> Speck {
    let mut best = Speck { x: 0, y: 0, ratio: 0.0 };
    let mut window = Vec::with_capacity(25);
    for y in 0..height {
        for x in 0..width {
            if !covered[y * width + x] {
                continue;
            }
            window.clear();
            for wy in y.saturating_sub(2)..(y + 3).min(height) {
                for wx in x.saturating_sub(2)..(x + 3).min(width) {
                    window.push(lum[wy * width + wx]);
                }
            }
            window.sort_by(f64::total_cmp);
            let median = window[window.len() / 2];
            let ratio = lum[y * width + x] / median.max(floor);
            if ratio > best.ratio {
                best = Speck { x, y, ratio };
            }
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grey(v: f32, a: f32) -> [f32; 4] {
        [v, v, v, a]
    }

    #[test]
    fn error_of_a_known_offset_with_the_references_noise_subtracted() {
        let (w, h) = (8, 6);
        // Two references that differ by ±0.1 around 1 on every covered pixel: the mean is
        // 1, the variance of the mean (0.1² · 2 / 1) / 2 = 0.01
        let r1: Vec<_> =
            (0..w * h).map(|i| if i % w < 6 { grey(1.1, 1.0) } else { grey(0.0, 0.0) }).collect();
        let r2: Vec<_> =
            (0..w * h).map(|i| if i % w < 6 { grey(0.9, 1.0) } else { grey(0.0, 0.0) }).collect();
        // An image 1.2 on the covered pixels (and anything outside them)
        let x: Vec<_> =
            (0..w * h).map(|i| if i % w < 6 { grey(1.2, 1.0) } else { grey(50.0, 0.0) }).collect();
        let e = image_error(&x, &[&r1, &r2], w, h);
        // (1.2 − 1)² − 0.01 = 0.03
        assert!((e.rel_rmse - 0.03f64.sqrt()).abs() < 1e-6, "{e:?}");
        assert!(
            (e.mean_ratio - 1.2).abs() < 1e-6 && (e.reference_noise - 0.1).abs() < 1e-6,
            "{e:?}"
        );
        // The image that is the references' mean has no error, not a negative one
        let mean: Vec<_> =
            r1.iter().zip(&r2).map(|(a, b)| std::array::from_fn(|c| 0.5 * (a[c] + b[c]))).collect();
        assert_eq!(image_error(&mean, &[&r1, &r2], w, h).rel_rmse, 0.0);
    }

    #[test]
    fn a_planted_speck_is_found_and_a_smooth_ramp_has_none() {
        let (w, h) = (20, 12);
        let ramp: Vec<f64> = (0..w * h).map(|i| 1.0 + 0.05 * (i % w) as f64).collect();
        let covered = vec![true; w * h];
        let smooth = largest_speck(&ramp, &covered, w, h, 0.01);
        assert!(smooth.ratio < 1.2, "{smooth:?}");
        let mut specked = ramp.clone();
        specked[7 * w + 13] *= 40.0;
        let s = largest_speck(&specked, &covered, w, h, 0.01);
        assert_eq!((s.x, s.y), (13, 7));
        assert!((s.ratio - 40.0).abs() < 0.5, "{s:?}");
        // Uncovered pixels are never specks, and a dark neighbourhood is floored
        let mut dark = vec![0.0; w * h];
        dark[3 * w + 3] = 1.0;
        let mut cov = vec![false; w * h];
        cov[3 * w + 3] = true;
        assert_eq!(largest_speck(&dark, &cov, w, h, 0.5).ratio, 2.0);
    }
}
