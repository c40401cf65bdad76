//! The renderer's messages (the `log` facade: warnings about clamped voxels, a missing
//! emission grid, a cache being converted…) as records of Python's `logging` logger
//! `plume`, so that they appear where a Python program shows its warnings.

use pyo3::prelude::*;

/// Forwards each record to `logging.getLogger("plume")`.
struct PythonLogger;

impl log::Log for PythonLogger {
    fn enabled(&self, metadata: &log::Metadata<'_>) -> bool {
        metadata.level() <= log::Level::Info
    }

    fn log(&self, record: &log::Record<'_>) {
        if !self.enabled(record.metadata()) {
            return;
        }
        // Python's levels: WARNING 30, INFO 20 (errors are raised, not logged)
        let level = match record.level() {
            log::Level::Error => 40,
            log::Level::Warn => 30,
            _ => 20,
        };
        let message = record.args().to_string();
        Python::attach(|py| {
            let logged = py
                .import("logging")
                .and_then(|logging| logging.call_method1("getLogger", ("plume",)))
                .and_then(|logger| logger.call_method1("log", (level, message)));
            // A logging failure must not become the render's: Python prints it
            if let Err(e) = logged {
                e.print(py);
            }
        });
    }

    fn flush(&self) {}
}

static LOGGER: PythonLogger = PythonLogger;

/// Install the forwarding logger (once per process; a logger already installed stays).
pub(crate) fn install() {
    if log::set_logger(&LOGGER).is_ok() {
        log::set_max_level(log::LevelFilter::Info);
    }
}
