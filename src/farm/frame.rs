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
//! [`render_frame`] runs the steps in order: [`FramePaths::resolve`], `decide`, loading
//! ([`crate::load::load_scene`]) and `warn_about`, `SamplePlan::new`, `replay` (debug
//! pixel) or `run_passes`, `stats_record`, `write_outputs`.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use crate::farm::fingerprint::{file_sha256, settings_hash};
use crate::farm::observer::{JobObserver, Pass, Replay, RunContext};
use crate::farm::part::{assess, stats_metadata, Completion, Existing, Expected, PartInfo};
use crate::farm::plan::Job;
use crate::farm::signals;
use crate::load::{load_scene, LoadedScene};
use crate::output::{write_exr_image, AovChannels, ExrImage};
use plume_core::error::{Error, Result};
use plume_engine::film::{Crop, Film, FIXED_POINT_BITS};
use plume_engine::integrator::AovLayout;
use plume_engine::integrator::LineTrace;
use plume_engine::medium::{EmissionKind, Estimator};
use plume_engine::render::{
    read_ahead_window, render_with, RenderControl, RenderObserver, RenderResult, RenderSettings,
    SampleBudget, SampleOrder, StopReason,
};
use plume_engine::stats::{cpu_seconds, peak_rss_since_reset_bytes, reset_peak_rss, RenderStats};
use plume_scene::split::format_range;
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

/// The files of one frame, frame tokens resolved.
pub struct FramePaths {
    /// The volume file.
    pub input: PathBuf,
    /// The EXR.
    pub output: PathBuf,
    /// The PNG preview.
    pub preview: Option<PathBuf>,
    /// The statistics file.
    pub stats: Option<PathBuf>,
}

impl FramePaths {
    /// The paths of `frame`.
    #[must_use]
    pub fn resolve(job: &Job<'_>, frame: Option<i64>) -> FramePaths {
        FramePaths {
            input: job.input.resolve(frame),
            output: job.output.resolve(frame),
            preview: job.preview.as_ref().map(|p| p.resolve(frame)),
            stats: job.stats.as_ref().map(|p| p.resolve(frame)),
        }
    }
}

/// An output to continue: what it holds and its exact sums (and AOV sums).
type Resume = (PartInfo, Vec<[i128; 4]>, Option<Vec<i128>>);

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

    let Some(mut resume) = decide(job, &paths, &hash, index, frame, observer)? else {
        return Ok(FrameOutcome::Skipped);
    };
    observer.frame_started(index, frame, &paths.output);
    for path in std::iter::once(&paths.output).chain(paths.preview.iter()).chain(paths.stats.iter())
    {
        plume_core::fs::check_writable(path)?;
    }
    let (input_sha256, input_bytes) = file_sha256(&paths.input)?;
    if resume.as_ref().is_some_and(|(info, ..)| info.input_sha256 != input_sha256) {
        log::info!(
            "{}: the input changed since it was started; rendering it again",
            paths.output.display()
        );
        resume = None;
    }

    // Load the frame's grids once and build the scene
    let loaded = load_scene(job.scene(), &paths.input, settings, frame)?;
    warn_about(job, &paths, &loaded);
    let plan = SamplePlan::new(job, resume.as_ref());
    let render_settings = RenderSettings {
        budget: plan.budget,
        seed,
        sampler: settings.render.sampler,
        threads: settings.render.threads,
        first_sample: plan.first_sample,
        integrator: plume_engine::integrator::Integrator::for_scene(job.scene()),
    };
    if let Some(dp) = settings.render.debug_pixel {
        observer.replayed(&replay(&loaded, &render_settings, dp));
        return Ok(FrameOutcome::Replayed);
    }
    if let Some((info, ..)) = &resume {
        log::info!(
            "{}: continuing from samples {} ({})",
            paths.output.display(),
            format_range(&info.samples),
            info.status.as_str()
        );
    }
    let render_start = Instant::now();
    let time_to_first_sample = start.elapsed().as_secs_f64();
    let result = run_passes(
        job,
        &paths,
        &loaded,
        &render_settings,
        &plan,
        resume,
        start,
        observer,
        &|done: u64, total: u64| {
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
        },
    );
    let spp = plan.resumed_spp + result.spp;
    if spp == 0 {
        return Ok(FrameOutcome::NotStarted);
    }
    let status = match result.stopped {
        StopReason::Finished => Completion::Complete,
        StopReason::Interrupted => Completion::Interrupted,
        StopReason::TimeLimit => Completion::TimeLimit,
    };
    let timing = Timing {
        wall: start.elapsed().as_secs_f64(),
        cpu: cpu_seconds() - cpu_at_start,
        time_to_first_sample,
    };
    let input = InputId { sha256: input_sha256, bytes: input_bytes };
    let frame_id = FrameId { frame, seed, settings_hash: hash, command_line: context.command_line };
    let record =
        stats_record(job, &paths, &loaded, &result, &frame_id, input, status, spp, &timing);
    write_outputs(job, &paths, &loaded, &result, &record, status, context.working_dir)?;
    if !settings.render.quiet {
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
            spp,
            record.estimator,
            timing.wall,
            time_to_first_sample,
            timing.cpu / 3600.0
        );
    }
    observer.frame_done(index, frame, status, &record);
    Ok(FrameOutcome::Written { status, output: paths.output, spp })
}

/// Skip, continue or render anew: `None` when the output is complete (skip), else the
/// output to continue, if any.
///
/// # Errors
/// None; fallible for the outputs' checks.
fn decide(
    job: &Job<'_>,
    paths: &FramePaths,
    hash: &str,
    index: usize,
    frame: Option<i64>,
    observer: &dyn JobObserver,
) -> Result<Option<Option<Resume>>> {
    let settings = &job.shot.settings;
    plume_core::fs::remove_stale_temporaries(&paths.output);
    if settings.farm.overwrite || settings.render.debug_pixel.is_some() {
        return Ok(Some(None));
    }
    let (width, height) = (job.scene().camera.width, job.scene().camera.height);
    let crop = job.pixels();
    let aov_channels = layout_for(&settings.output, job).map(|l| l.channels());
    let expected = Expected {
        settings_hash: hash.to_string(),
        width,
        height,
        crop,
        samples: job.samples.clone(),
        aov_channels,
    };
    Ok(match assess(&paths.output, &expected) {
        Existing::Missing => Some(None),
        Existing::Complete(info) => {
            // Decisions about existing outputs are always logged, also with --quiet
            log::info!(
                "{}: already complete ({} spp), skipped (farm.overwrite renders it again)",
                paths.output.display(),
                info.samples.end - info.samples.start
            );
            observer.frame_skipped(index, frame, &paths.output);
            None
        }
        Existing::Resumable(info, sums, aov) => Some(Some((info, sums, aov))),
        Existing::Stale(reason) => {
            log::info!("{}: {reason}; rendering it again", paths.output.display());
            Some(None)
        }
    })
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

/// The samples this run renders: the asked range, minus what a resumed image holds.
struct SamplePlan {
    budget: SampleBudget,
    first_sample: u64,
    resumed_spp: u64,
}

impl SamplePlan {
    fn new(job: &Job<'_>, resume: Option<&Resume>) -> SamplePlan {
        match &job.samples {
            Some(r) => {
                let from = resume.map_or(r.start, |(info, ..)| info.samples.end);
                let n = u32::try_from(r.end - from).expect("invariant: checked by Shot::validate");
                SamplePlan {
                    budget: SampleBudget::Spp(n),
                    first_sample: from,
                    resumed_spp: from - r.start,
                }
            }
            None => {
                let t = job
                    .shot
                    .settings
                    .render
                    .time
                    .expect("invariant: no sample range means a time budget");
                SamplePlan { budget: SampleBudget::Time(t), first_sample: 0, resumed_spp: 0 }
            }
        }
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
#[allow(clippy::too_many_arguments)]
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
        film.set_sums(&sums);
        if let Some(aov) = aov {
            film.set_aov_sums(&aov);
        }
        film
    });
    let stop = || signals::stop_requested().is_some();
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

/// Seconds a frame took.
struct Timing {
    wall: f64,
    cpu: f64,
    time_to_first_sample: f64,
}

/// The input file's identity.
struct InputId {
    sha256: String,
    bytes: u64,
}

/// What identifies the frame's pixels and how it was asked for.
struct FrameId<'a> {
    frame: Option<i64>,
    seed: u64,
    settings_hash: String,
    command_line: &'a str,
}

/// The frame's record: EXR header and stats line.
#[allow(clippy::too_many_arguments)]
fn stats_record(
    job: &Job<'_>,
    paths: &FramePaths,
    loaded: &LoadedScene,
    result: &RenderResult,
    id: &FrameId<'_>,
    input: InputId,
    status: Completion,
    spp: u64,
    timing: &Timing,
) -> RenderStats {
    let settings = &job.shot.settings;
    let (width, height) = (job.scene().camera.width, job.scene().camera.height);
    let crop = job.pixels();
    let range_start = job.samples.as_ref().map_or(0, |r| r.start);
    let sample_range = range_start..range_start + spp;
    let threads = if settings.render.threads == 0 {
        rayon::current_num_threads()
    } else {
        settings.render.threads
    };
    let samples = result.counters.samples as f64;
    let volume = loaded.scene.volume();
    RenderStats {
        plume_version: env!("CARGO_PKG_VERSION").into(),
        command_line: id.command_line.into(),
        host: plume_core::fs::host_name(),
        frame: id.frame,
        input: paths.input.display().to_string(),
        input_bytes: input.bytes,
        input_sha256: input.sha256,
        output: paths.output.display().to_string(),
        status: status.as_str().into(),
        spp,
        sample_range: format_range(&sample_range),
        resumed_from_spp: spp - result.spp,
        seed: id.seed,
        settings_hash: id.settings_hash.clone(),
        width,
        height,
        crop: crop.to_string(),
        fixed_point_bits: FIXED_POINT_BITS,
        wall_seconds: timing.wall,
        render_seconds: result.render_seconds,
        workers_busy: result.busy_seconds / result.render_seconds.max(1e-9),
        time_to_first_sample_seconds: timing.time_to_first_sample,
        cpu_seconds: timing.cpu,
        core_hours: timing.cpu / 3600.0,
        allocated_core_hours: timing.wall * threads as f64 / 3600.0,
        samples_per_second: samples / result.render_seconds.max(1e-9),
        samples_per_cpu_second: samples / timing.cpu.max(1e-9),
        peak_rss_bytes: peak_rss_since_reset_bytes(),
        threads,
        estimator: plume_engine::integrator::Integrator::for_scene(job.scene()).estimator_name(),
        volume_bytes: volume.memory_bytes() as u64,
        counters: result.counters,
        saturated_samples: result.film.saturated(),
        underflowed_samples: result.film.underflowed(),
        density_voxels_clamped: volume.report.density_clamped,
        source_voxels_clamped: volume.report.source_invalid,
    }
}

/// Write the EXR (with exact sums for parts and partial images, so they can be merged or
/// continued, and the resolved scene description), the preview and the stats line.
/// Nothing computed from a brick cache is saved before its checksums have all passed.
///
/// # Errors
/// A failed cache check; an output that cannot be written.
fn write_outputs(
    job: &Job<'_>,
    paths: &FramePaths,
    loaded: &LoadedScene,
    result: &RenderResult,
    record: &RenderStats,
    status: Completion,
    working_dir: &std::path::Path,
) -> Result<()> {
    let settings = &job.shot.settings;
    let warn = |msg: String| log::warn!("{msg}");
    if let Some(c) = result.counters.first_nonfinite {
        warn(format!(
            "{} non-finite samples dropped; first at render.debug_pixel {c}",
            result.counters.nonfinite_samples
        ));
    }
    if record.saturated_samples > 0 {
        warn(format!(
            "{} sample values exceeded the fixed-point range (2^63) and were clamped",
            record.saturated_samples
        ));
    }
    if let Some(check) = &loaded.cache {
        // Checksums, and the file at the path is still the one mapped
        check.verified()?;
        // ... and the one whose identity the record holds, hashed before it was opened
        if crate::cache::is_cache_path(&paths.input)
            && file_sha256(&paths.input)?.0 != record.input_sha256
        {
            return Err(Error::InputFailed {
                kind: "brick cache",
                path: paths.input.clone(),
                what: "it was replaced between hashing and opening it; nothing computed from it was written (run the command again)".into(),
            });
        }
    }
    let (width, height) = (record.width, record.height);
    let crop = job.pixels();
    let noisy = result.film.average(record.spp);
    let film_sums = result.film.sums();
    let sums = (job.write_sums || status != Completion::Complete).then_some(film_sums.as_slice());
    let mut metadata = stats_metadata(record);
    match plume_scene::file::to_toml(job.shot, working_dir) {
        Ok(text) => metadata.push(("plume:scene".into(), text)),
        Err(e) => warn(format!(
            "the scene description is not recorded in {}: {e}",
            paths.output.display()
        )),
    }
    let aov_sums = result.film.aov_sums();
    let layout = aov_layout(job, loaded);
    let names = layout.as_ref().map(AovLayout::channel_names).unwrap_or_default();
    let Written { pixels, layers, denoised } =
        beauty_and_layers(layout.as_ref(), (&film_sums, &aov_sums), noisy, record.spp, crop);
    if settings.output.denoise && !denoised {
        let block = crate::farm::fingerprint::half_block(settings);
        warn(format!("{} spp: denoising needs samples in both half buffers (blocks of {block}: more than {block} spp); the image is not denoised", record.spp));
    }
    let aovs = layout.as_ref().map(|_| AovChannels {
        layers: &layers,
        sums: sums.is_some().then_some((names.as_slice(), aov_sums.as_slice())),
    });
    write_exr_image(
        &paths.output,
        &ExrImage { width, height, crop, pixels: &pixels, sums, aovs, metadata: &metadata },
    )?;
    if let Some(p) = &paths.preview {
        let exposure = settings
            .output
            .exposure
            .map_or_else(|| crate::output::auto_exposure(&pixels), |ev| 2f32.powf(ev));
        crate::output::write_png(p, crop.width(), crop.height(), &pixels, exposure)?;
    }
    if let Some(p) = &paths.stats {
        let json = serde_json::to_value(record).expect("invariant: stats serialize");
        plume_core::fs::append_line(p, &json.to_string())?;
    }
    Ok(())
}

/// The AOV layout that `output` asks for (`--aovs`, `--denoise`): one layer per light
/// group of the job's lights, and the half sums with `--denoise`.
fn layout_for(output: &plume_scene::OutputSettings, job: &Job<'_>) -> Option<AovLayout> {
    let filtered = plume_engine::denoise::Filtered::for_camera(
        plume_engine::integrator::Integrator::for_scene(&job.shot.scene).camera_estimator(),
    );
    (output.aovs || output.denoise).then(|| AovLayout {
        groups: job.shot.scene.lights.groups(),
        halves: output.denoise.then_some(filtered),
    })
}

/// The AOV layout of this frame ([`layout_for`]).
fn aov_layout(job: &Job<'_>, loaded: &LoadedScene) -> Option<AovLayout> {
    let layout = layout_for(&job.shot.settings.output, job);
    if let (Some(l), Some(e)) = (&layout, &loaded.scene.lights().external) {
        debug_assert_eq!(l.groups, e.groups(), "the description's groups are the built lights'");
    }
    layout
}

/// Named `f32` channels (`emission.R`, …), each row-major over the image.
pub type Layers = Vec<(String, Vec<f32>)>;

/// What is written of an image: its beauty and its AOV layers.
#[derive(Debug)]
pub struct Written {
    /// The beauty, row-major over the image.
    pub pixels: Vec<[f32; 4]>,
    /// The AOV layers (with `noisy` when denoised).
    pub layers: Layers,
    /// Whether the beauty was denoised.
    pub denoised: bool,
}

/// The beauty and the AOV layers of an image (`crop`) from its exact sums `(RGBA, AOV
/// channels)` over `spp` samples and its noisy beauty: with half sums in the layout (and
/// samples in both halves) the beauty is denoised ([`plume_engine::denoise::from_sums`]) and the
/// noisy one becomes the layer `noisy`. Used by `plume render` and `plume merge`, so that
/// a merged frame is the single render's.
#[must_use]
pub fn beauty_and_layers(
    layout: Option<&AovLayout>,
    sums: (&[[i128; 4]], &[i128]),
    noisy: Vec<[f32; 4]>,
    spp: u64,
    crop: Crop,
) -> Written {
    let Some(layout) = layout else {
        return Written { pixels: noisy, layers: Vec::new(), denoised: false };
    };
    let mut layers = aov_layers(layout, sums.1, &noisy, spp);
    match plume_engine::denoise::from_sums(
        layout,
        sums.0,
        sums.1,
        spp,
        (crop.width() as usize, crop.height() as usize),
    ) {
        Some(denoised) => {
            for (c, name) in ["R", "G", "B", "A"].iter().enumerate() {
                layers.push((format!("noisy.{name}"), noisy.iter().map(|p| p[c]).collect()));
            }
            Written { pixels: denoised, layers, denoised: true }
        }
        None => Written { pixels: noisy, layers, denoised: false },
    }
}

/// The AOV layers' pixel values from their exact sums (`aov_sums`, `layout.channels()`
/// per pixel) over `spp` samples, with `alpha` from the beauty: `(name, values)` per
/// channel.
#[must_use]
pub fn aov_layers(layout: &AovLayout, aov_sums: &[i128], beauty: &[[f32; 4]], spp: u64) -> Layers {
    let (n, n_layers) = (layout.channels(), layout.layer_channels());
    let names = layout.channel_names();
    // Every layer channel but depth's hit count, which `depth.Z` divides by
    let mut layers: Layers = names[..n_layers - 1]
        .iter()
        .map(|c| (c.clone(), Vec::with_capacity(beauty.len())))
        .collect();
    for sums in aov_sums.chunks_exact(n) {
        for (layer, v) in
            layers.iter_mut().zip(layout.pixel(sums, spp, plume_engine::film::pixel_value))
        {
            layer.1.push(v);
        }
    }
    layers.push(("alpha.A".into(), beauty.iter().map(|p| p[3]).collect()));
    layers
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
