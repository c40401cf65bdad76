//! Files written atomically: every output plume writes goes to a temporary file beside
//! its destination (`.NAME.HOST.PID.tmp`), is synced, then renamed, so a reader never sees
//! a half-written file, even if plume is killed mid-write; a rerun removes the temporaries
//! a killed run left ([`remove_stale_temporaries`]).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
/// A temporary file that is removed when dropped (on every error path, and when a panic
/// unwinds), unless [`TemporaryFile::keep`] was called once it has been renamed into
/// place.
pub struct TemporaryFile {
    path: Option<PathBuf>,
}

impl TemporaryFile {
    /// Take charge of `path` (created or about to be).
    pub fn new(path: PathBuf) -> TemporaryFile {
        TemporaryFile { path: Some(path) }
    }

    /// The file has been renamed into place: leave it alone.
    pub fn keep(mut self) {
        self.path = None;
    }
}

impl Drop for TemporaryFile {
    fn drop(&mut self) {
        if let Some(p) = self.path.take() {
            let _ = std::fs::remove_file(p);
        }
    }
}

/// Write a file atomically: `write` fills a temporary file beside `path`, which is
/// synced and renamed over `path` only if everything succeeded.
///
/// # Errors
/// [`Error::Write`] naming `path` if the directory is not writable or writing fails (a
/// full disk included); the temporary file is removed and `path` is left as it was.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> Result<()> {
    if path.file_name().is_none() {
        return Err(Error::Write {
            path: path.to_path_buf(),
            source: std::io::Error::new(std::io::ErrorKind::InvalidInput, "not a file name"),
        });
    }
    let tmp = temporary_path(path);
    let result = (|| {
        let file = File::create(&tmp)?;
        let temporary = TemporaryFile::new(tmp.clone());
        let mut w = BufWriter::new(file);
        write(&mut w)?;
        w.flush()?;
        w.get_ref().sync_all()?;
        drop(w);
        std::fs::rename(&tmp, path)?;
        temporary.keep();
        // Make the rename itself durable (a crash of the machine, not only of plume)
        if let Ok(d) = File::open(parent_dir(path)) {
            let _ = d.sync_all();
        }
        Ok(())
    })();
    result.map_err(|source| Error::Write { path: path.to_path_buf(), source })
}

/// Append `line` and a newline to `path` (created if missing) with one `write`, so that
/// lines of processes appending to the same local file do not interleave, and a killed
/// process leaves whole lines. (On NFS, `O_APPEND` is not atomic between hosts: give
/// each task its own file, e.g. with a frame token.)
///
/// A write that fails part-way (a full disk takes what fits, then refuses the rest) is
/// undone: the file is cut back to where this line began, as long as nothing was appended
/// after it, and a file this call created is removed again. The file then holds exactly
/// its earlier lines.
///
/// # Errors
/// [`Error::Write`] naming `path`.
pub fn append_line(path: &Path, line: &str) -> Result<()> {
    use std::io::Seek as _;
    let mut text = String::with_capacity(line.len() + 1);
    text.push_str(line);
    text.push('\n');
    let fail = |source| Error::Write { path: path.to_path_buf(), source };
    let open = |new: bool| std::fs::OpenOptions::new().append(true).create_new(new).open(path);
    let (mut f, created) = match open(true) {
        Ok(f) => (f, true),
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
            (open(false).map_err(fail)?, false)
        }
        Err(e) => return Err(fail(e)),
    };
    let mut written = 0;
    let result = (|| {
        while written < text.len() {
            match f.write(&text.as_bytes()[written..]) {
                Ok(0) => return Err(std::io::Error::from(std::io::ErrorKind::WriteZero)),
                Ok(n) => written += n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        f.sync_data()
    })();
    if let Err(e) = result {
        // With O_APPEND the offset is the end of this process's last write
        let end = f.stream_position().ok();
        let start = end.and_then(|end| end.checked_sub(written as u64));
        let len = f.metadata().map(|m| m.len()).ok();
        if let Some(start) = start.filter(|_| written > 0 && end == len) {
            let _ = f.set_len(start);
        }
        if created && f.metadata().is_ok_and(|m| m.len() == 0) {
            let _ = std::fs::remove_file(path);
        }
        return Err(fail(e));
    }
    Ok(())
}

/// Check, before any expensive work, that `path` can be written: its directory exists and
/// accepts a new file. Creates and removes a probe file named like the temporaries, so a
/// probe left by a killed process is cleaned up by [`remove_stale_temporaries`].
///
/// # Errors
/// [`Error::Write`] naming `path`.
pub fn check_writable(path: &Path) -> Result<()> {
    let probe = temporary_path(path);
    File::create(&probe)
        .and_then(|_| std::fs::remove_file(&probe))
        .map_err(|source| Error::Write { path: path.to_path_buf(), source })
}

/// Remove temporary files that an earlier, killed plume on this host left beside `path`
/// (`.NAME.HOST.PID.tmp` whose process no longer exists). Best effort: errors are
/// ignored, files of live processes and of other hosts are kept.
pub fn remove_stale_temporaries(path: &Path) {
    let (Some(name), dir) = (path.file_name(), parent_dir(path)) else { return };
    let prefix = format!(".{}.{}.", name.to_string_lossy(), temporary_host());
    let Ok(entries) = std::fs::read_dir(&dir) else { return };
    for e in entries.flatten() {
        let file = e.file_name().to_string_lossy().into_owned();
        let Some(pid) = file.strip_prefix(&prefix).and_then(|r| r.strip_suffix(".tmp")) else {
            continue;
        };
        let Ok(pid) = pid.parse::<i32>() else { continue };
        if pid != std::process::id() as i32 && !process_alive(pid) {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

fn process_alive(pid: i32) -> bool {
    // SAFETY: kill with signal 0 sends nothing; it only checks that the process exists.
    let r = unsafe { libc::kill(pid, 0) };
    r == 0 || std::io::Error::last_os_error().raw_os_error() != Some(libc::ESRCH)
}

/// This machine's host name ("unknown" if it cannot be read).
#[must_use]
pub fn host_name() -> String {
    let mut buf = [0u8; 256];
    // SAFETY: gethostname writes at most buf.len() bytes into buf.
    let r = unsafe { libc::gethostname(buf.as_mut_ptr().cast(), buf.len()) };
    if r != 0 {
        return "unknown".into();
    }
    let end = buf.iter().position(|&b| b == 0).unwrap_or(buf.len());
    let h = String::from_utf8_lossy(&buf[..end]).into_owned();
    if h.is_empty() {
        "unknown".into()
    } else {
        h
    }
}

/// The temporary file beside `path`: `.NAME.HOST.PID.tmp`. Named after host and
/// process, so that a rerun can tell a killed run's leftovers from files being written
/// right now ([`remove_stale_temporaries`]).
pub fn temporary_path(path: &Path) -> PathBuf {
    let name = path.file_name().map_or_else(|| "out".into(), |n| n.to_string_lossy().into_owned());
    parent_dir(path).join(format!(".{name}.{}.{}.tmp", temporary_host(), std::process::id()))
}

/// The host name as used in temporary file names (no dots or slashes).
fn temporary_host() -> String {
    host_name().replace(['/', '.'], "_")
}

/// The directory `path` is in (`.` for a bare file name).
#[must_use]
pub fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}
