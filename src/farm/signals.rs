//! SIGTERM and SIGINT as a stop request that the render loop checks between passes.
//!
//! The first signal sets a flag: the current pass finishes (passes last about
//! `render::PASS_SECONDS`), the image is written with the spp actually rendered, and
//! plume exits with code 5. A second signal exits at once with code 5; the atomic writes
//! leave no partial file, and the rerun continues from the last image written. Farm
//! schedulers send SIGTERM before SIGKILL (Slurm: `KillWait`, 30 s by default).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};

use signal_hook::consts::{SIGINT, SIGTERM};

/// The stop flags, one per signal.
struct Flags {
    term: Arc<AtomicBool>,
    int: Arc<AtomicBool>,
}

static FLAGS: OnceLock<Flags> = OnceLock::new();

/// Install the handlers (once per process; later calls do nothing).
///
/// # Errors
/// The OS error if a handler cannot be installed.
pub fn install() -> std::io::Result<()> {
    if FLAGS.get().is_some() {
        return Ok(());
    }
    let flags = Flags { term: Arc::new(AtomicBool::new(false)), int: Arc::new(AtomicBool::new(false)) };
    for (signal, flag) in [(SIGTERM, &flags.term), (SIGINT, &flags.int)] {
        // Registered first, so it sees the flag as the previous signal left it: the
        // second signal exits immediately
        signal_hook::flag::register_conditional_shutdown(signal, crate::error::exit::INTERRUPTED, Arc::clone(flag))?;
        signal_hook::flag::register(signal, Arc::clone(flag))?;
    }
    let _ = FLAGS.set(flags);
    Ok(())
}

/// The signal that asked plume to stop, if any: `Some("SIGTERM")` or `Some("SIGINT")`.
#[must_use]
pub fn stop_requested() -> Option<&'static str> {
    let f = FLAGS.get()?;
    if f.term.load(Ordering::Relaxed) {
        Some("SIGTERM")
    } else if f.int.load(Ordering::Relaxed) {
        Some("SIGINT")
    } else {
        None
    }
}
