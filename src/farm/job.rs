//! `plume render` as a farm runs it: one frame, or a chunk of a sequence, per command.
//!
//! The shot was validated once ([`plume_scene::ValidShot`]); [`Job::new`] adds what
//! needs the file system, then each frame is rendered in turn by `farm::frame`. A frame
//! that fails is reported (stderr, `--progress`) and the others go on; a signal stops the
//! run after writing the current frame. The exit code sums up the run (`error::exit`): a
//! run of one frame exits with that frame's code, a run of several with 7 when any failed
//! or stopped early, and 5 when interrupted. An input that fails while in use
//! ([`Error::InputFailed`], or a lost page of a mapped file, `mapfault`) ends any run at
//! once with 4.

use std::ops::Range;

use plume_core::error::{exit, Error, Result};
use crate::farm::frame::{render_frame, FrameOutcome};
use crate::farm::part::Completion;
use crate::farm::pattern::FramePattern;
use crate::farm::progress::Progress;
use crate::farm::{frames, signals, split};
use plume_engine::film::Crop;
use plume_scene::{SceneDescription, ValidShot};

/// The plan of a `plume render` run.
pub struct Job<'a> {
    /// The shot as given.
    pub shot: &'a ValidShot,
    /// The volume file, maybe with a frame token.
    pub input: FramePattern,
    /// The EXR, maybe with a frame token.
    pub output: FramePattern,
    /// The preview.
    pub preview: Option<FramePattern>,
    /// The statistics file.
    pub stats: Option<FramePattern>,
    /// Frames in order; `[None]` without frames.
    pub frames: Vec<Option<i64>>,
    /// Pixels to render (crop or tile), `None` for the whole image.
    pub crop: Option<Crop>,
    /// Samples to render: the sample range, or `0..spp`; `None` for a time budget.
    pub samples: Option<Range<u64>>,
    /// Store exact sums in the EXR (parts and `output.sums`).
    pub write_sums: bool,
}

impl<'a> Job<'a> {
    /// Plan the run: frame patterns, frames, crop and samples.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] naming the key: a frame token without frames, several
    /// frames written to one file.
    pub fn new(shot: &'a ValidShot) -> Result<Job<'a>> {
        let (scene, settings) = (&shot.scene, &shot.settings);
        let input = FramePattern::parse(&scene.volume.file);
        let output = FramePattern::parse(&settings.output.image);
        let preview = settings.output.preview.as_deref().map(FramePattern::parse);
        let stats = settings.output.stats.as_deref().map(FramePattern::parse);
        let frames: Vec<Option<i64>> = match &settings.farm.frames {
            Some(list) => frames::parse_frames(list).map_err(|m| Error::invalid("farm.frames", m))?.into_iter().map(Some).collect(),
            None => {
                for (key, p) in [("volume.file", &input), ("output.image", &output)] {
                    if p.has_frame() && !p.as_path().exists() {
                        return Err(Error::invalid(key, format!("{} has a frame token; say which frames to render with farm.frames", p.as_path().display())));
                    }
                }
                vec![None]
            }
        };
        if frames.len() > 1 {
            for (key, p) in [("output.image", Some(&output)), ("output.preview", preview.as_ref())] {
                if let Some(p) = p.filter(|p| !p.has_frame()) {
                    return Err(Error::invalid(
                        key,
                        format!("{} frames would all be written to {}; put a frame token in it (####, %04d or $F4)", frames.len(), p.as_path().display()),
                    ));
                }
            }
        }
        let (width, height) = (scene.camera.width, scene.camera.height);
        let farm = &settings.farm;
        let crop = match (farm.crop, farm.tile) {
            (Some(c), _) => Some(c),
            (None, Some(t)) => Some(split::tile_crop(t.index, t.count, width, height).map_err(|m| Error::invalid("farm.tile", m))?),
            (None, None) => None,
        };
        let samples = match (&farm.sample_range, settings.render.spp, settings.render.time) {
            (Some(r), _, _) => Some(r.clone()),
            (None, _, Some(_)) => None,
            (None, Some(n), None) => Some(0..u64::from(n)),
            (None, None, None) => Some(0..64),
        };
        let write_sums = settings.output.sums || crop.is_some() || farm.sample_range.is_some();
        Ok(Job { shot, input, output, preview, stats, frames, crop, samples, write_sums })
    }

    /// The scene.
    #[must_use]
    pub fn scene(&self) -> &SceneDescription {
        &self.shot.scene
    }

    /// The pixels each frame renders: the crop or tile, else the whole image.
    #[must_use]
    pub fn pixels(&self) -> Crop {
        self.crop.unwrap_or(Crop::full(self.shot.scene.camera.width, self.shot.scene.camera.height))
    }
}

/// Run `plume render`.
///
/// # Errors
/// For one frame, that frame's error; for several, [`Error::FramesFailed`]; when a
/// signal stopped the run, [`Error::Interrupted`]; bad values and an input that failed
/// while in use ([`Error::InputFailed`]) stop the run at once.
pub fn render_command(shot: &ValidShot, command_line: &str) -> Result<()> {
    let job = Job::new(shot)?;
    if let Err(e) = signals::install() {
        eprintln!("plume: warning: cannot handle SIGTERM/SIGINT ({e}); a signal will end plume without writing the image so far");
    }
    let progress = Progress::new(shot.settings.render.progress, job.frames.len());
    let result = run_frames(&job, command_line, &progress);
    let code = result.as_ref().map_or_else(Error::exit_code, |()| exit::SUCCESS);
    progress.done(code, result.as_ref().err().map(ToString::to_string).as_deref());
    result
}

fn run_frames(job: &Job<'_>, command_line: &str, progress: &Progress) -> Result<()> {
    let single = job.frames.len() == 1;
    let mut failed = Vec::new();
    for (index, &frame) in job.frames.iter().enumerate() {
        if let Some(signal) = signals::stop_requested() {
            let what = format!("frames from {} on were not started", frame.map_or_else(String::new, |f| f.to_string()));
            return Err(Error::Interrupted { signal: signal.into(), what });
        }
        match render_frame(job, index, frame, command_line, progress) {
            Ok(FrameOutcome::Skipped | FrameOutcome::Replayed | FrameOutcome::Written { status: Completion::Complete, .. }) => {}
            Ok(FrameOutcome::Written { status: Completion::Interrupted, output, spp }) => {
                let signal = signals::stop_requested().unwrap_or("a signal");
                return Err(Error::Interrupted { signal: signal.into(), what: format!("wrote {} with {spp} spp", output.display()) });
            }
            Ok(FrameOutcome::NotStarted) => {
                let signal = signals::stop_requested().unwrap_or("a signal");
                return Err(Error::Interrupted { signal: signal.into(), what: "stopped before the first pass; nothing written".into() });
            }
            Ok(FrameOutcome::Written { status: Completion::TimeLimit, output, spp }) => {
                let e = Error::TimeLimit { what: format!("wrote {} with {spp} spp", output.display()) };
                if single {
                    return Err(e);
                }
                report(frame, index, &e, progress);
                failed.push(frame.unwrap_or(0));
            }
            // An input failing while in use (truncated, rewritten or replaced under plume,
            // or its storage failing) ends the run at once with exit code 4, however it
            // was noticed: a lost page comes as SIGBUS, which `mapfault` can only end the
            // process for, so the checksum pass and the final check of the file do the
            // same, and one fault has one exit code
            Err(e) if single || e.exit_code() == exit::BAD_ARGUMENTS || matches!(e, Error::InputFailed { .. }) => return Err(e),
            Err(e) => {
                report(frame, index, &e, progress);
                failed.push(frame.unwrap_or(0));
            }
        }
    }
    if failed.is_empty() {
        Ok(())
    } else {
        Err(Error::FramesFailed { failed, total: job.frames.len() })
    }
}

fn report(frame: Option<i64>, index: usize, e: &Error, progress: &Progress) {
    let name = frame.map_or_else(|| "image".to_string(), |f| format!("frame {f}"));
    eprintln!("plume: error: {name}: {e}");
    progress.frame_failed(index, frame, e.exit_code(), &e.to_string());
}
