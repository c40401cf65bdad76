//! The files of one frame of `plume render`: where they are ([`FramePaths`]), the frame's
//! record (EXR header and stats line: `stats_record`) and writing them (`write_outputs`:
//! the EXR with its exact sums and scene description, the PNG preview, the stats line).

use std::borrow::Cow;
use std::path::PathBuf;

use crate::farm::fingerprint::file_sha256;
use crate::farm::layers::{aov_layout, beauty_and_layers, FrameSums, Written};
use crate::farm::part::{stats_metadata, Completion};
use crate::farm::plan::Job;
use crate::load::LoadedScene;
use crate::output::{write_exr_image, AovChannels, ExactSums, ExrImage};
use plume_core::error::{Error, Result};
use plume_engine::film::{Moments, FIXED_POINT_BITS};
use plume_engine::integrator::AovLayout;
use plume_engine::noise::FrameNoise;
use plume_engine::render::RenderResult;
use plume_engine::stats::{peak_rss_since_reset_bytes, RenderStats};
use plume_scene::split::format_range;
use plume_scene::SceneDescription;

/// The files of one frame, frame tokens resolved.
pub struct FramePaths {
    /// The (first) volume's file.
    pub input: PathBuf,
    /// The further volumes' files (`volumes[1].file`, …), in order.
    pub more_inputs: Vec<PathBuf>,
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
            more_inputs: job.more_inputs.iter().map(|p| p.resolve(frame)).collect(),
            output: job.output.resolve(frame),
            preview: job.preview.as_ref().map(|p| p.resolve(frame)),
            stats: job.stats.as_ref().map(|p| p.resolve(frame)),
        }
    }
}

impl FramePaths {
    /// `scene` as this frame loads it: the further volumes' files are this frame's
    /// ([`FramePaths::more_inputs`]; the first volume's is [`FramePaths::input`], given to
    /// the loader beside the scene). Borrowed as it is for a scene of one volume.
    #[must_use]
    pub fn scene<'a>(&self, scene: &'a SceneDescription) -> Cow<'a, SceneDescription> {
        if self.more_inputs.is_empty() {
            return Cow::Borrowed(scene);
        }
        let mut frame_scene = scene.clone();
        for (entry, file) in frame_scene.more_volumes.iter_mut().zip(&self.more_inputs) {
            entry.volume.file.clone_from(file);
        }
        Cow::Owned(frame_scene)
    }
}

/// Seconds a frame took.
pub(crate) struct Timing {
    pub(crate) wall: f64,
    pub(crate) cpu: f64,
    pub(crate) time_to_first_sample: f64,
}

/// The frame's inputs' identity.
pub(crate) struct InputId {
    /// The first input's SHA-256, or with several volumes the SHA-256 of every input's
    /// (`fingerprint::inputs_sha256`): what resumes and merged parts must agree on.
    pub(crate) sha256: String,
    /// The first input's own SHA-256.
    pub(crate) first_sha256: String,
    /// The inputs' sizes together.
    pub(crate) bytes: u64,
}

/// What identifies the frame's pixels and how it was asked for.
pub(crate) struct FrameId<'a> {
    pub(crate) frame: Option<i64>,
    pub(crate) seed: u64,
    pub(crate) settings_hash: String,
    pub(crate) command_line: &'a str,
}

/// A frame as rendered: the engine's result, its film's sums and moments gathered once,
/// and the noise computed from them once (for the record and for the `error` layer).
pub(crate) struct Rendered<'a> {
    /// What the engine returned: the film, counters and times.
    pub(crate) result: &'a RenderResult,
    /// RGBA sums, row-major over the job's pixels.
    pub(crate) sums: Vec<[i128; 4]>,
    /// Moments, the same pixels.
    pub(crate) moments: Vec<Moments>,
    /// The `error` layer, the estimate and the spp histogram.
    pub(crate) noise: FrameNoise,
    /// Whether the whole budget was rendered, or the frame was interrupted or hit its time
    /// limit.
    pub(crate) status: Completion,
    /// Samples per pixel of the frame, resumed ones included.
    pub(crate) spp: u64,
}

impl<'a> Rendered<'a> {
    /// The frame of `job` that `result` rendered, `spp` samples in all.
    pub(crate) fn new(
        job: &Job<'_>,
        result: &'a RenderResult,
        status: Completion,
        spp: u64,
    ) -> Rendered<'a> {
        let (sums, moments) = (result.film.sums(), result.film.moments());
        let floor =
            job.shot.settings.render.noise_floor.unwrap_or(plume_engine::noise::DEFAULT_FLOOR);
        let noise = FrameNoise::of(&sums, &moments, job.pixels(), floor);
        Rendered { result, sums, moments, noise, status, spp }
    }
}

/// The frame's record: EXR header and stats line.
pub(crate) fn stats_record(
    job: &Job<'_>,
    paths: &FramePaths,
    loaded: &LoadedScene,
    rendered: &Rendered<'_>,
    id: &FrameId<'_>,
    input: &InputId,
    timing: &Timing,
) -> RenderStats {
    let Rendered { result, status, spp, .. } = *rendered;
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
        input_sha256: input.sha256.clone(),
        output: paths.output.display().to_string(),
        status: status.as_str().into(),
        spp,
        spp_histogram: rendered.noise.histogram.clone(),
        error_estimate: rendered.noise.estimate,
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
pub(crate) fn write_outputs(
    job: &Job<'_>,
    paths: &FramePaths,
    loaded: &LoadedScene,
    rendered: &Rendered<'_>,
    record: &RenderStats,
    input: &InputId,
    working_dir: &std::path::Path,
) -> Result<()> {
    let Rendered { result, status, .. } = *rendered;
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
    // The further volumes' mapped caches: their checksums too
    for check in &loaded.further_caches {
        check.verified()?;
    }
    if let Some(check) = &loaded.cache {
        // Checksums, and the file at the path is still the one mapped
        check.verified()?;
        // ... and the one whose identity the record holds (part of it, with several
        // volumes), hashed before it was opened
        if crate::cache::is_cache_path(&paths.input)
            && file_sha256(&paths.input)?.0 != input.first_sha256
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
    let noisy = result.film.average();
    let (film_sums, moments) = (&rendered.sums, &rendered.moments);
    let sums = (job.write_sums || status != Completion::Complete)
        .then_some(ExactSums { rgba: film_sums, moments });
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
    let frame_sums = FrameSums { rgba: film_sums, moments, aov: &aov_sums };
    let Written { pixels, layers, denoised } =
        beauty_and_layers(layout.as_ref(), frame_sums, noisy, &rendered.noise.errors, crop);
    if settings.output.denoise && !denoised {
        let block = crate::farm::fingerprint::half_block(settings);
        warn(format!("{} spp: denoising needs samples in both half buffers (blocks of {block}: more than {block} spp); the image is not denoised", record.spp));
    }
    let aovs = Some(AovChannels {
        layers: &layers,
        sums: layout
            .as_ref()
            .filter(|_| sums.is_some())
            .map(|_| (names.as_slice(), aov_sums.as_slice())),
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
