//! Machine-readable progress for farm schedulers (`render.progress`): the lines, formatted
//! here and handed to a sink the application gives (the binary writes them to stdout;
//! human logs go to stderr).
//!
//! - `openjd`: Open Job Description's stdout protocol, which AWS Deadline Cloud and
//!   `openjd run` parse: `openjd_progress: <0–100>` and `openjd_status: <text>` lines,
//!   and `openjd_fail: <reason>` before a non-zero exit.
//! - `json`: one JSON object per line with an `event` field: `frame_start`, `progress`,
//!   `frame_done`, `frame_skipped`, `frame_failed`, `done`.
//!
//! Percentages count the whole run (all frames of the chunk). Progress lines are sent at
//! most once a second; every other event is sent as it happens.

use std::sync::Mutex;
use std::time::{Duration, Instant};

use serde_json::{json, Value};

use plume_scene::ProgressFormat;

/// Least time between two `progress` lines.
const THROTTLE: Duration = Duration::from_secs(1);

/// Where the lines go: called once per event with its lines, in order.
pub type Sink = Box<dyn Fn(&[String]) + Send + Sync>;

/// The progress reporter of one run.
pub struct Progress {
    mode: ProgressFormat,
    frames: usize,
    last: Mutex<Option<Instant>>,
    sink: Sink,
}

impl Progress {
    /// A reporter for a run of `frames` frames, sending its lines to `sink`.
    #[must_use]
    pub fn new(mode: ProgressFormat, frames: usize, sink: Sink) -> Progress {
        Progress { mode, frames: frames.max(1), last: Mutex::new(None), sink }
    }

    fn emit(&self, lines: &[String]) {
        (self.sink)(lines);
    }

    fn percent(&self, index: usize, fraction: f64) -> f64 {
        (100.0 * (index as f64 + fraction.clamp(0.0, 1.0)) / self.frames as f64).min(100.0)
    }

    /// Frame `frame` (the `index`-th of the run, from 0) starts.
    pub fn frame_start(&self, index: usize, frame: Option<i64>, output: &str) {
        match self.mode {
            ProgressFormat::None => {}
            ProgressFormat::Openjd => self.emit(&[
                format!("openjd_status: {} ({}/{}): rendering", name(frame), index + 1, self.frames),
                format!("openjd_progress: {:.2}", self.percent(index, 0.0)),
            ]),
            ProgressFormat::Json => {
                self.emit(&[json!({"event": "frame_start", "frame": frame, "index": index, "frames": self.frames, "output": output}).to_string()])
            }
        }
    }

    /// A pass of the `index`-th frame ended: `done` spp of `target` (0 when the budget
    /// is time), `fraction` of the frame done.
    pub fn pass(&self, index: usize, frame: Option<i64>, done: u64, target: u64, fraction: f64) {
        if self.mode == ProgressFormat::None {
            return;
        }
        {
            let mut last = self.last.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
            if last.is_some_and(|t| t.elapsed() < THROTTLE) {
                return;
            }
            *last = Some(Instant::now());
        }
        let percent = self.percent(index, fraction);
        match self.mode {
            ProgressFormat::None => {}
            ProgressFormat::Openjd => self.emit(&[format!("openjd_progress: {percent:.2}")]),
            ProgressFormat::Json => {
                self.emit(&[json!({"event": "progress", "frame": frame, "spp": done, "target_spp": target, "percent": percent}).to_string()])
            }
        }
    }

    /// The `index`-th frame was written; `record` is its stats record.
    pub fn frame_done(&self, index: usize, frame: Option<i64>, status: &str, record: Value) {
        let percent = self.percent(index, 1.0);
        match self.mode {
            ProgressFormat::None => {}
            ProgressFormat::Openjd => {
                self.emit(&[format!("openjd_status: {} ({}/{}): {status}", name(frame), index + 1, self.frames), format!("openjd_progress: {percent:.2}")])
            }
            ProgressFormat::Json => {
                self.emit(&[json!({"event": "frame_done", "frame": frame, "status": status, "percent": percent, "stats": record}).to_string()])
            }
        }
    }

    /// The `index`-th frame's output was already complete.
    pub fn frame_skipped(&self, index: usize, frame: Option<i64>, output: &str) {
        let percent = self.percent(index, 1.0);
        match self.mode {
            ProgressFormat::None => {}
            ProgressFormat::Openjd => self.emit(&[
                format!("openjd_status: {} ({}/{}): already complete, skipped", name(frame), index + 1, self.frames),
                format!("openjd_progress: {percent:.2}"),
            ]),
            ProgressFormat::Json => self.emit(&[json!({"event": "frame_skipped", "frame": frame, "output": output, "percent": percent}).to_string()]),
        }
    }

    /// The `index`-th frame failed with `error` (exit code `code`).
    pub fn frame_failed(&self, index: usize, frame: Option<i64>, code: i32, error: &str) {
        match self.mode {
            ProgressFormat::None => {}
            ProgressFormat::Openjd => self.emit(&[format!(
                "openjd_status: {} ({}/{}): failed: {}",
                name(frame),
                index + 1,
                self.frames,
                one_line(error)
            )]),
            ProgressFormat::Json => self.emit(&[
                json!({"event": "frame_failed", "frame": frame, "exit_code": code, "error": error})
                    .to_string(),
            ]),
        }
    }

    /// The run ends with exit code `code` (`message` says why when it is not 0).
    pub fn done(&self, code: i32, message: Option<&str>) {
        match self.mode {
            ProgressFormat::None => {}
            ProgressFormat::Openjd => {
                let mut lines = Vec::new();
                if code == 0 {
                    lines.push("openjd_progress: 100.00".to_string());
                } else {
                    lines.push(format!(
                        "openjd_fail: exit code {code}: {}",
                        one_line(message.unwrap_or("failed"))
                    ));
                }
                self.emit(&lines);
            }
            ProgressFormat::Json => self
                .emit(&[json!({"event": "done", "exit_code": code, "error": message}).to_string()]),
        }
    }
}

fn name(frame: Option<i64>) -> String {
    frame.map_or_else(|| "image".to_string(), |f| format!("frame {f}"))
}

fn one_line(s: &str) -> String {
    s.replace(['\n', '\r'], " ")
}
