//! Process resource usage (CPU time, peak RSS) and the `--stats` JSON record.

use serde::Serialize;

use crate::integrator::Counters;

/// CPU seconds (user + system) consumed by this process so far.
#[must_use]
pub fn cpu_seconds() -> f64 {
    let u = rusage();
    let tv = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    tv(u.ru_utime) + tv(u.ru_stime)
}

/// Peak resident set size of this process in bytes.
#[must_use]
pub fn peak_rss_bytes() -> u64 {
    // ru_maxrss is in KiB on Linux.
    rusage().ru_maxrss.max(0) as u64 * 1024
}

fn rusage() -> libc::rusage {
    // SAFETY: getrusage only writes into the zeroed struct we pass; RUSAGE_SELF is valid.
    unsafe {
        let mut u: libc::rusage = std::mem::zeroed();
        libc::getrusage(libc::RUSAGE_SELF, &mut u);
        u
    }
}

/// The `--stats` JSON record of one render.
#[derive(Clone, Debug, Serialize)]
pub struct RenderStats {
    /// plume version.
    pub plume_version: String,
    /// Input file.
    pub input: String,
    /// Samples per pixel taken.
    pub spp: u64,
    /// Seed.
    pub seed: u64,
    /// Wall seconds from start of the command to the image written.
    pub wall_seconds: f64,
    /// Wall seconds spent in the render loop.
    pub render_seconds: f64,
    /// Seconds from start of the command to the first sample (loading + set-up).
    pub time_to_first_sample_seconds: f64,
    /// CPU seconds of the process (user + system).
    pub cpu_seconds: f64,
    /// `cpu_seconds / 3600`.
    pub core_hours: f64,
    /// Camera samples per wall second of rendering.
    pub samples_per_second: f64,
    /// Camera samples per CPU second of the whole process.
    pub samples_per_cpu_second: f64,
    /// Peak resident set size, bytes.
    pub peak_rss_bytes: u64,
    /// Worker threads.
    pub threads: usize,
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
    /// Estimator used.
    pub estimator: String,
    /// Heap bytes of the brick volume.
    pub volume_bytes: u64,
    /// Integer counters.
    pub counters: Counters,
    /// Input voxels cleaned (NaN/inf/negative → 0).
    pub density_voxels_clamped: u64,
    /// Source voxels cleaned.
    pub source_voxels_clamped: u64,
}
