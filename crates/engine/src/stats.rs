//! Process resource usage (CPU time, peak RSS) and the `--stats` JSON record.

use serde::Serialize;

use crate::integrator::counters::Counters;

/// Bytes per GiB, for messages.
pub const GIB: f64 = 1024.0 * 1024.0 * 1024.0;

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

/// Reset this process's peak-RSS high-water mark (Linux `clear_refs` 5), so that
/// [`peak_rss_since_reset_bytes`] measures one frame of a sequence. Best effort.
pub fn reset_peak_rss() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

/// Peak resident set size since the last [`reset_peak_rss`] (`VmHWM`), in bytes; the
/// process peak ([`peak_rss_bytes`]) where `/proc` is unavailable.
#[must_use]
pub fn peak_rss_since_reset_bytes() -> u64 {
    let hwm = std::fs::read_to_string("/proc/self/status").ok().and_then(|s| {
        s.lines().find_map(|l| {
            l.strip_prefix("VmHWM:")
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
        })
    });
    hwm.map_or_else(peak_rss_bytes, |kib| kib * 1024)
}

/// The record of one rendered frame (or part of a frame): appended to the `--stats` file
/// as one JSON line and stored in the EXR header as `plume:<camelCaseName>` attributes.
#[derive(Clone, Debug, Serialize)]
pub struct RenderStats {
    /// plume version.
    pub plume_version: String,
    /// The command line of the process.
    pub command_line: String,
    /// Host name of the machine.
    pub host: String,
    /// Frame number (sequences and `--frames`), else absent.
    pub frame: Option<i64>,
    /// Input file.
    pub input: String,
    /// Input file size, bytes.
    pub input_bytes: u64,
    /// SHA-256 of the input file, hex.
    pub input_sha256: String,
    /// Output EXR.
    pub output: String,
    /// `complete`, `interrupted` or `time-limit` (see `farm::part::Completion`).
    pub status: String,
    /// Samples per pixel in the image.
    pub spp: u64,
    /// Pixels per sample count held (one entry unless adaptive sampling stopped pixels
    /// at different counts).
    pub spp_histogram: Vec<crate::noise::SppCount>,
    /// The image's estimated remaining error, from its own samples (`noise`).
    pub error_estimate: crate::noise::ErrorEstimate,
    /// Sample indices in the image, `a..b` (b − a = spp).
    pub sample_range: String,
    /// Samples per pixel taken before a resume (0 for a fresh render).
    pub resumed_from_spp: u64,
    /// Seed.
    pub seed: u64,
    /// Hash of the version, seed and every flag that changes pixels (`farm::fingerprint`).
    pub settings_hash: String,
    /// Full image width.
    pub width: u32,
    /// Full image height.
    pub height: u32,
    /// Pixels rendered, `x0,y0,x1,y1`.
    pub crop: String,
    /// F of the exact sums (units of 2^−F).
    pub fixed_point_bits: u32,
    /// Wall seconds from the start of the frame to the image rendered (loading, hashing
    /// and rendering; the EXR write follows).
    pub wall_seconds: f64,
    /// Wall seconds spent in the render loop.
    pub render_seconds: f64,
    /// Workers rendering a tile, on average over the render loop (at most `threads`;
    /// below it, workers waited at the ends of passes).
    pub workers_busy: f64,
    /// Seconds from the start of the frame to the first sample (hashing, loading, set-up).
    pub time_to_first_sample_seconds: f64,
    /// CPU seconds (user + system) of the process during this frame.
    pub cpu_seconds: f64,
    /// `cpu_seconds / 3600`: the core-hours consumed.
    pub core_hours: f64,
    /// `wall_seconds × threads / 3600`: the core-hours held (what a farm bills).
    pub allocated_core_hours: f64,
    /// Camera samples per wall second of rendering.
    pub samples_per_second: f64,
    /// Camera samples per CPU second of the frame.
    pub samples_per_cpu_second: f64,
    /// Peak resident set size during this frame, bytes.
    pub peak_rss_bytes: u64,
    /// Worker threads.
    pub threads: usize,
    /// Estimator used (`Line`; with a camera segment's own, `Line, camera RayMarch`).
    pub estimator: String,
    /// Heap bytes of the brick volume.
    pub volume_bytes: u64,
    /// Integer counters.
    pub counters: Counters,
    /// Sample values or sums clamped to the fixed-point range (should be 0).
    pub saturated_samples: u64,
    /// Non-zero sample values below the fixed-point unit, stored as 0.
    pub underflowed_samples: u64,
    /// Input voxels cleaned (NaN/inf/negative → 0).
    pub density_voxels_clamped: u64,
    /// Source voxels cleaned.
    pub source_voxels_clamped: u64,
}
