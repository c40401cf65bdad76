//! `plume render` as a farm runs it: one frame, or a chunk of a sequence, per command.
//!
//! The shot was validated once ([`plume_scene::ValidShot`]); [`Job::new`] adds what
//! needs the file system, then each frame is rendered in turn by `farm::frame`. A frame
//! that fails is reported (to the
//! [`JobObserver`](crate::farm::observer::JobObserver)) and the others go on; a signal stops
//! the run after writing the current frame. The exit code sums up the run
//! (`error::exit`): a run of one frame exits with that frame's code, a run of several
//! with 7 when any failed or stopped early, and 5 when interrupted. An input that fails
//! while in use ([`Error::InputFailed`], or a lost page of a mapped file, `mapfault`)
//! ends any run at once with 4.

use crate::farm::frame::{render_frame, FrameOutcome};
use crate::farm::observer::RunContext;
use crate::farm::part::Completion;
use crate::farm::plan::Job;
use crate::farm::signals;
use plume_core::error::{exit, Error, Result};
use plume_scene::ValidShot;

/// Run `plume render`, telling `context.observer` how it goes. SIGTERM and SIGINT stop it
/// between passes once the application has installed `farm::signals`.
///
/// # Errors
/// For one frame, that frame's error; for several, [`Error::FramesFailed`] (each failed
/// frame's error went to
/// [`JobObserver::frame_failed`](crate::farm::observer::JobObserver::frame_failed)); when a signal stopped the run,
/// [`Error::Interrupted`]; bad values and an input that failed while in use
/// ([`Error::InputFailed`]) stop the run at once.
pub fn render_command(shot: &ValidShot, context: &RunContext<'_>) -> Result<()> {
    let job = Job::new(shot)?;
    context.observer.run_started(job.frames.len());
    run_frames(&job, context)
}

fn run_frames(job: &Job<'_>, context: &RunContext<'_>) -> Result<()> {
    let single = job.frames.len() == 1;
    let mut failed = Vec::new();
    for (index, &frame) in job.frames.iter().enumerate() {
        if let Some(signal) = signals::stop_requested() {
            let what = format!(
                "frames from {} on were not started",
                frame.map_or_else(String::new, |f| f.to_string())
            );
            return Err(Error::Interrupted { signal: signal.into(), what });
        }
        match render_frame(job, index, frame, context) {
            Ok(
                FrameOutcome::Skipped
                | FrameOutcome::Replayed
                | FrameOutcome::Written { status: Completion::Complete, .. },
            ) => {}
            Ok(FrameOutcome::Written { status: Completion::Interrupted, output, spp }) => {
                let signal = signals::stop_requested().unwrap_or("a signal");
                return Err(Error::Interrupted {
                    signal: signal.into(),
                    what: format!("wrote {} with {spp} spp", output.display()),
                });
            }
            Ok(FrameOutcome::NotStarted) => {
                let signal = signals::stop_requested().unwrap_or("a signal");
                return Err(Error::Interrupted {
                    signal: signal.into(),
                    what: "stopped before the first pass; nothing written".into(),
                });
            }
            Ok(FrameOutcome::Written { status: Completion::TimeLimit, output, spp }) => {
                let e =
                    Error::TimeLimit { what: format!("wrote {} with {spp} spp", output.display()) };
                if single {
                    return Err(e);
                }
                context.observer.frame_failed(index, frame, &e);
                failed.push(frame.unwrap_or(0));
            }
            // An input failing while in use (truncated, rewritten or replaced under plume,
            // or its storage failing) ends the run at once with exit code 4, however it
            // was noticed: a lost page comes as SIGBUS, which `mapfault` can only end the
            // process for, so the checksum pass and the final check of the file do the
            // same, and one fault has one exit code
            Err(e)
                if single
                    || e.exit_code() == exit::BAD_ARGUMENTS
                    || matches!(e, Error::InputFailed { .. }) =>
            {
                return Err(e)
            }
            Err(e) => {
                context.observer.frame_failed(index, frame, &e);
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
