//! The advisory lock (`flock`) on `.NAME.lock` beside the automatic cache `NAME`, held
//! while a process converts, so that other processes making the same cache (farm nodes
//! sharing a cache directory) wait and then use it instead of converting again, and held
//! while a process removes a cache it found damaged, so that it removes only the file it
//! checked, never a new one that a converter renamed over it meanwhile
//! ([`super::CacheCheck::verified`]).
//!
//! The kernel releases the lock when the [`CacheLock`] is dropped or the process dies. The
//! lock file is left in place: removing it would let a process still waiting on the old
//! file and one opening a new file both hold "the" lock.
//!
//! **Bounded wait.** A holder that hangs (a node whose storage stopped answering, a process
//! stopped by a debugger) would otherwise keep every waiter waiting forever. A waiter polls
//! with `LOCK_NB`, sleeping `FIRST_SLEEP` doubling to `LONGEST_SLEEP` between tries (and
//! checking for SIGTERM/SIGINT each time), and gives up after its timeout
//! ([`Acquired::TimedOut`]); what to do then is the caller's decision.
//!
//! Where locks are not available (`flock` refused, e.g. an NFS mount with `nolock`, or a
//! directory where the lock file cannot be created) the caller goes on without one:
//! correctness never depends on it (each converter writes its own temporary and renames a
//! complete file), only duplicate work does.

use std::fs::File;
use std::os::fd::AsRawFd;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use plume_core::error::{Error, Result};

/// The first pause between two tries.
const FIRST_SLEEP: Duration = Duration::from_millis(10);
/// The longest pause between two tries (also how late a stop signal is noticed).
const LONGEST_SLEEP: Duration = Duration::from_millis(500);

/// A held lock (or none, where the file system refuses locks). Released when dropped.
#[derive(Debug)]
pub struct CacheLock {
    file: Option<File>,
}

/// What waiting for the lock gave.
#[derive(Debug)]
pub enum Acquired {
    /// The lock is held until this is dropped.
    Locked(CacheLock),
    /// Another process held it for the whole timeout.
    TimedOut {
        /// The lock file.
        lock: PathBuf,
        /// How long this process waited.
        waited: Duration,
    },
}

/// The lock file of the cache `cache`: `.NAME.lock` beside it.
#[must_use]
pub fn lock_path(cache: &Path) -> PathBuf {
    let name =
        cache.file_name().map_or_else(|| "cache".into(), |n| n.to_string_lossy().into_owned());
    plume_core::fs::parent_dir(cache).join(format!(".{name}.lock"))
}

impl CacheLock {
    /// True when a lock is really held (false where the file system refused it).
    #[must_use]
    pub fn is_held(&self) -> bool {
        self.file.is_some()
    }

    /// Lock the cache `cache`, waiting at most `timeout` for another holder. `waiting`,
    /// when given, is logged (`log::info!`) once, when the lock is found taken. Without
    /// locks (see the module docs) a warning is logged and an unheld lock returned.
    ///
    /// # Errors
    /// [`Error::Interrupted`] when SIGTERM or SIGINT arrives while waiting.
    pub fn acquire(cache: &Path, timeout: Duration, waiting: Option<&str>) -> Result<Acquired> {
        let lock_path = lock_path(cache);
        let unlocked = |e: std::io::Error| {
            log::warn!(
                "cannot lock {} ({e}); going on without waiting for other processes",
                lock_path.display()
            );
            Ok(Acquired::Locked(CacheLock { file: None }))
        };
        let file = match File::options()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&lock_path)
        {
            Ok(f) => f,
            Err(e) => return unlocked(e),
        };
        let start = Instant::now();
        let mut sleep = FIRST_SLEEP;
        let mut announced = false;
        loop {
            // SAFETY: flock on a descriptor owned by `file`, which outlives the call.
            if unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) } == 0 {
                return Ok(Acquired::Locked(CacheLock { file: Some(file) }));
            }
            let e = std::io::Error::last_os_error();
            match e.raw_os_error() {
                Some(libc::EWOULDBLOCK) => {}
                Some(libc::EINTR) => continue,
                _ => return unlocked(e),
            }
            if let Some(signal) = plume_core::stop::stop_requested() {
                let what = format!("stopped while waiting for the lock {} of the automatic cache {}; nothing written", lock_path.display(), cache.display());
                return Err(Error::Interrupted { signal: signal.into(), what });
            }
            let waited = start.elapsed();
            if waited >= timeout {
                return Ok(Acquired::TimedOut { lock: lock_path, waited });
            }
            if let (Some(message), false) = (waiting, announced) {
                log::info!("{message}");
                announced = true;
            }
            std::thread::sleep(sleep.min(timeout - waited));
            sleep = (sleep * 2).min(LONGEST_SLEEP);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("plume-lock-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    /// A second holder waits for the timeout and no longer; the first one's drop frees
    /// the lock. (`flock` locks belong to open files, so two in one process conflict.)
    #[test]
    fn a_held_lock_times_out_and_a_dropped_one_is_free() {
        let dir = scratch("timeout");
        let cache = dir.join("x.plume");
        let Acquired::Locked(first) = CacheLock::acquire(&cache, Duration::ZERO, None).unwrap()
        else {
            panic!("a free lock is taken at once")
        };
        assert!(first.is_held() && lock_path(&cache).exists());
        let start = Instant::now();
        match CacheLock::acquire(&cache, Duration::from_millis(300), None).unwrap() {
            Acquired::TimedOut { lock, waited } => {
                assert_eq!(lock, dir.join(".x.plume.lock"));
                assert!(
                    waited >= Duration::from_millis(300)
                        && start.elapsed() < Duration::from_secs(5),
                    "{waited:?}"
                );
            }
            Acquired::Locked(_) => panic!("a held lock was taken twice"),
        }
        drop(first);
        assert!(
            matches!(CacheLock::acquire(&cache, Duration::ZERO, None).unwrap(), Acquired::Locked(l) if l.is_held())
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
