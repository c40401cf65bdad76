//! Reading untrusted VDB files in a child process, so that no file can crash, hang or
//! exhaust plume.
//!
//! OpenVDB 10.0.1 segfaults on about 5% and hangs on about 1% of randomly mutated copies of
//! real files (issue 7). No amount of checking in the shim makes a C++ parser of that size
//! safe, so plume runs it where a crash cannot hurt: `plume __read-grids …`, a hidden
//! subcommand of the same binary, started with
//!
//! - `RLIMIT_DATA` = [`IsolationLimits::memory_bytes`]: an allocation sized by a lying
//!   header fails (`std::bad_alloc` → a clean "out of memory" reply, or an abort);
//! - `RLIMIT_CPU` = [`IsolationLimits::cpu_seconds`], `RLIMIT_CORE` = 0, no core dumps
//!   (`PR_SET_DUMPABLE` 0), `PR_SET_PDEATHSIG` so that it dies with its parent, and
//!   `oom_score_adj` 1000 so that the kernel's OOM killer takes it first;
//! - a wall-clock deadline ([`IsolationLimits::timeout`]) enforced by the parent, which
//!   `poll`s the pipes and kills the child when it passes.
//!
//! The child streams the grids back over its stdout in the format of `wire.rs` (magic,
//! version, then one record per grid with bulk `f32` data); the parent parses it
//! defensively, with every length checked before anything is sized from it. A `BEGIN`
//! record is flushed before each grid is read, so a crash names the grid. Every failure
//! becomes [`Error::ReaderFailed`], one line, exit code 3.
//!
//! In-process reading ([`super::read_grids`], [`super::list_grids`]) stays available for
//! trusted files and for library callers; [`ReadIsolation`] chooses.
//!
//! # Child command line
//!
//! ```text
//! plume __read-grids list FILE
//! plume __read-grids read FILE MAX_BYTES (need|want) N SEL_1 … SEL_N  [(need|want) N …]
//! plume __read-grids stream FILE MAX_BYTES SEL
//! ```
//!
//! `need` is a required [`GridRequest`], `want` an optional one; `MAX_BYTES` is
//! [`ReadLimits::max_bytes`]; `stream` sends one grid batch by batch of leaves
//! ([`super::stream_float_grid_isolated`]). The command can be run by hand to replay a
//! failure (the reply is binary: pipe it into `xxd`).

use std::ffi::OsString;
use std::io::{self, BufReader, BufWriter, Read, Write};
use std::os::fd::{AsFd, AsRawFd};
use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStderr, ChildStdout, Command, ExitStatus, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use super::read::{check_file, plan_requests};
use super::stream::serve_stream;
use super::wire::{ChildError, Decoder, Encoder, Record, WireError};
use super::{list_grids, read_float_grid, FloatGrid, FoundGrid, GridInfo, GridRequest};
use super::{read_grids, GridSelector, ReadLimits};
use crate::error::{Error, Result};

/// The hidden subcommand (`argv[1]`) that runs the reader; `main.rs` dispatches on it
/// before parsing the command line.
pub const READER_SUBCOMMAND: &str = "__read-grids";

/// Default wall-clock limit of one isolated read (`--read-timeout`).
pub const DEFAULT_TIMEOUT: Duration = Duration::from_secs(120);

/// Memory the reader process needs beyond the grids themselves: code, libraries, OpenVDB's
/// registries, stacks and pipe buffers (it peaks at about 30 MB on an empty read).
pub const BASE_MEMORY_BYTES: u64 = 256 << 20;

/// Bytes of the child's stderr kept for error messages.
const STDERR_TAIL_BYTES: usize = 8 * 1024;

/// Resource limits of the reader process.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct IsolationLimits {
    /// `RLIMIT_DATA` of the child, bytes (heap and private writable mappings).
    pub memory_bytes: u64,
    /// `RLIMIT_CPU` of the child, seconds (SIGXCPU, then SIGKILL a second later).
    pub cpu_seconds: u64,
    /// Wall-clock limit from spawn to exit; the parent kills the child when it passes.
    pub timeout: Duration,
}

impl IsolationLimits {
    /// Limits for reads under `read_limits`: memory `2 × max_bytes + 256 MiB` (OpenVDB's
    /// tree plus the voxelized copy of one grid; grids are sent and freed one at a time),
    /// CPU time equal to `timeout`.
    #[must_use]
    pub fn new(read_limits: &ReadLimits, timeout: Duration) -> IsolationLimits {
        IsolationLimits {
            memory_bytes: read_limits.max_bytes.saturating_mul(2).saturating_add(BASE_MEMORY_BYTES),
            cpu_seconds: timeout.as_secs_f64().ceil().max(1.0) as u64,
            timeout,
        }
    }
}

/// The executable registered by [`set_reader_exe`].
static READER_EXE: OnceLock<PathBuf> = OnceLock::new();

/// Registers the executable that serves [`READER_SUBCOMMAND`]; the `plume` binary
/// registers itself at start-up. Only the first call has an effect.
pub fn set_reader_exe(exe: PathBuf) {
    let _ = READER_EXE.set(exe);
}

/// The executable registered by [`set_reader_exe`], if any.
#[must_use]
pub fn reader_exe() -> Option<&'static Path> {
    READER_EXE.get().map(PathBuf::as_path)
}

/// Where VDB files are read.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ReadIsolation {
    /// In this process: fastest, but a malformed file can crash or hang plume.
    InProcess,
    /// In a child process of `reader_exe` (the `plume` binary) under `limits`.
    Child {
        /// Executable that serves [`READER_SUBCOMMAND`].
        reader_exe: PathBuf,
        /// Limits of the child.
        limits: IsolationLimits,
    },
}

impl ReadIsolation {
    /// The CLI's choice: a child of the registered executable unless `no_isolation`.
    /// Without a registered executable (a library caller that has not called
    /// [`set_reader_exe`]) reading stays in-process.
    #[must_use]
    pub fn from_flags(
        no_isolation: bool,
        read_limits: &ReadLimits,
        timeout: Duration,
    ) -> ReadIsolation {
        match reader_exe() {
            Some(exe) if !no_isolation => ReadIsolation::Child {
                reader_exe: exe.to_path_buf(),
                limits: IsolationLimits::new(read_limits, timeout),
            },
            _ => ReadIsolation::InProcess,
        }
    }

    /// [`super::list_grids`], here or in the child.
    ///
    /// # Errors
    /// As [`super::list_grids`], plus [`Error::ReaderFailed`] and [`Error::ReaderSpawn`].
    pub fn list_grids(&self, path: &Path) -> Result<Vec<GridInfo>> {
        match self {
            ReadIsolation::InProcess => list_grids(path),
            ReadIsolation::Child { reader_exe, limits } => {
                list_grids_isolated(reader_exe, path, limits)
            }
        }
    }

    /// [`super::read_grids`], here or in the child.
    ///
    /// # Errors
    /// As [`super::read_grids`], plus [`Error::ReaderFailed`] and [`Error::ReaderSpawn`].
    pub fn read_grids(
        &self,
        path: &Path,
        requests: &[GridRequest],
        read_limits: &ReadLimits,
    ) -> Result<Vec<Option<FoundGrid>>> {
        match self {
            ReadIsolation::InProcess => read_grids(path, requests, read_limits),
            ReadIsolation::Child { reader_exe, limits } => {
                read_grids_isolated(reader_exe, path, requests, read_limits, limits)
            }
        }
    }
}

/// Reads the grids named by `selectors` (all required) in one child process of
/// `reader_exe`.
///
/// # Errors
/// As [`super::read_float_grid`]; [`Error::ReaderFailed`] when the child crashes, hangs,
/// exceeds a limit or replies with garbage; [`Error::ReaderSpawn`] when it cannot start.
pub fn read_float_grids_isolated(
    reader_exe: &Path,
    path: &Path,
    selectors: &[GridSelector],
    read_limits: &ReadLimits,
    limits: &IsolationLimits,
) -> Result<Vec<FloatGrid>> {
    let requests: Vec<GridRequest> = selectors.iter().cloned().map(GridRequest::required).collect();
    let found = read_grids_isolated(reader_exe, path, &requests, read_limits, limits)?;
    Ok(found
        .into_iter()
        .map(|f| {
            f.expect("invariant: the reply parser accepts ABSENT only for optional requests").grid
        })
        .collect())
}

/// [`super::read_grids`] in one child process of `reader_exe`.
///
/// # Errors
/// As [`read_float_grids_isolated`].
pub fn read_grids_isolated(
    reader_exe: &Path,
    path: &Path,
    requests: &[GridRequest],
    read_limits: &ReadLimits,
    limits: &IsolationLimits,
) -> Result<Vec<Option<FoundGrid>>> {
    // Missing files, directories, NanoVDB and non-VDB files are refused here, by Rust code
    check_file(path)?;
    let mut args: Vec<OsString> =
        vec!["read".into(), path.into(), read_limits.max_bytes.to_string().into()];
    for request in requests {
        if request.alternatives.is_empty() {
            return Err(Error::invalid("grid request", "no grid selector given"));
        }
        args.push(if request.required { "need" } else { "want" }.into());
        args.push(request.alternatives.len().to_string().into());
        args.extend(request.alternatives.iter().map(|a| OsString::from(a.to_string())));
    }
    let mut run = ReaderRun::spawn(reader_exe, &args, limits)?;
    let mut grid: Option<String> = None;
    let outcome =
        run.parse(read_limits.max_bytes, |decoder| parse_read_reply(decoder, requests, &mut grid));
    run.finish(path, outcome, grid.clone(), limits)?.map_err(|e| child_error(path, e, grid, limits))
}

/// [`super::list_grids`] in a child process of `reader_exe`.
///
/// # Errors
/// As [`read_float_grids_isolated`].
pub fn list_grids_isolated(
    reader_exe: &Path,
    path: &Path,
    limits: &IsolationLimits,
) -> Result<Vec<GridInfo>> {
    check_file(path)?;
    let args: Vec<OsString> = vec!["list".into(), path.into()];
    let mut run = ReaderRun::spawn(reader_exe, &args, limits)?;
    // Listing moves no bulk data
    let outcome = run.parse(0, |decoder| {
        let reply = match decoder.next()? {
            Record::Infos(infos) => Ok(infos),
            Record::Failed(e) => Err(e),
            other => return Err(unexpected(&other)),
        };
        match decoder.next()? {
            Record::End => Ok(reply),
            other => Err(unexpected(&other)),
        }
    });
    run.finish(path, outcome, None, limits)?.map_err(|e| child_error(path, e, None, limits))
}

/// The records of a `read` reply, checked against the requests: each request is answered
/// in order, by BEGIN + GRID for the alternative announced, or by ABSENT if optional.
/// `grid` tracks the selector being read, for crash messages.
fn parse_read_reply<R: Read>(
    decoder: &mut Decoder<R>,
    requests: &[GridRequest],
    grid: &mut Option<String>,
) -> std::result::Result<std::result::Result<Vec<Option<FoundGrid>>, ChildError>, WireError> {
    let mut found: Vec<Option<FoundGrid>> = Vec::with_capacity(requests.len());
    let mut begun: Option<(usize, usize)> = None;
    loop {
        let next = requests.get(found.len());
        match decoder.next()? {
            Record::Begin { request, alternative } => {
                let (request, alternative) = (request as usize, alternative as usize);
                match next {
                    Some(r) if request == found.len() && alternative < r.alternatives.len() => {
                        *grid = Some(r.alternatives[alternative].to_string());
                        begun = Some((request, alternative));
                    }
                    _ => return Err(malformed_reply("BEGIN out of order")),
                }
            }
            Record::Grid { request, alternative, grid: g } => {
                let (request, alternative) = (request as usize, alternative as usize);
                if begun != Some((request, alternative))
                    || !next.is_some_and(|r| r.alternatives[alternative].name == g.name)
                {
                    return Err(malformed_reply("GRID does not answer the grid begun"));
                }
                found.push(Some(FoundGrid { alternative, grid: g }));
                begun = None;
                *grid = None;
            }
            Record::Absent { request } => match next {
                Some(r) if request as usize == found.len() && !r.required && begun.is_none() => {
                    found.push(None);
                }
                _ => return Err(malformed_reply("ABSENT out of order")),
            },
            Record::Failed(e) => {
                return match decoder.next()? {
                    Record::End => Ok(Err(e)),
                    other => Err(unexpected(&other)),
                };
            }
            Record::End if found.len() == requests.len() => return Ok(Ok(found)),
            other => return Err(unexpected(&other)),
        }
    }
}

pub(super) fn malformed_reply(message: &str) -> WireError {
    WireError::Malformed(message.to_string())
}

pub(super) fn unexpected(record: &Record) -> WireError {
    let name = match record {
        Record::Begin { .. } => "BEGIN",
        Record::Grid { .. } => "GRID",
        Record::Absent { .. } => "ABSENT",
        Record::Infos(_) => "INFOS",
        Record::Failed(_) => "FAILED",
        Record::End => "END",
        Record::Stream(_) => "STREAM",
        Record::Leaves => "LEAVES",
        Record::Tiles => "TILES",
    };
    WireError::Malformed(format!("unexpected {name} record"))
}

/// The error the child reported cleanly, as the in-process reader would have returned it.
pub(super) fn child_error(
    path: &Path,
    error: ChildError,
    grid: Option<String>,
    limits: &IsolationLimits,
) -> Error {
    let path = path.to_path_buf();
    match error {
        ChildError::Open { message } => Error::Open { path, source: io::Error::other(message) },
        ChildError::Vdb { message } => Error::Vdb { path, message },
        ChildError::GridNotFound { name, available } => {
            Error::GridNotFound { path, name, available }
        }
        ChildError::Unsupported { grid, message } => Error::UnsupportedGrid { path, grid, message },
        ChildError::TooLarge { grid, needed, limit } => {
            Error::TooLarge { path, grid, needed, limit }
        }
        ChildError::OutOfMemory => Error::ReaderFailed {
            path,
            grid,
            what: format!("reader ran out of memory at its limit of {} bytes", limits.memory_bytes),
        },
    }
}

/// One running reader process and its pipes.
pub(super) struct ReaderRun {
    child: Child,
    pipes: BufReader<ChildPipes>,
    /// Set when the parent killed the child because its deadline passed.
    timed_out: bool,
}

/// A reply parsed to the end (or a clean failure), or why it could not be.
pub(super) type Parsed<T> = std::result::Result<std::result::Result<T, ChildError>, WireError>;

impl ReaderRun {
    pub(super) fn spawn(
        exe: &Path,
        args: &[OsString],
        limits: &IsolationLimits,
    ) -> Result<ReaderRun> {
        let deadline = Instant::now() + limits.timeout;
        let mut command = Command::new(exe);
        command
            .arg(READER_SUBCOMMAND)
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        let (memory, cpu) = (limits.memory_bytes, limits.cpu_seconds);
        // SAFETY: the closure runs in the forked child before exec. It makes only
        // async-signal-safe system calls (setrlimit, prctl) on values copied into it; it
        // allocates nothing and takes no lock, so it cannot deadlock on state another
        // thread of the parent held at fork time.
        unsafe {
            command.pre_exec(move || limit_this_process(memory, cpu));
        }
        let mut child = command
            .spawn()
            .map_err(|source| Error::ReaderSpawn { exe: exe.to_path_buf(), source })?;
        let (stdout, stderr) = match (child.stdout.take(), child.stderr.take()) {
            (Some(stdout), Some(stderr)) => (stdout, stderr),
            _ => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(Error::ReaderSpawn {
                    exe: exe.to_path_buf(),
                    source: io::Error::other("no pipes to the child"),
                });
            }
        };
        // A larger pipe lets the child decode the next batch while the parent consumes
        // this one (the default 64 KiB holds an eighth of a leaf batch). Best effort.
        // SAFETY: fcntl on a pipe descriptor we own; F_SETPIPE_SZ only resizes its buffer.
        unsafe {
            libc::fcntl(std::os::fd::AsRawFd::as_raw_fd(&stdout), libc::F_SETPIPE_SZ, PIPE_BYTES);
        }
        let pipes = ChildPipes { stdout, stderr: Some(stderr), stderr_tail: Vec::new(), deadline };
        Ok(ReaderRun { child, pipes: BufReader::with_capacity(1 << 20, pipes), timed_out: false })
    }

    /// Runs `body` on the reply.
    pub(super) fn parse<T>(
        &mut self,
        max_grid_bytes: u64,
        body: impl FnOnce(&mut Decoder<&mut BufReader<ChildPipes>>) -> Parsed<T>,
    ) -> Parsed<T> {
        let mut decoder = Decoder::new(&mut self.pipes, max_grid_bytes)?;
        let parsed = body(&mut decoder)?;
        // Nothing may follow END
        let mut byte = [0u8; 1];
        match decoder.input().read(&mut byte)? {
            0 => Ok(parsed),
            _ => Err(malformed_reply("bytes after END")),
        }
    }

    /// Waits for the child (killing it if the reply was bad or the deadline passes) and
    /// turns the exit status and parse outcome into the result. A child that dies by a
    /// signal or exits non-zero fails the read even after a complete reply: its memory
    /// may have been corrupt while it wrote.
    pub(super) fn finish<T>(
        mut self,
        path: &Path,
        outcome: Parsed<T>,
        grid: Option<String>,
        limits: &IsolationLimits,
    ) -> Result<std::result::Result<T, ChildError>> {
        // The reply stopped short (EOF) or was complete: the child is exiting by itself.
        // Otherwise (garbage, a pipe error, the deadline) it is stopped now.
        let killed_for = match &outcome {
            Ok(_) => None,
            Err(WireError::Io(e)) if e.kind() == io::ErrorKind::UnexpectedEof => None,
            Err(WireError::Io(e)) if e.kind() == io::ErrorKind::TimedOut => {
                self.timed_out = true;
                None
            }
            Err(WireError::Io(e)) => Some(format!("reading the reader's reply failed: {e}")),
            Err(WireError::Malformed(m)) => Some(format!("reader sent a malformed reply ({m})")),
        };
        if self.timed_out || killed_for.is_some() {
            let _ = self.child.kill();
        }
        let status = self.wait();
        let stderr = self.pipes.get_ref().stderr_excerpt();
        let failed = |what: String| Error::ReaderFailed {
            path: path.to_path_buf(),
            grid: grid.clone(),
            what: with_stderr(what, &stderr),
        };
        if self.timed_out {
            return Err(failed(format!(
                "reader did not finish within {} s (--read-timeout); killed",
                limits.timeout.as_secs_f64()
            )));
        }
        if let Some(what) = killed_for {
            return Err(failed(format!("{what}; killed")));
        }
        let status = status.map_err(|e| failed(format!("cannot wait for the reader: {e}")))?;
        // Rust's allocation failure message, C++'s uncaught std::bad_alloc
        let out_of_memory = stderr.contains("memory allocation of") || stderr.contains("bad_alloc");
        let out_of_memory_message =
            || format!("reader ran out of memory at its limit of {} bytes", limits.memory_bytes);
        if let Some(signal) = status.signal() {
            let what = match signal {
                libc::SIGXCPU => {
                    format!(
                        "reader exceeded its CPU time limit of {} s; killed",
                        limits.cpu_seconds
                    )
                }
                _ if out_of_memory => {
                    format!("{} ({})", out_of_memory_message(), signal_name(signal))
                }
                libc::SIGKILL => {
                    "reader was killed with SIGKILL (by the system's out-of-memory killer?)".into()
                }
                _ => format!("reader crashed with {}", signal_name(signal)),
            };
            return Err(failed(what));
        }
        match (status.code(), outcome) {
            (Some(0), Ok(reply)) => Ok(reply),
            (Some(0), Err(_)) => Err(failed("reader exited before finishing its reply".into())),
            (code, _) => Err(failed(if out_of_memory {
                out_of_memory_message()
            } else {
                let code = code.map_or_else(|| "unknown".to_string(), |c| c.to_string());
                format!("reader exited with status {code}")
            })),
        }
    }

    /// Collects the exit status, draining stderr meanwhile (so that the child cannot block
    /// on a full pipe), and kills the child if the deadline passes first. Does not wait
    /// for stderr to close: a grandchild could hold it open.
    fn wait(&mut self) -> io::Result<ExitStatus> {
        loop {
            if let Some(status) = self.child.try_wait()? {
                self.pipes.get_mut().drain_stderr();
                return Ok(status);
            }
            match self.pipes.get_ref().remaining_ms() {
                Ok(ms) => {
                    self.pipes.get_mut().poll_once(false, ms.min(10))?;
                }
                Err(_) => {
                    self.timed_out = true;
                    let _ = self.child.kill();
                    let status = self.child.wait();
                    self.pipes.get_mut().drain_stderr();
                    return status;
                }
            }
        }
    }
}

/// The child's stdout (the reply) and stderr (kept for messages), read under one deadline.
/// Buffer size asked for the reply pipe (the default `pipe-max-size` allows 1 MiB).
const PIPE_BYTES: libc::c_int = 1 << 20;

pub(super) struct ChildPipes {
    stdout: ChildStdout,
    /// `None` once it reached end of file.
    stderr: Option<ChildStderr>,
    stderr_tail: Vec<u8>,
    deadline: Instant,
}

impl ChildPipes {
    /// Moves the deadline later by `by`: a streaming parent does not count the time its
    /// visitor takes against the reader.
    pub(super) fn extend_deadline(&mut self, by: Duration) {
        self.deadline += by;
    }

    /// Milliseconds left, or `TimedOut`.
    fn remaining_ms(&self) -> io::Result<i32> {
        let left = self.deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Err(io::Error::new(io::ErrorKind::TimedOut, "reader deadline passed"));
        }
        Ok(i32::try_from(left.as_millis().max(1)).unwrap_or(i32::MAX))
    }

    /// Waits up to `timeout_ms` for stdout (if `want_stdout`) or stderr to be readable or
    /// closed, and reads what stderr has. Returns whether stdout is ready.
    fn poll_once(&mut self, want_stdout: bool, timeout_ms: i32) -> io::Result<bool> {
        let stderr_fd = self.stderr.as_ref().map_or(-1, AsRawFd::as_raw_fd);
        let stdout_fd = if want_stdout { self.stdout.as_raw_fd() } else { -1 };
        let mut fds = [
            libc::pollfd { fd: stdout_fd, events: libc::POLLIN, revents: 0 },
            libc::pollfd { fd: stderr_fd, events: libc::POLLIN, revents: 0 },
        ];
        // SAFETY: `fds` is a valid array of two pollfd structs for the duration of the
        // call; poll ignores entries with a negative fd.
        let ready = unsafe { libc::poll(fds.as_mut_ptr(), 2, timeout_ms) };
        if ready < 0 {
            let e = io::Error::last_os_error();
            return if e.kind() == io::ErrorKind::Interrupted { Ok(false) } else { Err(e) };
        }
        if fds[1].revents != 0 {
            self.read_stderr();
        }
        Ok(fds[0].revents != 0)
    }

    /// Reads what stderr holds without waiting (after the child exited), at most 256 KiB.
    fn drain_stderr(&mut self) {
        for _ in 0..64 {
            let Some(fd) = self.stderr.as_ref().map(AsRawFd::as_raw_fd) else { return };
            let mut pollfd = libc::pollfd { fd, events: libc::POLLIN, revents: 0 };
            // SAFETY: one valid pollfd for the duration of the call; timeout 0 never blocks.
            if unsafe { libc::poll(&mut pollfd, 1, 0) } <= 0 {
                return;
            }
            self.read_stderr();
        }
    }

    fn read_stderr(&mut self) {
        let Some(stderr) = &mut self.stderr else { return };
        let mut buf = [0u8; 4096];
        match stderr.read(&mut buf) {
            Ok(0) | Err(_) => self.stderr = None,
            Ok(n) => {
                self.stderr_tail.extend_from_slice(&buf[..n]);
                if self.stderr_tail.len() > 2 * STDERR_TAIL_BYTES {
                    let cut = self.stderr_tail.len() - STDERR_TAIL_BYTES;
                    self.stderr_tail.drain(..cut);
                }
            }
        }
    }

    /// The last non-empty line of the child's stderr, printable, at most 200 characters.
    fn stderr_excerpt(&self) -> String {
        let text = String::from_utf8_lossy(&self.stderr_tail);
        let line = text.lines().rev().map(str::trim).find(|l| !l.is_empty()).unwrap_or("");
        line.chars().filter(|c| !c.is_control()).take(200).collect()
    }
}

impl Read for ChildPipes {
    /// Reads the reply, failing with `TimedOut` once the deadline has passed.
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        loop {
            let timeout = self.remaining_ms()?;
            if self.poll_once(true, timeout)? {
                return self.stdout.read(buf);
            }
        }
    }
}

/// Appends the child's last stderr line, if any, to a message.
fn with_stderr(what: String, stderr: &str) -> String {
    if stderr.is_empty() {
        what
    } else {
        format!("{what} (reader said: {stderr})")
    }
}

fn signal_name(signal: i32) -> String {
    let name = match signal {
        libc::SIGSEGV => "SIGSEGV",
        libc::SIGBUS => "SIGBUS",
        libc::SIGABRT => "SIGABRT",
        libc::SIGFPE => "SIGFPE",
        libc::SIGILL => "SIGILL",
        libc::SIGKILL => "SIGKILL",
        libc::SIGTERM => "SIGTERM",
        libc::SIGINT => "SIGINT",
        libc::SIGXCPU => "SIGXCPU",
        libc::SIGXFSZ => "SIGXFSZ",
        libc::SIGTRAP => "SIGTRAP",
        libc::SIGSYS => "SIGSYS",
        libc::SIGPIPE => "SIGPIPE",
        _ => return format!("signal {signal}"),
    };
    name.to_string()
}

/// Applied in the child between fork and exec (see [`ReaderRun::spawn`]).
fn limit_this_process(memory_bytes: u64, cpu_seconds: u64) -> io::Result<()> {
    let set = |resource, soft: u64, hard: u64| {
        let limit = libc::rlimit { rlim_cur: soft as libc::rlim_t, rlim_max: hard as libc::rlim_t };
        // SAFETY: setrlimit reads the struct we pass and changes only this process.
        if unsafe { libc::setrlimit(resource, &limit) } != 0 {
            return Err(io::Error::last_os_error());
        }
        Ok(())
    };
    set(libc::RLIMIT_DATA, memory_bytes, memory_bytes)?;
    set(libc::RLIMIT_CPU, cpu_seconds, cpu_seconds.saturating_add(1))?;
    set(libc::RLIMIT_CORE, 0, 0)?;
    // SAFETY: prctl with PR_SET_PDEATHSIG takes a signal number and changes only this
    // process: it is killed when the thread that spawned it exits.
    if unsafe { libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL as libc::c_ulong, 0, 0, 0) } != 0
    {
        return Err(io::Error::last_os_error());
    }
    // First in line for the kernel's OOM killer, should the machine run short before the
    // reader reaches its own limit (best effort: /proc may be missing).
    // SAFETY: open/write/close on a static NUL-terminated path and a static buffer;
    // raising one's own oom_score_adj needs no privilege.
    unsafe {
        let fd = libc::open(c"/proc/self/oom_score_adj".as_ptr(), libc::O_WRONLY | libc::O_CLOEXEC);
        if fd >= 0 {
            libc::write(fd, b"1000".as_ptr().cast(), 4);
            libc::close(fd);
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------
// The child

/// Runs the reader subcommand (the arguments after [`READER_SUBCOMMAND`]) and ends the
/// process: exit status 0 after a complete reply (which may report a clean failure), 1
/// when the reply cannot be written, 2 on a malformed command line.
///
/// The process ends with `_exit`, skipping C++ static destructors: after a read of a
/// hostile file the heap may be damaged, and a crash on the way out would turn a good
/// reply into a failure.
pub fn reader_main(args: &[OsString]) -> ! {
    // SAFETY: prctl(PR_SET_DUMPABLE, 0) only changes this process's dumpable flag (no core
    // dump of a crash on a hostile file). It is reset by exec, so it is set here.
    unsafe {
        libc::prctl(libc::PR_SET_DUMPABLE, 0, 0, 0, 0);
    }
    let code = match ReaderCommand::parse(args) {
        Ok(command) => match serve(&command) {
            Ok(()) => 0,
            Err(e) => {
                eprintln!("plume {READER_SUBCOMMAND}: cannot write the reply: {e}");
                1
            }
        },
        Err(message) => {
            eprintln!("plume {READER_SUBCOMMAND}: {message}");
            2
        }
    };
    let _ = io::stderr().flush();
    // SAFETY: _exit ends the process without running atexit handlers; every output
    // stream was flushed above.
    unsafe { libc::_exit(code) }
}

/// A parsed reader command line.
enum ReaderCommand {
    List { path: PathBuf },
    Read { path: PathBuf, limits: ReadLimits, requests: Vec<GridRequest> },
    Stream { path: PathBuf, limits: ReadLimits, selector: GridSelector },
}

impl ReaderCommand {
    fn parse(args: &[OsString]) -> std::result::Result<ReaderCommand, String> {
        let usage = || {
            format!(
                "usage: plume {READER_SUBCOMMAND} list FILE | read FILE MAX_BYTES (need|want) N SEL... ... \
                 | stream FILE MAX_BYTES SEL"
            )
        };
        let mut it = args.iter();
        fn text(
            arg: Option<&OsString>,
            usage: impl Fn() -> String,
        ) -> std::result::Result<&str, String> {
            arg.and_then(|a| a.to_str()).ok_or_else(usage)
        }
        let mode = text(it.next(), usage)?;
        let path = PathBuf::from(it.next().ok_or_else(usage)?);
        match mode {
            "list" if it.len() == 0 => Ok(ReaderCommand::List { path }),
            "read" => {
                let max_bytes = text(it.next(), usage)?.parse().map_err(|_| usage())?;
                let mut requests = Vec::new();
                while let Some(kind) = it.next() {
                    let required = match kind.to_str() {
                        Some("need") => true,
                        Some("want") => false,
                        _ => return Err(usage()),
                    };
                    let count: usize = text(it.next(), usage)?.parse().map_err(|_| usage())?;
                    if count == 0 || count > it.len() {
                        return Err(usage());
                    }
                    let alternatives = (0..count)
                        .map(|_| {
                            text(it.next(), usage)?
                                .parse::<GridSelector>()
                                .map_err(|e| e.to_string())
                        })
                        .collect::<std::result::Result<Vec<_>, _>>()?;
                    requests.push(GridRequest { alternatives, required });
                }
                Ok(ReaderCommand::Read { path, limits: ReadLimits { max_bytes }, requests })
            }
            "stream" if it.len() == 2 => {
                let max_bytes = text(it.next(), usage)?.parse().map_err(|_| usage())?;
                let selector = text(it.next(), usage)?.parse().map_err(|e: Error| e.to_string())?;
                Ok(ReaderCommand::Stream { path, limits: ReadLimits { max_bytes }, selector })
            }
            _ => Err(usage()),
        }
    }
}

/// Writes the reply to a duplicate of stdout, and points stdout at stderr so that nothing
/// OpenVDB might print can corrupt the reply.
fn serve(command: &ReaderCommand) -> io::Result<()> {
    let reply = std::fs::File::from(io::stdout().as_fd().try_clone_to_owned()?);
    // SAFETY: dup2 on two open descriptors of this process; fd 1 now refers to stderr.
    if unsafe { libc::dup2(libc::STDERR_FILENO, libc::STDOUT_FILENO) } < 0 {
        return Err(io::Error::last_os_error());
    }
    let mut out = Encoder::new(BufWriter::with_capacity(256 * 1024, reply))?;
    match command {
        ReaderCommand::List { path } => match list_grids(path) {
            Ok(infos) => out.infos(&infos)?,
            Err(e) => out.failed(&ChildError::from_error(&e))?,
        },
        ReaderCommand::Read { path, limits, requests } => {
            serve_read(&mut out, path, limits, requests)?;
        }
        ReaderCommand::Stream { path, limits, selector } => {
            serve_stream(&mut out, path, limits, selector)?;
        }
    }
    out.end()?;
    Ok(())
}

fn serve_read<W: Write>(
    out: &mut Encoder<W>,
    path: &Path,
    limits: &ReadLimits,
    requests: &[GridRequest],
) -> io::Result<()> {
    let plan = match plan_requests(path, requests) {
        Ok(plan) => plan,
        Err(e) => return out.failed(&ChildError::from_error(&e)),
    };
    for (index, (choice, request)) in plan.into_iter().zip(requests).enumerate() {
        let index = wire_index(index);
        let Some(alternative) = choice else {
            out.absent(index)?;
            continue;
        };
        out.begin(index, wire_index(alternative))?;
        // Each grid is sent and freed before the next is read
        match read_float_grid(path, &request.alternatives[alternative], limits) {
            Ok(grid) => out.grid(index, wire_index(alternative), &grid)?,
            Err(e) => return out.failed(&ChildError::from_error(&e)),
        }
    }
    Ok(())
}

/// Request and alternative indices come from a command line, far below `u32::MAX`.
fn wire_index(i: usize) -> u32 {
    u32::try_from(i).expect("invariant: request indices come from a command line")
}
