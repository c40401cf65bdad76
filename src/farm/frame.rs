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
//!
//! This file owns the frame's steps and the render itself (passes, sample order, debug
//! pixel replay, warnings about the loaded data). [`render_frame`] runs the steps in
//! order: [`FramePaths::resolve`], `decide` (`farm::resume`), loading
//! ([`crate::load::load_scene`]) and `warn_about`, `SamplePlan::new` (`farm::resume`),
//! `replay` (debug pixel) or `run_passes`, `stats_record` and `write_outputs`
//! (`farm::outputs`, with the image's layers from `farm::layers`).

use std::path::PathBuf;
use std::time::{Duration, Instant};

use crate::farm::fingerprint::{file_sha256, inputs_sha256, settings_hash};
use crate::farm::layers::aov_layout;
use crate::farm::observer::{JobObserver, Pass, Replay, RunContext};
use crate::farm::outputs::{
    stats_record, write_outputs, FrameId, FramePaths, InputId, Rendered, Timing,
};
use crate::farm::part::Completion;
use crate::farm::plan::Job;
use crate::farm::resume::{decide, log_continuing, unless_input_changed, Resume, SamplePlan};
use crate::farm::signals;
use crate::load::{load_scene, LoadedScene};
use plume_core::error::{Error, Result};
use plume_engine::film::Film;
use plume_engine::integrator::AovLayout;
use plume_engine::integrator::LineTrace;
use plume_engine::medium::{EmissionKind, Estimator};
use plume_engine::render::{
    read_ahead_window, render_with, RenderControl, RenderObserver, RenderResult, RenderSettings,
    SampleBudget, SampleOrder, StopReason,
};
use plume_engine::stats::{cpu_seconds, reset_peak_rss, RenderStats};
use plume_scene::{DeferPaths, EmissionSource, SampleOrderChoice};
use plume_volume::out_of_core::memory::{MemoryBound, MemoryLimits};
use plume_volume::Volume;

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

/// Render frame `frame` (the `index`-th of the run), telling `context.observer`.
///
/// # Errors
/// Input missing or unreadable (code 3), bad values found while loading (2), an output
/// that cannot be written (4).
pub fn render_frame(
    job: &Job<'_>,
    index: usize,
    frame: Option<i64>,
    context: &RunContext<'_>,
) -> Result<FrameOutcome> {
    let observer = context.observer;
    let settings = &job.shot.settings;
    let start = Instant::now();
    let cpu_at_start = cpu_seconds();
    reset_peak_rss();
    let paths = FramePaths::resolve(job, frame);
    // Default seed: the frame number (two's complement for negative frames)
    let seed = settings.render.seed.unwrap_or(frame.map_or(0, |f| f as u64));
    let hash = settings_hash(job.shot, seed);

    let Some(resume) = decide(job, &paths, &hash, index, frame, observer)? else {
        return Ok(FrameOutcome::Skipped);
    };
    observer.frame_started(index, frame, &paths.output);
    let (input, resume) = check_files(job, &paths, resume)?;

    // Load the frame's grids once and build the scene
    let loaded = load_scene(&paths.scene(job.scene()), &paths.input, settings, frame)?;
    warn_about(job, &paths, &loaded);
    let plan = SamplePlan::new(job, resume.as_ref());
    let render_settings = RenderSettings {
        budget: plan.budget,
        seed,
        sampler: settings.render.sampler,
        threads: settings.render.threads,
        first_sample: plan.first_sample,
        integrator: plume_engine::integrator::Integrator::for_scene(job.scene()),
        adaptive: crate::farm::fingerprint::adaptive_settings(settings),
    };
    if let Some(dp) = settings.render.debug_pixel {
        observer.replayed(&replay(&loaded, &render_settings, dp));
        return Ok(FrameOutcome::Replayed);
    }
    log_continuing(&paths.output, resume.as_ref());
    let render_start = Instant::now();
    let time_to_first_sample = start.elapsed().as_secs_f64();
    let on_pass = pass_reporter(&plan, index, frame, observer, render_start);
    let result = run_passes(
        job,
        &paths,
        &loaded,
        &render_settings,
        &plan,
        resume,
        start,
        observer,
        &on_pass,
    );
    let spp = plan.resumed_spp + result.spp;
    if spp == 0 {
        return Ok(FrameOutcome::NotStarted);
    }
    let status = completion(result.stopped);
    let timing = Timing {
        wall: start.elapsed().as_secs_f64(),
        cpu: cpu_seconds() - cpu_at_start,
        time_to_first_sample,
    };
    let frame_id = FrameId { frame, seed, settings_hash: hash, command_line: context.command_line };
    let rendered = Rendered::new(job, &result, status, spp);
    let record = stats_record(job, &paths, &loaded, &rendered, &frame_id, &input, &timing);
    write_outputs(job, &paths, &loaded, &rendered, &record, &input, context.working_dir)?;
    if !settings.render.quiet {
        log_written(job, &paths, &record, status, &timing);
    }
    observer.frame_done(index, frame, status, &record);
    Ok(FrameOutcome::Written { status, output: paths.output, spp })
}

/// Check that the frame's outputs can be written and identify its inputs (SHA-256 and
/// size); `resume` is dropped if an input changed since it was started.
///
/// # Errors
/// An output that cannot be written (code 4), an input that cannot be read (3; a further
/// volume's named by its key, `volumes[1].file`).
fn check_files(
    job: &Job<'_>,
    paths: &FramePaths,
    resume: Option<Resume>,
) -> Result<(InputId, Option<Resume>)> {
    for path in std::iter::once(&paths.output).chain(paths.preview.iter()).chain(paths.stats.iter())
    {
        plume_core::fs::check_writable(path)?;
    }
    let (first_sha256, mut bytes) = file_sha256(&paths.input)?;
    let mut each = vec![first_sha256.clone()];
    let entries = job.scene().entries();
    for (entry, path) in entries.iter().skip(1).zip(&paths.more_inputs) {
        let (sha256, size) = file_sha256(path).map_err(|e| match e {
            Error::Open { path, source } => Error::InvalidInput {
                what: entry.key("file"),
                message: format!("cannot open {}: {source}", path.display()),
            },
            other => other,
        })?;
        each.push(sha256);
        bytes += size;
    }
    let sha256 = inputs_sha256(&each);
    let resume = unless_input_changed(resume, &paths.output, &sha256);
    Ok((InputId { sha256, first_sha256, bytes }, resume))
}

/// Tells `observer` of each pass of the frame (the `index`-th, `frame`) rendering `plan`
/// from `render_start`: the samples done and the fraction of the frame done.
fn pass_reporter<'a>(
    plan: &'a SamplePlan,
    index: usize,
    frame: Option<i64>,
    observer: &'a dyn JobObserver,
    render_start: Instant,
) -> impl Fn(u64, u64) + Sync + 'a {
    move |done: u64, total: u64| {
        let fraction = match plan.budget {
            SampleBudget::Spp(_) => {
                (plan.resumed_spp + done) as f64 / (plan.resumed_spp + total).max(1) as f64
            }
            SampleBudget::Time(t) | SampleBudget::CpuTime(t) => {
                render_start.elapsed().as_secs_f64() / t
            }
        };
        observer.pass_done(&Pass {
            index,
            frame,
            done,
            target: total,
            resumed: plan.resumed_spp,
            fraction,
        });
    }
}

/// How far a render that stopped for `stopped` got.
fn completion(stopped: StopReason) -> Completion {
    match stopped {
        StopReason::Finished => Completion::Complete,
        StopReason::Interrupted => Completion::Interrupted,
        StopReason::TimeLimit => Completion::TimeLimit,
    }
}

/// The line saying that the frame was written: where, its size, samples, state and
/// estimator, and what it cost.
fn log_written(
    job: &Job<'_>,
    paths: &FramePaths,
    record: &RenderStats,
    status: Completion,
    timing: &Timing,
) {
    let state = if status == Completion::Complete {
        String::new()
    } else {
        format!(", {}", status.as_str())
    };
    let crop = job.pixels();
    log::info!(
        "{} ({}x{}, {} spp{state}, {}) in {:.2} s ({:.2} s to first sample, {:.3} core-h)",
        paths.output.display(),
        crop.width(),
        crop.height(),
        record.spp,
        record.estimator,
        timing.wall,
        timing.time_to_first_sample,
        timing.cpu / 3600.0
    );
    if let Some(threshold) = job.shot.settings.render.noise_threshold {
        log::info!("{}", adaptive_summary(record, threshold));
    }
}

/// The line that ends an adaptive render: the estimated error reached and how the samples
/// were spent.
fn adaptive_summary(record: &RenderStats, threshold: f64) -> String {
    let h = &record.spp_histogram;
    let pixels: u64 = h.iter().map(|b| b.pixels).sum();
    let samples: u64 = h.iter().map(|b| b.spp * b.pixels).sum();
    let capped: u64 = h.iter().filter(|b| b.spp == record.spp).map(|b| b.pixels).sum();
    let estimate = record
        .error_estimate
        .rel_rmse
        .map_or_else(|| "no estimate (fewer than 2 samples)".into(), |e| format!("{e:.4}"));
    format!(
        "noise threshold {threshold}: estimated relRMSE {estimate} over {} pixels (floor {}); {:.1} spp on average, {} to {}, {capped} pixels at the cap",
        record.error_estimate.pixels,
        record.error_estimate.floor,
        samples as f64 / pixels.max(1) as f64,
        h.first().map_or(0, |b| b.spp),
        h.last().map_or(0, |b| b.spp),
    )
}

/// Warnings about the loaded data: clamped voxels, an empty volume, no emission, an
/// estimator that cannot see part of it.
fn warn_about(job: &Job<'_>, paths: &FramePaths, loaded: &LoadedScene) {
    let input = paths.input.display();
    let volume = loaded.scene.volume();
    let warn = |msg: String| log::warn!("{msg}");
    if volume.report.density_clamped > 0 {
        warn(format!(
            "{input}: {} density voxels were NaN, infinite or negative and were set to 0",
            volume.report.density_clamped
        ));
    }
    if volume.report.albedo_clamped > 0 {
        warn(format!(
            "{input}: {} albedo voxels were outside [0, 1] or NaN and were clamped",
            volume.report.albedo_clamped
        ));
    }
    if volume.report.source_invalid > 0 {
        warn(format!(
            "{input}: {} emission-source voxels were NaN, infinite or negative and were set to 0",
            volume.report.source_invalid
        ));
    }
    if volume.is_empty() {
        warn(format!(
            "{input}: grid {:?} is empty; the image will be transparent black",
            job.scene().volume.density_grid
        ));
    }
    if loaded.emission_kind == EmissionKind::None
        && job.scene().emission.source == EmissionSource::Auto
    {
        warn(format!("{input}: no temperature or emission grid found; rendering absorption only"));
    }
    let integrator = plume_engine::integrator::Integrator::for_scene(job.scene());
    let point = [
        (integrator.estimator, "integrator.estimator"),
        (integrator.camera_estimator(), "integrator.camera_estimator"),
    ]
    .into_iter()
    .find(|(e, _)| *e == Estimator::Point);
    if let Some((_, key)) = point.filter(|_| loaded.scene.medium().emission.emits_without_density())
    {
        warn(format!("{key} point scores only at collisions: emission where density is 0 (allowed by emission.convention cycles) is not rendered"));
    }
}

/// Replay one pixel sample: its path's trace and its value.
fn replay(
    loaded: &LoadedScene,
    settings: &RenderSettings,
    dp: plume_engine::render::SampleId,
) -> Replay {
    let (x, y, s) = (dp.x, dp.y, dp.sample);
    let mut trace = LineTrace::default();
    let mut counters = plume_engine::integrator::Counters::default();
    let l = plume_engine::with_scene!(&loaded.scene, scene => {
        let plume_engine::render::PixelSample { ray, mut sampler, time } = plume_engine::render::pixel_sample(scene, settings.sampler, settings.seed, x, y, s);
        // The pixel's split count when splitting by brightness: the same pilot as the render's
        let split_map = plume_engine::pilot::split_map(scene, settings);
        plume_engine::integrator::split_map::pixel_integrator(&settings.integrator, split_map.as_ref(), x, y).li_aovs(scene, &ray, time, plume_engine::integrator::PathState { sampler: &mut sampler, counters: &mut counters, trace: &mut trace, aovs: &mut plume_engine::integrator::NoAovs })
    });
    Replay { sample: dp, trace: trace.0, value: format!("{l:?}") }
}

/// Render the frame's passes, continuing `resume`, telling `observer` (the passes' start
/// and end) and `on_pass` (each pass).
#[allow(clippy::too_many_arguments)] // the frame's job, files, scene and plan, and the two observers
fn run_passes(
    job: &Job<'_>,
    paths: &FramePaths,
    loaded: &LoadedScene,
    settings: &RenderSettings,
    plan: &SamplePlan,
    resume: Option<Resume>,
    start: Instant,
    observer: &dyn JobObserver,
    on_pass: &dyn RenderObserver,
) -> RenderResult {
    let job_settings = &job.shot.settings;
    let (width, height) = (job.scene().camera.width, job.scene().camera.height);
    let target = match plan.budget {
        SampleBudget::Spp(n) => u64::from(n),
        SampleBudget::Time(_) | SampleBudget::CpuTime(_) => 0,
    };
    let aovs = aov_layout(job, loaded);
    let film = resume.map(|(_, sums, aov)| {
        let mut film = Film::with_aovs(
            width,
            height,
            job.pixels(),
            aovs.as_ref().map_or(0, AovLayout::channels),
        );
        film.set_sums(&sums.rgba);
        film.set_moments(&sums.moments);
        if let Some(aov) = aov {
            film.set_aov_sums(&aov);
        }
        film
    });
    let stop = || signals::stop_requested().is_some() || observer.stop_requested();
    let volume = loaded.scene.volume();
    let auto = job_settings.render.sample_order == SampleOrderChoice::Auto;
    let defer_auto = job_settings.render.defer_paths == DeferPaths::Auto;
    let available = if auto || defer_auto { MemoryLimits::read().available() } else { None };
    let order = sample_order(job, volume, matches!(plan.budget, SampleBudget::Spp(_)), available);
    if order == SampleOrder::TileMajor && auto && !job_settings.render.quiet {
        // Names the cgroup limit when that is what decided
        let what = available.map_or_else(String::new, |a| format!(" ({a})"));
        log::info!(
            "{}: {:.2} GB of bricks, more than the memory available{what}; rendering tile by tile (render.sample_order)",
            paths.input.display(),
            volume.memory_bytes() as f64 / 1e9
        );
    }
    let control = RenderControl {
        crop: job.crop,
        film,
        stop: Some(&stop),
        deadline: job_settings.farm.time_limit.map(|t| start + Duration::from_secs_f64(t)),
        order,
        // Deferral slows a render whose pages stay in memory (docs/BENCHMARKS.md, "Deferred
        // paths"): `auto` is only for a cache larger than what is available
        defer_paths: match job_settings.render.defer_paths {
            DeferPaths::Auto if !larger_than_available(volume, available) => DeferPaths::Never,
            choice => choice,
        },
        read_ahead_window: read_ahead_window(crate::load::bind::memory_budget(job_settings)),
        aovs,
        half_block: Some(crate::farm::fingerprint::half_block(job_settings)),
    };
    observer.render_started(target);
    let result = plume_engine::with_scene!(&loaded.scene, scene => render_with(scene, settings, control, on_pass));
    observer.render_finished();
    result
}

/// Whether `volume` is paged from a cache file larger than the memory `available` (its
/// pages could not all stay in the page cache: `MemAvailable`, or what this process's
/// cgroup limit leaves, whichever is smaller; see [`MemoryLimits::available`]).
fn larger_than_available(volume: &Volume, available: Option<MemoryBound>) -> bool {
    volume.is_mapped() && volume.memory_bytes() as u64 > available.map_or(u64::MAX, |a| a.bytes)
}

/// The sample order for this frame: `auto` is tile-major for a mapped volume larger than
/// the memory `available` now ([`larger_than_available`]), when the render has a fixed
/// spp and no time limit (which tile-major order cannot honour without abandoning the
/// frame).
fn sample_order(
    job: &Job<'_>,
    volume: &Volume,
    fixed_spp: bool,
    available: Option<MemoryBound>,
) -> SampleOrder {
    let settings = &job.shot.settings;
    match settings.render.sample_order {
        SampleOrderChoice::Progressive => SampleOrder::Progressive,
        SampleOrderChoice::TileMajor => SampleOrder::TileMajor,
        SampleOrderChoice::Auto => {
            if larger_than_available(volume, available)
                && fixed_spp
                && settings.farm.time_limit.is_none()
            {
                SampleOrder::TileMajor
            } else {
                SampleOrder::Progressive
            }
        }
    }
}
