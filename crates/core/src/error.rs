//! The library's error type. Every message names the file, grid or flag involved, so
//! `main` can print it as one line and exit non-zero.

use std::path::PathBuf;

/// Result alias used throughout plume.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong before or after rendering (the render itself is infallible).
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The input file does not exist or cannot be opened.
    #[error("cannot open {}: {source}", .path.display())]
    Open {
        /// File that was opened.
        path: PathBuf,
        /// OS error.
        #[source]
        source: std::io::Error,
    },
    /// OpenVDB refused the file (corrupt, truncated, not a VDB, unsupported version).
    #[error("cannot read VDB file {}: {message}", .path.display())]
    Vdb {
        /// File being read.
        path: PathBuf,
        /// What OpenVDB (or the shim's validation) said.
        message: String,
    },
    /// No grid with the requested name (or index) in the file.
    #[error("no grid {name:?} in {}; available: {}", .path.display(), format_list(.available))]
    GridNotFound {
        /// File searched.
        path: PathBuf,
        /// Requested selector, e.g. `density` or `density[1]`.
        name: String,
        /// Selectors of the grids that exist.
        available: Vec<String>,
    },
    /// The grid exists but has a value type or transform plume cannot use.
    #[error("grid {grid:?} in {}: {message}", .path.display())]
    UnsupportedGrid {
        /// File read.
        path: PathBuf,
        /// Grid selector.
        grid: String,
        /// What is unsupported, e.g. "value type vec3s is not a scalar grid".
        message: String,
    },
    /// Reading would need more memory than allowed.
    #[error("{}: grid {grid:?} needs {needed} bytes, more than the input memory limit of {limit} bytes (reading.max_input_memory)", .path.display())]
    TooLarge {
        /// File read.
        path: PathBuf,
        /// Grid selector.
        grid: String,
        /// Bytes the grid would need.
        needed: u64,
        /// Limit in force.
        limit: u64,
    },
    /// The isolated reader process (see `vdb::isolate`) failed on this file: it crashed,
    /// hung, ran out of its memory or CPU limit, or replied with garbage. plume itself is
    /// unharmed; the file is treated as unreadable.
    #[error("corrupt or hostile VDB {}: {what}{}", .path.display(), reading_context(.grid))]
    ReaderFailed {
        /// File being read.
        path: PathBuf,
        /// Selector of the grid being read when it failed; `None` while listing grids.
        grid: Option<String>,
        /// What happened, e.g. "reader crashed with SIGSEGV".
        what: String,
    },
    /// The isolated reader process could not be started (plume's own installation or
    /// the system is at fault, not the input).
    #[error("cannot start the isolated VDB reader {}: {source} (reading.no_isolation reads in-process)", .exe.display())]
    ReaderSpawn {
        /// Executable that serves the reader (the `plume` binary).
        exe: PathBuf,
        /// OS error.
        #[source]
        source: std::io::Error,
    },
    /// A brick cache file (`plume prepare`) is not one, has another format version, fails
    /// a checksum, or no longer matches its source or the render's flags. It is never
    /// rendered from; an automatic cache is rebuilt instead.
    #[error("brick cache {}: {what}", .path.display())]
    Cache {
        /// The cache file.
        path: PathBuf,
        /// What is wrong and what to do.
        what: String,
    },
    /// An input other than a VDB or a brick cache (an environment map, …) is not usable:
    /// not the expected format, the wrong shape, or values plume cannot use.
    #[error("{what}: {message}")]
    InvalidInput {
        /// What the input is and where it came from, e.g. `environment map sky.exr`.
        what: String,
        /// What is wrong, naming the pixel or channel where there is one.
        message: String,
    },
    /// An input that passed its checks failed while plume was using it: it was truncated,
    /// rewritten or replaced by another process, or its storage returned an I/O error.
    /// Nothing computed from it is written. (A fault in a mapped page never becomes this
    /// error: `mapfault` ends the process with the same kind of line and exit code.)
    #[error("{kind} {}: {what}", .path.display())]
    InputFailed {
        /// What the file is, e.g. `brick cache`.
        kind: &'static str,
        /// The file.
        path: PathBuf,
        /// What happened and what to do.
        what: String,
    },
    /// Another process held the lock of an automatic brick cache's conversion for longer
    /// than `render.cache_lock_timeout` (it may hang), and the input does not fit the
    /// memory budget without the cache. Nothing was written.
    #[error("{}: {what}", .lock.display())]
    CacheLocked {
        /// The lock file (`.NAME.lock` beside the cache).
        lock: PathBuf,
        /// Who held it, for how long, and what to do.
        what: String,
    },
    /// A flag has a value plume cannot use.
    #[error("invalid value for {flag}: {message}")]
    InvalidArgument {
        /// The flag, e.g. `--camera-from`.
        flag: String,
        /// Why.
        message: String,
    },
    /// A scene file (`plume render shot.toml`) does not parse, has an unknown key or a
    /// value of the wrong type or out of range.
    #[error("{}{}: {}{message}", .path.display(), .line.map(|l| format!(":{l}")).unwrap_or_default(), .key.as_ref().map(|k| format!("key `{k}`: ")).unwrap_or_default())]
    SceneFile {
        /// The scene file.
        path: PathBuf,
        /// 1-based line, where known.
        line: Option<usize>,
        /// The dotted key (`camera.width`), where known.
        key: Option<String>,
        /// What is wrong.
        message: String,
    },
    /// Writing an output failed (nothing is left half-written).
    #[error("cannot write {}: {source}", .path.display())]
    Write {
        /// Output path.
        path: PathBuf,
        /// Underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The scene cannot be rendered (empty volume, incompatible grids, …).
    #[error("{0}")]
    Scene(String),
    /// A part given to `plume merge` is unusable or disagrees with the others.
    #[error("{}: {message}", .path.display())]
    InvalidPart {
        /// The part (EXR) at fault.
        path: PathBuf,
        /// Why, naming the other part where two disagree.
        message: String,
    },
    /// SIGTERM or SIGINT stopped the render; what was rendered was written.
    #[error("interrupted by {signal}: {what} (run the same command again to finish)")]
    Interrupted {
        /// `SIGTERM` or `SIGINT`.
        signal: String,
        /// What was written or not.
        what: String,
    },
    /// `--time-limit` stopped a frame before its sample budget; the image was written.
    #[error("time limit reached: {what} (run the same command again to continue)")]
    TimeLimit {
        /// What was written.
        what: String,
    },
    /// Some frames of a sequence failed; the others were rendered.
    #[error("{} of {total} frames failed: {}", .failed.len(), format_frames(.failed))]
    FramesFailed {
        /// The failed frames.
        failed: Vec<i64>,
        /// Frames in the run.
        total: usize,
    },
}

/// Process exit codes (documented in `plume --help` and docs/farm.md, "Exit codes").
pub mod exit {
    /// Success (also: every output already complete and skipped).
    pub const SUCCESS: i32 = 0;
    /// Bad arguments (also clap's usage errors).
    pub const BAD_ARGUMENTS: i32 = 2;
    /// An input is missing, unreadable or invalid (VDB, grid, merge part).
    pub const INPUT: i32 = 3;
    /// Rendering or writing an output failed, including an input that failed *while* it
    /// was in use (truncated, rewritten or replaced by another process, an I/O error of
    /// its storage; see `mapfault`): the input was valid when checked, so the failure is
    /// the run's, and the same command may succeed once the file is restored. Such an
    /// input failure ends a run of several frames at once with this code (a lost page
    /// comes as SIGBUS, which no frame can return as an error; `farm::job`).
    pub const RENDER_OR_OUTPUT: i32 = 4;
    /// Interrupted by SIGTERM/SIGINT; the image so far was written with its spp.
    pub const INTERRUPTED: i32 = 5;
    /// `--time-limit` reached; the image so far was written with its spp.
    pub const TIME_LIMIT: i32 = 6;
    /// A run of several frames in which some frames failed or stopped early (and the
    /// others were rendered; an input failing while in use is 4 instead).
    pub const FRAMES_FAILED: i32 = 7;
}

impl Error {
    /// Process exit code for this error: 2 bad arguments, 3 input missing/unreadable/
    /// invalid, 4 render or output failure (an input failing while in use included),
    /// 5 interrupted, 6 time limit, 7 some frames failed (see [`exit`]).
    #[must_use]
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::InvalidArgument { .. } | Error::SceneFile { .. } => 2,
            Error::Open { .. }
            | Error::Vdb { .. }
            | Error::GridNotFound { .. }
            | Error::UnsupportedGrid { .. }
            | Error::TooLarge { .. }
            | Error::ReaderFailed { .. }
            | Error::Cache { .. }
            | Error::InvalidInput { .. }
            | Error::Scene(_) => 3,
            Error::Write { .. }
            | Error::ReaderSpawn { .. }
            | Error::InputFailed { .. }
            | Error::CacheLocked { .. } => exit::RENDER_OR_OUTPUT,
            Error::InvalidPart { .. } => exit::INPUT,
            Error::Interrupted { .. } => exit::INTERRUPTED,
            Error::TimeLimit { .. } => exit::TIME_LIMIT,
            Error::FramesFailed { .. } => exit::FRAMES_FAILED,
        }
    }

    /// Shorthand for [`Error::InvalidArgument`].
    pub fn invalid(flag: &str, message: impl Into<String>) -> Error {
        Error::InvalidArgument { flag: flag.to_string(), message: message.into() }
    }
}

/// " while reading grid \"density\"", or " while listing grids" for `plume info`.
fn reading_context(grid: &Option<String>) -> String {
    match grid {
        Some(selector) => format!(" while reading grid {selector:?}"),
        None => " while listing grids".to_string(),
    }
}

fn format_list(items: &[String]) -> String {
    if items.is_empty() {
        "none".to_string()
    } else {
        items.join(", ")
    }
}

/// Comma-separated frame numbers (at most 20 shown).
fn format_frames(frames: &[i64]) -> String {
    let mut parts: Vec<String> = frames.iter().take(20).map(i64::to_string).collect();
    if frames.len() > 20 {
        parts.push(format!("… ({} more)", frames.len() - 20));
    }
    parts.join(", ")
}
