//! `plume render` as a farm runs it: one frame, or a chunk of a sequence, per command.
//!
//! The flags are checked once ([`Job::new`]); then each frame is rendered in turn by
//! `farm::frame`. A frame that fails is reported (stderr, `--progress`) and the others go
//! on; a signal stops the run after writing the current frame. The exit code sums up the
//! run (`error::exit`): a run of one frame exits with that frame's code, a run of several
//! with 7 when any failed or stopped early, and 5 when interrupted.

use std::ops::Range;

use crate::cli::RenderArgs;
use crate::error::{exit, Error, Result};
use crate::farm::frame::{render_frame, FrameOutcome};
use crate::farm::part::Completion;
use crate::farm::pattern::FramePattern;
use crate::farm::progress::Progress;
use crate::farm::{frames, signals, split};
use crate::film::Crop;

/// The validated plan of a `plume render` run.
pub struct Job<'a> {
    /// The flags as given.
    pub args: &'a RenderArgs,
    /// FILE, maybe with a frame token.
    pub input: FramePattern,
    /// `--output`, maybe with a frame token.
    pub output: FramePattern,
    /// `--preview`.
    pub preview: Option<FramePattern>,
    /// `--stats`.
    pub stats: Option<FramePattern>,
    /// Frames in order; `[None]` without `--frames`.
    pub frames: Vec<Option<i64>>,
    /// Pixels to render (`--crop`, `--tile`), `None` for the whole image.
    pub crop: Option<Crop>,
    /// Samples to render: `--sample-range`, or `0..--spp`; `None` for a `--time` budget.
    pub samples: Option<Range<u64>>,
    /// Store exact sums in the EXR (parts and `--sums`).
    pub write_sums: bool,
}

impl<'a> Job<'a> {
    /// Check the farm flags (the render flags are checked by `app::validate`).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] naming the flag.
    pub fn new(args: &'a RenderArgs) -> Result<Job<'a>> {
        let input = FramePattern::parse(&args.file);
        let output = FramePattern::parse(&args.output);
        let preview = args.preview.as_deref().map(FramePattern::parse);
        let stats = args.stats.as_deref().map(FramePattern::parse);
        let frames: Vec<Option<i64>> = match &args.frames {
            Some(list) => frames::parse_frames(list).map_err(|m| Error::invalid("--frames", m))?.into_iter().map(Some).collect(),
            None => {
                for (flag, p) in [("FILE", &input), ("--output", &output)] {
                    if p.has_frame() && !p.as_path().exists() {
                        return Err(Error::invalid(flag, format!("{} has a frame token; say which frames to render with --frames", p.as_path().display())));
                    }
                }
                vec![None]
            }
        };
        if frames.len() > 1 {
            for (flag, p) in [("--output", Some(&output)), ("--preview", preview.as_ref())] {
                if let Some(p) = p.filter(|p| !p.has_frame()) {
                    return Err(Error::invalid(flag, format!("{} frames would all be written to {}; put a frame token in it (####, %04d or $F4)", frames.len(), p.as_path().display())));
                }
            }
        }
        if let Some(t) = args.time_limit {
            if !(t.is_finite() && t > 0.0) {
                return Err(Error::invalid("--time-limit", format!("{t} must be a positive number of seconds")));
            }
        }
        let crop = match (args.crop, args.tile) {
            (Some(c), _) => {
                if !c.fits(args.width, args.height) {
                    return Err(Error::invalid("--crop", format!("{c} is not inside the {}x{} image", args.width, args.height)));
                }
                Some(c)
            }
            (None, Some((i, n))) => Some(split::tile_crop(i, n, args.width, args.height).map_err(|m| Error::invalid("--tile", m))?),
            (None, None) => None,
        };
        let samples = match (&args.sample_range, args.spp, args.time) {
            (Some(r), _, _) => Some(r.clone()),
            (None, _, Some(_)) => None,
            (None, Some(n), None) => Some(0..u64::from(n)),
            (None, None, None) => Some(0..64),
        };
        if let Some(r) = &samples {
            if r.end - r.start > u64::from(u32::MAX) {
                return Err(Error::invalid("--sample-range", "at most 4294967295 samples per pixel in one run"));
            }
        }
        let write_sums = args.sums || crop.is_some() || args.sample_range.is_some();
        Ok(Job { args, input, output, preview, stats, frames, crop, samples, write_sums })
    }
}

/// Run `plume render`.
///
/// # Errors
/// For one frame, that frame's error; for several, [`Error::FramesFailed`]; when a
/// signal stopped the run, [`Error::Interrupted`]; bad flags stop the run at once.
pub fn render_command(args: &RenderArgs, command_line: &str) -> Result<()> {
    crate::app::validate(args)?;
    let job = Job::new(args)?;
    if let Err(e) = signals::install() {
        eprintln!("plume: warning: cannot handle SIGTERM/SIGINT ({e}); a signal will end plume without writing the image so far");
    }
    let progress = Progress::new(args.progress, job.frames.len());
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
            Err(e) if single || e.exit_code() == exit::BAD_ARGUMENTS => return Err(e),
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
