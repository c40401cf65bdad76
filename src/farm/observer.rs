//! What a `plume render` run tells the application as it goes ([`JobObserver`]), and
//! what the application gives it besides the shot ([`RunContext`]).
//!
//! The farm never prints: a progress bar, the machine-readable progress lines of
//! `render.progress` (`farm::progress` formats them) and the replay of
//! `render.debug_pixel` are the application's, fed from here. Messages for people go
//! through the `log` facade.

use std::path::Path;

use plume_core::error::Error;
use plume_engine::stats::RenderStats;
use plume_scene::SampleId;

use crate::farm::part::Completion;

/// A pass of a frame ended.
#[derive(Clone, Copy, Debug)]
pub struct Pass {
    /// The frame's place in the run, from 0.
    pub index: usize,
    /// The frame number (`None` without frames).
    pub frame: Option<i64>,
    /// Samples per pixel rendered by this run so far, of `target`.
    pub done: u64,
    /// Samples per pixel this run renders (0 for a time budget).
    pub target: u64,
    /// Samples per pixel the image held before this run (a continued output).
    pub resumed: u64,
    /// How much of the frame is done, in [0, 1]: by samples, or by time for a time budget.
    pub fraction: f64,
}

/// A replayed pixel sample (`render.debug_pixel`): nothing is written.
#[derive(Clone, Debug)]
pub struct Replay {
    /// The sample.
    pub sample: SampleId,
    /// The path's trace, one line per event (segments, collisions, light samples).
    pub trace: Vec<String>,
    /// The sample's value and AOVs as the integrator returned them (`Debug` text).
    pub value: String,
}

/// Told of a run's progress. Every method has an empty default: implement what is shown.
///
/// Calls come from the thread that runs the frames, in order: `run_started`, then per
/// frame `frame_skipped`, or `frame_started`, `render_started`, `pass_done`…,
/// `render_finished`, `frame_done`, or `replayed`, or `frame_failed` (when the run goes
/// on without the frame; an error that ends the run is returned instead).
pub trait JobObserver: Sync {
    /// The run renders `frames` frames.
    fn run_started(&self, _frames: usize) {}

    /// The `index`-th frame (number `frame`) starts; it is written to `output`.
    fn frame_started(&self, _index: usize, _frame: Option<i64>, _output: &Path) {}

    /// The `index`-th frame's `output` was already complete: skipped.
    fn frame_skipped(&self, _index: usize, _frame: Option<i64>, _output: &Path) {}

    /// The frame's passes start: `target` samples per pixel (0 for a time budget).
    fn render_started(&self, _target: u64) {}

    /// A pass ended.
    fn pass_done(&self, _pass: &Pass) {}

    /// The frame's passes ended (also when stopped early).
    fn render_finished(&self) {}

    /// The `index`-th frame was written, `status` being how far it got; `record` is its
    /// statistics record.
    fn frame_done(
        &self,
        _index: usize,
        _frame: Option<i64>,
        _status: Completion,
        _record: &RenderStats,
    ) {
    }

    /// The `index`-th frame failed with `error`; the run goes on with the next frame.
    fn frame_failed(&self, _index: usize, _frame: Option<i64>, _error: &Error) {}

    /// `render.debug_pixel`: a sample was replayed instead of rendering the frame.
    fn replayed(&self, _replay: &Replay) {}

    /// Whether the observer asks the render to stop, as a signal would: asked between
    /// passes (an embedding application's own stop, such as Python's Ctrl-C or a progress
    /// callback that failed). The frame is then written as interrupted.
    fn stop_requested(&self) -> bool {
        false
    }
}

/// An observer that shows nothing (tests, benchmarks).
#[derive(Clone, Copy, Debug, Default)]
pub struct Silent;

impl JobObserver for Silent {}

/// What the application gives a `plume render` run besides the shot.
#[derive(Clone, Copy)]
pub struct RunContext<'a> {
    /// The command line, recorded in every output.
    pub command_line: &'a str,
    /// The directory relative paths are relative to: the scene description recorded in
    /// each EXR has its paths made absolute against it.
    pub working_dir: &'a Path,
    /// Told of the run's progress.
    pub observer: &'a dyn JobObserver,
}
