//! Benchmarks (`plume bench …`): speed, memory and accuracy figures are measured here,
//! never in timed tests (STYLE.md §8). Each prints a table and can write JSON.
//!
//! - `core`: DDA throughput, parallel speed-up, time to first sample, brick memory;
//! - `methods`: the paper's equal-time table on generated explosions (kept for
//!   continuity; `compare` measures the same and more);
//! - `compare`: any scene and flags, any methods, equal CPU time and equal spp against a
//!   given or computed reference, several seeds, RMSE / relMSE / bias, CSV, JSON, plots;
//! - `extremes`: the numerical-extremes sweep with closed forms;
//! - `demo`: the README's demo timed per seed, and its error against long references
//!   (the clean first picture);
//! - `interpolation`: trilinear against nearest reconstruction on real files: cost per
//!   sample, memory, plume's emission rule against Cycles', a close-up picture;
//! - `volumes`: cost per sample and memory against the number of instances of a volume;
//! - `report`: the whole suite that writes `docs/BENCHMARKS.md` (`--quick`: its short form).

pub mod compare;
pub mod core;
pub mod demo;
pub mod extremes;
pub mod interpolation;
pub mod methods;
pub mod metrics;
pub mod numbers;
pub mod options;
pub mod outputs;
pub mod plot;
pub mod progressive;
pub mod report;
pub mod spec;
pub mod targets;
pub mod volumes;

use plume_core::error::{Error, Result};

/// Write `value` as pretty JSON to `path`, if given.
///
/// # Errors
/// [`Error::Write`].
pub fn write_json<T: serde::Serialize>(path: &Option<std::path::PathBuf>, value: &T) -> Result<()> {
    if let Some(p) = path {
        let json = serde_json::to_string_pretty(value).map_err(|e| Error::Scene(e.to_string()))?;
        plume_core::fs::write_atomic(p, |w| std::io::Write::write_all(w, json.as_bytes()))?;
    }
    Ok(())
}

/// Reset the kernel's peak-RSS mark (`VmHWM`) of this process to its current RSS, so that
/// the next [`peak_rss_bytes`] is the peak since now. Returns false where that is not
/// supported (then the peak is the process's peak so far).
pub fn reset_peak_rss() -> bool {
    // Linux ≥ 4.0: writing 5 to clear_refs resets the peak RSS (proc(5))
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}

/// Peak resident set size in bytes since the last [`reset_peak_rss`] (`VmHWM`), or the
/// process's peak from `getrusage` where `/proc` is not available.
#[must_use]
pub fn peak_rss_bytes() -> u64 {
    let from_proc = std::fs::read_to_string("/proc/self/status").ok().and_then(|s| {
        let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
        let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
        Some(kib * 1024)
    });
    from_proc.unwrap_or_else(plume_engine::stats::peak_rss_bytes)
}

/// The machine a report was measured on: what [`machine`] returns.
#[derive(Clone, Debug, PartialEq, Eq)]
#[must_use]
pub struct Machine {
    /// Logical CPUs available to this process.
    pub cpus: usize,
    /// CPU model name (from `/proc/cpuinfo`), or `unknown CPU`.
    pub model: String,
    /// Physical memory in bytes (`MemTotal` of `/proc/meminfo`), or 0 where unknown.
    pub memory_bytes: u64,
}

/// The machine, for reports.
pub fn machine() -> Machine {
    let n = std::thread::available_parallelism().map_or(1, std::num::NonZero::get);
    let model = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, m)| m.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    let memory_bytes = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|s| {
            let line = s.lines().find(|l| l.starts_with("MemTotal:"))?;
            let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
            Some(kib * 1024)
        })
        .unwrap_or(0);
    Machine { cpus: n, model, memory_bytes }
}

#[cfg(test)]
mod tests {
    #[test]
    fn peak_rss_is_positive_after_reset() {
        super::reset_peak_rss();
        assert!(super::peak_rss_bytes() > 0);
    }
}
