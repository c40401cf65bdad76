//! One frame of a `plume render` run: decide (skip, continue or render), load, render,
//! write the EXR, preview and stats record.
//!
//! - An output that is complete, with the same settings hash and samples, is skipped
//!   (it must decode fully and carry plume's record; existing is not enough).
//! - An output of the same settings and input with exact sums and fewer samples than
//!   asked (left by an interrupted or time-limited render, or rendered with `--sums` and
//!   a smaller `--spp`) is continued: its sums are loaded and only the missing samples
//!   are rendered, so the result is bit-identical to rendering them all at once.
//! - Anything else at the output path is rendered anew.
//!
//! Outputs are written atomically, so SIGKILL at any moment leaves either the previous
//! file or the new one, and stale temporaries are removed by the next run.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle};

use crate::app::{integrator, load_scene};
use crate::cli::{EmissionArg, RenderArgs, SampleOrderArg};
use crate::volume::Volume;
use crate::error::{Error, Result};
use crate::farm::fingerprint::{file_sha256, settings_hash};
use crate::farm::job::Job;
use crate::farm::part::{assess, stats_metadata, Completion, Existing, Expected};
use crate::farm::progress::Progress;
use crate::farm::signals;
use crate::farm::split::format_range;
use crate::film::{Crop, Film, FIXED_POINT_BITS};
use crate::integrator::LineTrace;
use crate::medium::{EmissionKind, Estimator};
use crate::output::{write_exr_image, ExrImage};
use crate::render::{render_with, RenderControl, RenderSettings, SampleBudget, SampleOrder, StopReason};
use crate::stats::{cpu_seconds, peak_rss_since_reset_bytes, reset_peak_rss, RenderStats};

/// What became of a frame.
#[derive(Debug)]
pub enum FrameOutcome {
    /// The output was already complete.
    Skipped,
    /// `--debug-pixel`: a sample was replayed, nothing written.
    Replayed,
    /// A signal came before the first pass: nothing written.
    NotStarted,
    /// The image was written.
    Written {
        /// How far it got.
        status: Completion,
        /// Where.
        output: PathBuf,
        /// Samples per pixel in it.
        spp: u64,
    },
}

/// Render frame `frame` (the `index`-th of the run).
///
/// # Errors
/// Input missing or unreadable (code 3), bad flags found while loading (2), an output
/// that cannot be written (4).
pub fn render_frame(job: &Job<'_>, index: usize, frame: Option<i64>, command_line: &str, progress: &Progress) -> Result<FrameOutcome> {
    let args = job.args;
    let start = Instant::now();
    let cpu_at_start = cpu_seconds();
    reset_peak_rss();
    let input = job.input.resolve(frame);
    let output = job.output.resolve(frame);
    let preview = job.preview.as_ref().map(|p| p.resolve(frame));
    let stats_path = job.stats.as_ref().map(|p| p.resolve(frame));
    // Default seed: the frame number (two's complement for negative frames)
    let seed = args.seed.unwrap_or(frame.map_or(0, |f| f as u64));
    let (width, height) = (args.width, args.height);
    let crop = job.crop.unwrap_or(Crop::full(width, height));
    let hash = settings_hash(args, seed);
    let quiet = args.quiet;

    // Skip, continue or render anew
    crate::output::remove_stale_temporaries(&output);
    let mut resume = None;
    if !args.overwrite && args.debug_pixel.is_none() {
        let expected = Expected { settings_hash: hash.clone(), width, height, crop, samples: job.samples.clone() };
        match assess(&output, &expected) {
            Existing::Missing => {}
            Existing::Complete(info) => {
                // Decisions about existing outputs are always logged, also with --quiet
                eprintln!("plume: {}: already complete ({} spp), skipped (--overwrite renders it again)", output.display(), info.samples.end - info.samples.start);
                progress.frame_skipped(index, frame, &output.display().to_string());
                return Ok(FrameOutcome::Skipped);
            }
            Existing::Resumable(info, sums) => resume = Some((info, sums)),
            Existing::Stale(reason) => eprintln!("plume: {}: {reason}; rendering it again", output.display()),
        }
    }
    progress.frame_start(index, frame, &output.display().to_string());
    for path in std::iter::once(&output).chain(preview.iter()).chain(stats_path.iter()) {
        crate::output::check_writable(path)?;
    }
    let (input_sha256, input_bytes) = file_sha256(&input)?;
    if resume.as_ref().is_some_and(|(info, _)| info.input_sha256 != input_sha256) {
        eprintln!("plume: {}: the input changed since it was started; rendering it again", output.display());
        resume = None;
    }

    // Load the frame's grids once and build the scene
    let mut frame_args = args.clone();
    frame_args.file = input.clone();
    let loaded = load_scene(&frame_args)?;
    let scene = &loaded.scene;
    let volume = &scene.field;
    let warn = |msg: String| eprintln!("plume: warning: {msg}");
    if volume.report.density_clamped > 0 {
        warn(format!("{}: {} density voxels were NaN, infinite or negative and were set to 0", input.display(), volume.report.density_clamped));
    }
    if volume.report.albedo_clamped > 0 {
        warn(format!("{}: {} albedo voxels were outside [0, 1] or NaN and were clamped", input.display(), volume.report.albedo_clamped));
    }
    if volume.report.source_invalid > 0 {
        warn(format!("{}: {} emission-source voxels were NaN, infinite or negative and were set to 0", input.display(), volume.report.source_invalid));
    }
    if volume.is_empty() {
        warn(format!("{}: grid {:?} is empty; the image will be transparent black", input.display(), args.grids.density_grid));
    }
    if loaded.emission_kind == EmissionKind::None && args.grids.emission == EmissionArg::Auto {
        warn(format!("{}: no temperature or emission grid found; rendering absorption only", input.display()));
    }
    let integ = integrator(args);
    if integ.estimator == Estimator::Point && scene.medium.emission.emits_without_density() {
        warn("--estimator point scores only at collisions: emission where density is 0 (allowed by --convention cycles) is not rendered".into());
    }

    // Samples: the asked range, minus what a resumed image holds
    let (budget, first_sample, resumed_spp) = match &job.samples {
        Some(r) => {
            let from = resume.as_ref().map_or(r.start, |(info, _)| info.samples.end);
            let n = u32::try_from(r.end - from).expect("invariant: checked by Job::new");
            (SampleBudget::Spp(n), from, from - r.start)
        }
        None => (SampleBudget::Time(args.time.expect("invariant: no sample range means --time")), 0, 0),
    };
    let settings = RenderSettings { budget, seed, threads: args.threads, first_sample, integrator: integ };
    if let Some(dp) = &args.debug_pixel {
        // Replay one pixel sample and print its path
        let (x, y, s) = crate::cli::parse_debug_pixel(dp).map_err(|m| Error::invalid("--debug-pixel", m))?;
        let crate::render::PixelSample { ray, mut sampler } = crate::render::pixel_sample(scene, seed, x, y, s);
        let mut trace = LineTrace::default();
        let mut counters = crate::integrator::Counters::default();
        let l = settings.integrator.li(scene, &ray, &mut sampler, &mut counters, &mut trace);
        for line in &trace.0 {
            eprintln!("plume: debug {x},{y},{s}: {line}");
        }
        println!("{l:?}");
        return Ok(FrameOutcome::Replayed);
    }
    if let Some((info, _)) = &resume {
        eprintln!("plume: {}: continuing from samples {} ({})", output.display(), format_range(&info.samples), info.status.as_str());
    }

    let target = match budget {
        SampleBudget::Spp(n) => u64::from(n),
        SampleBudget::Time(_) | SampleBudget::CpuTime(_) => 0,
    };
    let bar = (!quiet && std::io::IsTerminal::is_terminal(&std::io::stderr())).then(|| {
        let pb = if target > 0 { ProgressBar::new(target) } else { ProgressBar::new_spinner() };
        pb.set_style(ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} spp {msg}").unwrap_or_else(|_| ProgressStyle::default_bar()));
        pb
    });
    let film = resume.as_ref().map(|(_, sums)| {
        let mut film = Film::with_crop(width, height, crop);
        film.set_sums(sums);
        film
    });
    let stop = || signals::stop_requested().is_some();
    let order = sample_order(args, volume, matches!(budget, SampleBudget::Spp(_)));
    if order == SampleOrder::TileMajor && args.sample_order == SampleOrderArg::Auto && !quiet {
        eprintln!(
            "plume: {}: {:.1} GB of bricks, more than the memory available; rendering tile by tile (--sample-order)",
            input.display(),
            volume.memory_bytes() as f64 / 1e9
        );
    }
    let control = RenderControl {
        crop: job.crop,
        film,
        stop: Some(&stop),
        deadline: args.time_limit.map(|t| start + Duration::from_secs_f64(t)),
        order,
    };
    let render_start = Instant::now();
    let time_to_first_sample = start.elapsed().as_secs_f64();
    let result = render_with(scene, &settings, control, &|done, total| {
        if let Some(pb) = &bar {
            pb.set_position(done);
        }
        let fraction = match settings.budget {
            SampleBudget::Spp(_) => (resumed_spp + done) as f64 / (resumed_spp + total).max(1) as f64,
            SampleBudget::Time(t) | SampleBudget::CpuTime(t) => render_start.elapsed().as_secs_f64() / t,
        };
        progress.pass(index, frame, resumed_spp + done, resumed_spp + total, fraction);
    });
    if let Some(pb) = &bar {
        pb.finish_and_clear();
    }
    let spp = resumed_spp + result.spp;
    if spp == 0 {
        return Ok(FrameOutcome::NotStarted);
    }
    let status = match result.stopped {
        StopReason::Finished => Completion::Complete,
        StopReason::Interrupted => Completion::Interrupted,
        StopReason::TimeLimit => Completion::TimeLimit,
    };
    let range_start = job.samples.as_ref().map_or(0, |r| r.start);
    let sample_range = range_start..range_start + spp;

    // The record: EXR header and stats line
    let wall = start.elapsed().as_secs_f64();
    let cpu = cpu_seconds() - cpu_at_start;
    let threads = if args.threads == 0 { rayon::current_num_threads() } else { args.threads };
    let samples = result.counters.samples as f64;
    let record = RenderStats {
        plume_version: env!("CARGO_PKG_VERSION").into(),
        command_line: command_line.into(),
        host: crate::output::host_name(),
        frame,
        input: input.display().to_string(),
        input_bytes,
        input_sha256,
        output: output.display().to_string(),
        status: status.as_str().into(),
        spp,
        sample_range: format_range(&sample_range),
        resumed_from_spp: resumed_spp,
        seed,
        settings_hash: hash,
        width,
        height,
        crop: crop.to_string(),
        fixed_point_bits: FIXED_POINT_BITS,
        wall_seconds: wall,
        render_seconds: result.render_seconds,
        time_to_first_sample_seconds: time_to_first_sample,
        cpu_seconds: cpu,
        core_hours: cpu / 3600.0,
        allocated_core_hours: wall * threads as f64 / 3600.0,
        samples_per_second: samples / result.render_seconds.max(1e-9),
        samples_per_cpu_second: samples / cpu.max(1e-9),
        peak_rss_bytes: peak_rss_since_reset_bytes(),
        threads,
        estimator: format!("{:?}", settings.integrator.estimator),
        volume_bytes: volume.memory_bytes() as u64,
        counters: result.counters,
        saturated_samples: result.film.saturated(),
        underflowed_samples: result.film.underflowed(),
        density_voxels_clamped: volume.report.density_clamped,
        source_voxels_clamped: volume.report.source_invalid,
    };
    if let Some(c) = result.counters.first_nonfinite {
        warn(format!("{} non-finite samples dropped; first at --debug-pixel {c}", result.counters.nonfinite_samples));
    }
    if record.saturated_samples > 0 {
        warn(format!("{} sample values exceeded the fixed-point range (2^63) and were clamped", record.saturated_samples));
    }

    // Outputs: EXR (with exact sums for parts and partial images, so they can be merged
    // or continued), preview, stats line
    // Nothing computed from a brick cache is saved before its checksums have all passed
    if let Some(check) = &loaded.cache {
        check.verified()?;
    }
    let pixels = result.film.average(spp);
    let sums = (job.write_sums || status != Completion::Complete).then(|| result.film.sums());
    let metadata = stats_metadata(&record);
    write_exr_image(&output, &ExrImage { width, height, crop, pixels: &pixels, sums: sums.as_deref(), metadata: &metadata })?;
    if let Some(p) = &preview {
        let exposure = args.exposure.map_or_else(|| crate::output::auto_exposure(&pixels), |ev| 2f32.powf(ev));
        crate::output::write_png(p, crop.width(), crop.height(), &pixels, exposure)?;
    }
    let json = serde_json::to_value(&record).expect("invariant: stats serialize");
    if let Some(p) = &stats_path {
        crate::output::append_line(p, &json.to_string())?;
    }
    if !quiet {
        let state = if status == Completion::Complete { String::new() } else { format!(", {}", status.as_str()) };
        eprintln!(
            "plume: {} ({}x{}, {} spp{state}, {}) in {:.2} s ({:.2} s to first sample, {:.3} core-h)",
            output.display(),
            crop.width(),
            crop.height(),
            spp,
            record.estimator,
            wall,
            time_to_first_sample,
            cpu / 3600.0
        );
    }
    progress.frame_done(index, frame, status.as_str(), json);
    Ok(FrameOutcome::Written { status, output, spp })
}

/// `--sample-order` for this frame: `auto` is tile-major for a mapped volume larger than
/// the memory available now (its pages could not all stay in the page cache), when the
/// render has a fixed spp and no time limit (which tile-major order cannot honour
/// without abandoning the frame).
fn sample_order(args: &RenderArgs, volume: &Volume, fixed_spp: bool) -> SampleOrder {
    match args.sample_order {
        SampleOrderArg::Progressive => SampleOrder::Progressive,
        SampleOrderArg::TileMajor => SampleOrder::TileMajor,
        SampleOrderArg::Auto => {
            let available = crate::stats::available_memory_bytes().unwrap_or(u64::MAX);
            let larger = volume.is_mapped() && volume.memory_bytes() as u64 > available;
            if larger && fixed_spp && args.time_limit.is_none() {
                SampleOrder::TileMajor
            } else {
                SampleOrder::Progressive
            }
        }
    }
}
