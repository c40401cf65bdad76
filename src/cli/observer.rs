//! What `plume render` shows while it runs ([`Terminal`], the farm's
//! [`JobObserver`]): a progress bar on a terminal (indicatif; not with `-q`), the
//! machine-readable progress lines of `--progress` on stdout
//! ([`plume::farm::progress::Progress`] formats them), a `--debug-pixel` replay (its
//! trace on stderr, its value on stdout), and the error of each frame that failed while
//! the run went on.

use std::io::Write as _;
use std::path::Path;
use std::sync::{Mutex, OnceLock, PoisonError};

use indicatif::{ProgressBar, ProgressStyle};

use plume::farm::observer::{JobObserver, Pass, Replay};
use plume::farm::part::Completion;
use plume::farm::progress::Progress;
use plume_core::error::{exit, Error, Result};
use plume_engine::stats::RenderStats;
use plume_scene::{JobSettings, ProgressFormat};
use plume_volume::out_of_core::mapfault::{self, StdoutProtocol};

use super::logger::name_keys;

/// The terminal side of one `plume render` run.
pub struct Terminal {
    /// `render.quiet`: no progress bar.
    quiet: bool,
    /// `render.progress`.
    mode: ProgressFormat,
    /// The bar of the frame being rendered.
    bar: Mutex<Option<ProgressBar>>,
    /// The progress lines, once the run has started.
    progress: OnceLock<Progress>,
}

impl Terminal {
    /// What a run with `settings` shows.
    #[must_use]
    pub fn new(settings: &JobSettings) -> Terminal {
        Terminal {
            quiet: settings.render.quiet,
            mode: settings.render.progress,
            bar: Mutex::new(None),
            progress: OnceLock::new(),
        }
    }

    /// The run ended with `result` (its error as the user reads it): the progress
    /// protocol's last line, if the run started.
    pub fn finish(&self, result: &Result<()>) {
        if let Some(progress) = self.progress.get() {
            let code = result.as_ref().map_or_else(Error::exit_code, |()| exit::SUCCESS);
            let message = result.as_ref().err().map(|e| name_keys(&e.to_string()));
            progress.done(code, message.as_deref());
        }
    }

    fn with_bar(&self, f: impl FnOnce(&mut Option<ProgressBar>)) {
        f(&mut self.bar.lock().unwrap_or_else(PoisonError::into_inner));
    }
}

/// Progress lines on stdout, flushed per event.
fn stdout_lines(lines: &[String]) {
    let mut out = std::io::stdout().lock();
    for l in lines {
        // A closed stdout must not stop the render
        let _ = writeln!(out, "{l}");
    }
    let _ = out.flush();
}

/// `image`, or `frame N`.
fn frame_name(frame: Option<i64>) -> String {
    frame.map_or_else(|| "image".to_string(), |f| format!("frame {f}"))
}

impl JobObserver for Terminal {
    fn run_started(&self, frames: usize) {
        // A mapped input that fails under the render ends plume from a signal handler,
        // which then prints the protocol's failure line too
        mapfault::report_on_stdout(match self.mode {
            ProgressFormat::None => StdoutProtocol::None,
            ProgressFormat::Openjd => StdoutProtocol::Openjd,
            ProgressFormat::Json => StdoutProtocol::Json,
        });
        let _ = self.progress.set(Progress::new(self.mode, frames, Box::new(stdout_lines)));
    }

    fn frame_started(&self, index: usize, frame: Option<i64>, output: &Path) {
        if let Some(p) = self.progress.get() {
            p.frame_start(index, frame, &output.display().to_string());
        }
    }

    fn frame_skipped(&self, index: usize, frame: Option<i64>, output: &Path) {
        if let Some(p) = self.progress.get() {
            p.frame_skipped(index, frame, &output.display().to_string());
        }
    }

    fn render_started(&self, target: u64) {
        if self.quiet || !std::io::IsTerminal::is_terminal(&std::io::stderr()) {
            return;
        }
        let pb = if target > 0 { ProgressBar::new(target) } else { ProgressBar::new_spinner() };
        pb.set_style(
            ProgressStyle::with_template(
                "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} spp {msg}",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        self.with_bar(|bar| *bar = Some(pb));
    }

    fn pass_done(&self, pass: &Pass) {
        self.with_bar(|bar| {
            if let Some(pb) = bar {
                pb.set_position(pass.done);
            }
        });
        if let Some(p) = self.progress.get() {
            p.pass(
                pass.index,
                pass.frame,
                pass.resumed + pass.done,
                pass.resumed + pass.target,
                pass.fraction,
            );
        }
    }

    fn render_finished(&self) {
        self.with_bar(|bar| {
            if let Some(pb) = bar.take() {
                pb.finish_and_clear();
            }
        });
    }

    fn frame_done(
        &self,
        index: usize,
        frame: Option<i64>,
        status: Completion,
        record: &RenderStats,
    ) {
        if let Some(p) = self.progress.get() {
            p.frame_done(
                index,
                frame,
                status.as_str(),
                serde_json::to_value(record).expect("invariant: stats serialize"),
            );
        }
    }

    fn frame_failed(&self, index: usize, frame: Option<i64>, error: &Error) {
        let message = name_keys(&error.to_string());
        eprintln!("plume: error: {}: {message}", frame_name(frame));
        if let Some(p) = self.progress.get() {
            p.frame_failed(index, frame, error.exit_code(), &message);
        }
    }

    fn replayed(&self, replay: &Replay) {
        for line in &replay.trace {
            eprintln!("plume: debug {}: {line}", replay.sample);
        }
        println!("{}", replay.value);
    }
}
