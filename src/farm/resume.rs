//! Skip, continue or render anew an existing output of `plume render` (`decide`, see
//! `farm::frame`'s docs for the rules; `unless_input_changed` once the input is hashed),
//! and the samples this run then renders (`SamplePlan`: the asked range, minus what a
//! continued output holds).

use std::path::Path;

use crate::farm::layers::layout_for;
use crate::farm::observer::JobObserver;
use crate::farm::outputs::FramePaths;
use crate::farm::part::{assess, Existing, Expected, PartInfo};
use crate::farm::plan::Job;
use plume_core::error::Result;
use plume_engine::render::SampleBudget;
use plume_scene::split::format_range;

/// An output to continue: what it holds and its exact sums and moments (and AOV sums).
pub(crate) type Resume = (PartInfo, crate::output::OwnedSums, Option<Vec<i128>>);

/// Skip, continue or render anew: `None` when the output is complete (skip), else the
/// output to continue, if any.
///
/// # Errors
/// None; fallible for the outputs' checks.
pub(crate) fn decide(
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

/// `resume`, unless the input changed since it was started (`input_sha256` is the
/// input's now): then it is rendered again.
pub(crate) fn unless_input_changed(
    resume: Option<Resume>,
    output: &Path,
    input_sha256: &str,
) -> Option<Resume> {
    if resume.as_ref().is_some_and(|(info, ..)| info.input_sha256 != input_sha256) {
        log::info!(
            "{}: the input changed since it was started; rendering it again",
            output.display()
        );
        return None;
    }
    resume
}

/// Say that `resume`, if any, is continued.
pub(crate) fn log_continuing(output: &Path, resume: Option<&Resume>) {
    if let Some((info, ..)) = resume {
        log::info!(
            "{}: continuing from samples {} ({})",
            output.display(),
            format_range(&info.samples),
            info.status.as_str()
        );
    }
}

/// The samples this run renders: the asked range, minus what a resumed image holds.
pub(crate) struct SamplePlan {
    /// The samples per pixel (or the time) this run renders.
    pub(crate) budget: SampleBudget,
    /// The index of the first sample this run renders.
    pub(crate) first_sample: u64,
    /// Samples per pixel the continued output already holds.
    pub(crate) resumed_spp: u64,
}

impl SamplePlan {
    pub(crate) fn new(job: &Job<'_>, resume: Option<&Resume>) -> SamplePlan {
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
