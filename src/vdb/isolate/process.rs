//! One reader process: `plume __read-grids …` spawned under its resource limits (set
//! between fork and exec), its stdout and stderr polled under the wall-clock deadline, and
//! its exit status, signal or stderr turned into [`Error::ReaderFailed`].

use std::ffi::OsString;
use std::io::{self, BufReader, Read};
use std::os::fd::AsRawFd;
use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::path::Path;
use std::process::{Child, ChildStderr, ChildStdout, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use super::{malformed_reply, IsolationLimits, ReaderCommand, READER_SUBCOMMAND};
use crate::vdb::wire::{ChildError, Decoder, WireError};
use plume_core::error::{Error, Result};

/// Bytes of the child's stderr kept for error messages.
const STDERR_TAIL_BYTES: usize = 8 * 1024;

/// One running reader process and its pipes.
pub(in crate::vdb) struct ReaderRun {
    child: Child,
    pipes: BufReader<ChildPipes>,
    /// Set when the parent killed the child because its deadline passed.
    timed_out: bool,
}

/// A reply parsed to the end (or a clean failure), or why it could not be.
pub(in crate::vdb) type Parsed<T> =
    std::result::Result<std::result::Result<T, ChildError>, WireError>;

impl ReaderRun {
    pub(in crate::vdb) fn spawn(
        reader: &ReaderCommand,
        args: &[OsString],
        limits: &IsolationLimits,
    ) -> Result<ReaderRun> {
        let deadline = Instant::now() + limits.timeout;
        let mut command = Command::new(&reader.exe);
        command
            .args(&reader.prefix)
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
            .map_err(|source| Error::ReaderSpawn { exe: reader.exe.clone(), source })?;
        let (stdout, stderr) = match (child.stdout.take(), child.stderr.take()) {
            (Some(stdout), Some(stderr)) => (stdout, stderr),
            _ => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(Error::ReaderSpawn {
                    exe: reader.exe.clone(),
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
    pub(in crate::vdb) fn parse<T>(
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
    pub(in crate::vdb) fn finish<T>(
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
                "reader did not finish within {} s (reading.read_timeout); killed",
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

/// Buffer size asked for the reply pipe (the default `pipe-max-size` allows 1 MiB).
const PIPE_BYTES: libc::c_int = 1 << 20;

/// The child's stdout (the reply) and stderr (kept for messages), read under one deadline.
pub(in crate::vdb) struct ChildPipes {
    stdout: ChildStdout,
    /// `None` once it reached end of file.
    stderr: Option<ChildStderr>,
    stderr_tail: Vec<u8>,
    deadline: Instant,
}

impl ChildPipes {
    /// Moves the deadline later by `by`: a streaming parent does not count the time its
    /// visitor takes against the reader.
    pub(in crate::vdb) fn extend_deadline(&mut self, by: Duration) {
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
