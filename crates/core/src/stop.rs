//! A process-wide stop request: the application sets it from its SIGTERM and SIGINT
//! handlers, and long waits below the render loop (a cache lock, a conversion) check it,
//! so that a stop ends them as it ends a render. The render loop itself takes a stop
//! closure instead, so a library caller decides what stops it.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};

/// The stop flags, one per signal; a signal handler sets them (`signal_hook::flag`).
#[derive(Debug)]
pub struct StopFlags {
    /// Set by SIGTERM.
    pub term: Arc<AtomicBool>,
    /// Set by SIGINT.
    pub int: Arc<AtomicBool>,
}

static FLAGS: OnceLock<StopFlags> = OnceLock::new();

/// The process's stop flags (created on first use, all clear).
pub fn flags() -> &'static StopFlags {
    FLAGS.get_or_init(|| StopFlags {
        term: Arc::new(AtomicBool::new(false)),
        int: Arc::new(AtomicBool::new(false)),
    })
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
