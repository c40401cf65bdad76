//! Command-line interface (clap derive). Doc comments here are the `--help` text.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};
use glam::DVec3;

/// plume: a renderer for emissive heterogeneous volumes (OpenVDB), with line
/// integration and forward next-event estimation.
///
/// Exit codes: 0 success (also when every output was already complete and skipped);
/// 2 bad arguments; 3 input missing, unreadable or invalid (VDB file, grid, merge part);
/// 4 render or output failure; 5 interrupted by SIGTERM/SIGINT (the image so far was
/// written with its real spp; a rerun continues it); 6 --time-limit reached (likewise);
/// 7 a run of several frames in which some frames failed or stopped early (each is
/// reported; the others were rendered). A run of one frame exits with that frame's code.
/// 101 is a bug (a panic): please report it.
#[derive(Debug, Parser)]
#[command(name = "plume", version, about, long_about)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Render a VDB file, or a sequence of them, to float EXRs (and optionally PNG
    /// previews).
    Render(Box<RenderArgs>),
    /// Assemble parts of a frame rendered as tiles (--crop, --tile) and sample ranges
    /// (--sample-range) into one EXR, bit-identical to rendering it in one process.
    Merge(MergeArgs),
    /// Print every grid of a VDB file: name, type, class, voxels, bounds, transform,
    /// value range, memory.
    Info(InfoArgs),
    /// Convert a .vdb into a brick cache file (.plume) that renders out of core: bricks,
    /// pyramid and FNEE proxy, memory-mapped by `plume render OUT.plume`.
    Prepare(PrepareArgs),
    /// Generate procedural volumes.
    #[command(subcommand)]
    Synth(SynthCommand),
    /// Benchmarks: speed and memory figures.
    #[command(subcommand)]
    Bench(BenchCommand),
}

/// `plume bench …`.
#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Core renderer figures: DDA voxel steps/s per core, parallel speed-up, time to first
    /// sample, brick memory vs raw voxel data.
    Core(BenchCoreArgs),
    /// The paper's equal-time comparison of methods on thin and dense generated
    /// explosions: RMSE against a converged reference, spp, core-hours.
    Methods(BenchMethodsArgs),
    /// Methods at equal CPU time and equal spp against a given or computed reference,
    /// several seeds: RMSE, relMSE, bias, spp, samples per CPU second, core-hours, peak
    /// memory; as a table, CSV, JSON and PNG plots.
    Compare(Box<crate::bench::args::CompareArgs>),
    /// Numerical extremes: density scales, temperatures, voxel sizes and NaN/inf/negative
    /// voxels, checked against closed forms.
    Extremes(crate::bench::args::ExtremesArgs),
    /// The whole benchmark suite behind docs/BENCHMARKS.md (tables and plots).
    Report(crate::bench::args::ReportArgs),
}

/// `plume bench methods`.
#[derive(Debug, Args)]
pub struct BenchMethodsArgs {
    /// Explosion resolution.
    #[arg(long, default_value_t = 64)]
    pub resolution: u32,
    /// Image width.
    #[arg(long, default_value_t = 160)]
    pub width: u32,
    /// Image height.
    #[arg(long, default_value_t = 120)]
    pub height: u32,
    /// CPU seconds per method (equal CPU time).
    #[arg(long, default_value_t = 10.0)]
    pub time: f64,
    /// CPU seconds for each reference render.
    #[arg(long, default_value_t = 120.0)]
    pub reference_time: f64,
    /// MIS heuristic of the compared methods.
    #[arg(long, value_enum, default_value_t = MisArg::Power)]
    pub mis: MisArg,
    /// FNEE proxy resolution of the compared methods.
    #[arg(long, default_value_t = 64)]
    pub proxy_resolution: u32,
    /// Regimes as NAME=DENSITY_SCALE, comma-separated.
    #[arg(long, default_value = "thin=1,dense=20")]
    pub regimes: String,
    /// Threads (0 = all cores).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Also write the results as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// `plume bench core`.
#[derive(Debug, Args)]
pub struct BenchCoreArgs {
    /// Resolution of the generated explosion.
    #[arg(long, default_value_t = 256)]
    pub resolution: u32,
    /// Threads for the parallel run (0 = all cores).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// File whose time to first sample is measured.
    #[arg(long, default_value = "../shared/data/smoke/openvdb_org_smoke1.vdb")]
    pub ttfs_file: PathBuf,
    /// Also write the figures as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// `plume merge`.
#[derive(Debug, Args)]
pub struct MergeArgs {
    /// Parts: EXRs written with --crop, --tile, --sample-range or --sums, of one frame.
    #[arg(required = true)]
    pub parts: Vec<PathBuf>,
    /// Output EXR.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Keep the exact sums in the output, so that it can be merged again (e.g. with more
    /// samples rendered later).
    #[arg(long)]
    pub sums: bool,
    /// Write a tone-mapped sRGB PNG preview here.
    #[arg(long)]
    pub preview: Option<PathBuf>,
    /// Preview exposure in stops (default: automatic).
    #[arg(long, allow_hyphen_values = true)]
    pub exposure: Option<f32>,
    /// No summary.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Machine-readable progress on stdout.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ProgressArg {
    /// None (logs on stderr only).
    None,
    /// Open Job Description: `openjd_progress: PERCENT` and `openjd_status: TEXT` lines.
    Openjd,
    /// One JSON object per line (`event`: frame_start, progress, frame_done, frame_skipped,
    /// frame_failed, done).
    Json,
}

/// `plume info`.
#[derive(Debug, Args)]
pub struct InfoArgs {
    /// The .vdb file, or a .plume brick cache (its metadata, after checking every
    /// checksum).
    pub file: PathBuf,
    /// Print a JSON array instead of text.
    #[arg(long)]
    pub json: bool,
    /// Seconds the isolated VDB reader may take before it is killed.
    #[arg(long, default_value_t = 120.0)]
    pub read_timeout: f64,
    /// Read the file in this process, not in an isolated child (trusted files only).
    #[arg(long)]
    pub no_isolation: bool,
}

/// `plume synth …`.
#[derive(Debug, Subcommand)]
pub enum SynthCommand {
    /// A fireball: sparse `density` and Kelvin `temperature` grids in a 4 m cube.
    Explosion(SynthExplosionArgs),
    /// A solar flare: hot (10⁶–2·10⁷ K) plasma loops over a dark photosphere in a 100 m cube.
    ///
    /// A sheared flare arcade of thin, hot loops with bright knots near some loop tops,
    /// under fans of cooler active-region loops; y up, photosphere at y = 0 (read metres
    /// as megametres). Grids `density` (unitless) and `temperature` (Kelvin).
    ///
    /// The flare is generated brick by brick and scales to any resolution (about 32 GB of
    /// voxel data at 4096³), but a .vdb is built in memory, so .vdb output stops at an
    /// estimated 8 GiB (about 2500³).
    ///
    /// Rendering: the loops are optically thin at the default --density-scale 1 and the
    /// preview's automatic exposure suits them, so `plume render flare.vdb -o flare.exr
    /// --preview flare.png --spp 16` needs no other flag. For a closer view add
    /// `--camera-from 40,40,115 --camera-at 0,14,0`; --density-scale 5 adds visible
    /// self-absorption in the dense arcade; --exposure N (stops) keeps brightness fixed
    /// across seeds and resolutions.
    Flare(SynthFlareArgs),
}

/// `plume synth explosion`.
#[derive(Debug, Args)]
pub struct SynthExplosionArgs {
    /// Voxels along each axis of the 4 m cube.
    #[arg(long, default_value_t = 128, value_parser = clap::value_parser!(u32).range(8..=16384))]
    pub resolution: u32,
    /// Output .vdb file.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Noise seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// Which grids make the volume and how they are read: shared by `render` and `prepare`,
/// because a brick cache stores exactly what these flags select.
#[derive(Clone, Debug, Args)]
pub struct GridArgs {
    /// Density grid name (`name[N]` for the N-th duplicate).
    #[arg(long, default_value = "density")]
    pub density_grid: String,
    /// What drives emission.
    #[arg(long, value_enum, default_value_t = EmissionArg::Auto)]
    pub emission: EmissionArg,
    /// Temperature grid name (blackbody).
    #[arg(long, default_value = "temperature")]
    pub temperature_grid: String,
    /// Temperature grid values to Kelvin: `kelvin` or `linear:OFFSET,SCALE`.
    #[arg(long, default_value = "kelvin")]
    pub temperature_map: String,
    /// Physical blackbody: temperatures below this (Kelvin) emit nothing.
    #[arg(long, default_value_t = 500.0)]
    pub temperature_cutoff: f32,
    /// Emission grid name (`--emission grid`).
    #[arg(long)]
    pub emission_grid: Option<String>,
    /// Physical, or Blender Cycles' Principled Volume convention.
    #[arg(long, value_enum, default_value_t = ConventionArg::Physical)]
    pub convention: ConventionArg,
    /// Per-voxel albedo grid (values clamped to [0, 1]), times --albedo.
    #[arg(long)]
    pub albedo_grid: Option<String>,
    /// Largest input a grid read may allocate, e.g. `8GiB`, `512MiB` (default: half of RAM).
    #[arg(long, value_parser = parse_bytes)]
    pub max_input_memory: Option<u64>,
    /// Seconds the isolated VDB reader may take before it is killed.
    #[arg(long, default_value_t = 120.0)]
    pub read_timeout: f64,
    /// Read the file in this process, not in an isolated child that limits memory and
    /// time and survives crashes (saves a few ms; trusted files only).
    #[arg(long)]
    pub no_isolation: bool,
}

impl Default for GridArgs {
    /// The flags' defaults, as `plume render` and `plume prepare` take them.
    fn default() -> Self {
        #[derive(Parser)]
        struct Defaults {
            #[command(flatten)]
            grids: GridArgs,
        }
        Defaults::parse_from(["plume"]).grids
    }
}

/// `plume prepare`.
#[derive(Clone, Debug, Args)]
pub struct PrepareArgs {
    /// The .vdb file to convert.
    pub file: PathBuf,
    /// The cache file to write (`.plume`); written atomically.
    #[arg(short, long)]
    pub output: PathBuf,
    /// FNEE proxy resolution to store (default 64, or the data resolution if smaller); a
    /// render asking for another one builds its own from the bricks.
    #[arg(long)]
    pub proxy_resolution: Option<u32>,
    /// Which grids, and how the source maps (a render from the cache must agree).
    #[command(flatten)]
    pub grids: GridArgs,
    /// No summary line.
    #[arg(long, short)]
    pub quiet: bool,
}

/// `plume synth flare`.
#[derive(Debug, Args)]
pub struct SynthFlareArgs {
    /// Voxels along each axis of the 100 m cube (any value up to 65536).
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub resolution: u32,
    /// Output file: a .vdb (built in memory, up to an estimated 8 GiB) or a .plume brick
    /// cache (streamed slab by slab: any size).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Loop layout seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// Emission estimator along free-path segments.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum EstimatorArg {
    /// Collision estimator L_e/μ_t at sampled collisions.
    Point,
    /// Track-length estimator (line integration, the paper's).
    Line,
    /// Expected-value estimator (exact per-voxel closed form, deterministic).
    RayMarch,
    /// Per-voxel blend of line and point (`--kappa`).
    Blend,
}

/// The paper's methods (its conclusion table) as presets.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum MethodArg {
    /// Collision estimator + classic NEE with MIS in volume measure.
    PointNee,
    /// Line integration + classic NEE (no MIS partner).
    LineNee,
    /// Line integration + forward NEE with MIS (the paper's method).
    LineFnee,
    /// Expected-value (ray-marching) estimator, forward paths only.
    RayMarch,
}

/// Next event technique.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum LightSamplingArg {
    /// Forward (phase-sampled) paths only.
    None,
    /// Classic NEE to emissive voxels (volume measure).
    Nee,
    /// Forward NEE: proxy direction + free path, MIS in solid angle.
    Fnee,
}

/// MIS heuristic.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum MisArg {
    /// Balance heuristic.
    Balance,
    /// Power heuristic (exponent 2).
    Power,
}

/// What drives emission.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum EmissionArg {
    /// Blackbody if the temperature grid exists, else an emission grid if one of
    /// `emission`, `flame`, `heat`, `flame_noise` exists, else none.
    Auto,
    /// Blackbody from the temperature grid.
    Blackbody,
    /// Scalar emission grid × colour × scale.
    Grid,
    /// No emission (absorption only).
    None,
}

/// Emission convention.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ConventionArg {
    /// Emission density ∝ density × source.
    Physical,
    /// Blender Cycles' Principled Volume: emission not multiplied by density.
    Cycles,
}

/// `--sample-order`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum SampleOrderArg {
    /// Tile-major when the volume is a mapped cache larger than available memory and the
    /// render has a fixed spp and no time limit; progressive otherwise.
    Auto,
    /// Passes over the whole image.
    Progressive,
    /// Each tile's samples together, tiles in order, bricks read ahead.
    TileMajor,
}

/// Up axis used when the camera is framed automatically.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum UpAxis {
    /// +y up (Houdini, OpenVDB samples).
    Y,
    /// +z up (Blender).
    Z,
}

impl RenderArgs {
    /// The albedo scale: `--albedo`, else 1 with an albedo grid, else 0.
    #[must_use]
    pub fn albedo(&self) -> f32 {
        self.albedo.unwrap_or(if self.grids.albedo_grid.is_some() { 1.0 } else { 0.0 })
    }
}

/// `plume render`.
#[derive(Clone, Debug, Args)]
// Negative numbers reach our validation, which names the flag and the allowed range.
#[command(allow_negative_numbers = true)]
pub struct RenderArgs {
    /// The .vdb file or .plume brick cache (`plume prepare`), or with --frames a
    /// pattern with a frame token: `fire.####.vdb`
    /// (one `#` per digit), `fire.%04d.vdb` or `fire.$F4.vdb`. Numbers wider than the
    /// padding are printed in full.
    pub file: PathBuf,
    /// Output EXR (32-bit float RGBA; alpha = 1 − transmittance); with --frames a
    /// pattern like FILE's. Written atomically; an output that is already complete is
    /// skipped unless --overwrite, and one left by an interrupted render is continued.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Samples per pixel.
    #[arg(long, conflicts_with = "time")]
    pub spp: Option<u32>,
    /// Render whole 1-spp passes until this many seconds are spent.
    #[arg(long)]
    pub time: Option<f64>,
    /// Seed of the sample streams (default: the frame number with --frames, else 0).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Worker threads (0 = all cores, and one more when rendering tile by tile from a
    /// brick cache, where workers wait for the disk). The image does not depend on it.
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Image width in pixels.
    #[arg(long, default_value_t = 640)]
    pub width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 480)]
    pub height: u32,
    /// Camera position x,y,z (world). Without it the volume is framed automatically.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub camera_from: Option<DVec3>,
    /// Point looked at x,y,z (default: the volume's centre).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub camera_at: Option<DVec3>,
    /// Up vector x,y,z (default: from --up-axis).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub camera_up: Option<DVec3>,
    /// Horizontal field of view in degrees.
    #[arg(long, default_value_t = 40.0)]
    pub fov: f64,
    /// Up axis for automatic framing and the default --camera-up.
    #[arg(long, value_enum, default_value_t = UpAxis::Y)]
    pub up_axis: UpAxis,
    /// The paper's methods as presets: estimator + light sampling. `--estimator` and
    /// `--light-sampling` override the preset's parts.
    #[arg(long, value_enum, default_value_t = MethodArg::LineFnee)]
    pub method: MethodArg,
    /// Emission estimator (default: from --method).
    #[arg(long, value_enum)]
    pub estimator: Option<EstimatorArg>,
    /// Next event technique at scattering vertices (default: from --method).
    #[arg(long, value_enum)]
    pub light_sampling: Option<LightSamplingArg>,
    /// MIS heuristic between forward sampling and NEE/FNEE.
    #[arg(long, value_enum, default_value_t = MisArg::Power)]
    pub mis: MisArg,
    /// FNEE proxy grid resolution (cells along the longest axis; a power of two, 8 up to
    /// the data resolution). Default 64, or the data resolution if that is smaller.
    #[arg(long)]
    pub proxy_resolution: Option<u32>,
    /// Single-scattering albedo in [0, 1] (0: emission–absorption only). With
    /// --albedo-grid it multiplies the grid (default 1 then).
    #[arg(long)]
    pub albedo: Option<f32>,
    /// Henyey–Greenstein asymmetry g in (−1, 1).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub g: f64,
    /// Largest number of scattering events per path.
    #[arg(long, default_value_t = 64)]
    pub max_depth: u32,
    /// Constant environment radiance r,g,b seen by escaping paths (default: none).
    #[arg(long, value_parser = parse_vec3)]
    pub environment: Option<DVec3>,
    /// Render only sample S of pixel (X, Y) and print its path: X,Y,S.
    #[arg(long)]
    pub debug_pixel: Option<String>,
    /// κ of the blend estimator: α = 1/(1 + κ μ Δ) per voxel.
    #[arg(long, default_value_t = 4.0)]
    pub kappa: f64,
    /// Which grids make the volume, how the source maps, and how files are read.
    #[command(flatten)]
    pub grids: GridArgs,
    /// σ_t: extinction per world unit per unit density.
    #[arg(long, default_value_t = 1.0)]
    pub density_scale: f64,
    /// Emission scale s_e.
    #[arg(long, default_value_t = 1.0)]
    pub emission_scale: f32,
    /// Emission colour r,g,b (a tint for blackbody).
    #[arg(long, value_parser = parse_vec3, default_value = "1,1,1")]
    pub emission_color: DVec3,
    /// Write a tone-mapped sRGB PNG preview here (a pattern with --frames).
    #[arg(long)]
    pub preview: Option<PathBuf>,
    /// Preview exposure in stops (default: automatic).
    #[arg(long, allow_hyphen_values = true)]
    pub exposure: Option<f32>,
    /// Append render statistics here, one JSON object per frame and line (JSON Lines):
    /// wall and CPU seconds, core-hours, spp, samples/s, peak RSS, input SHA-256, host,
    /// command line. May hold a frame token.
    #[arg(long)]
    pub stats: Option<PathBuf>,
    /// Bound on resident anonymous memory, e.g. `4GiB` (default: half of RAM). A .vdb
    /// larger than a quarter of it on disk renders through a brick cache (mapped; the OS
    /// page cache may hold its pages), and a render whose own tables would exceed it is
    /// refused.
    #[arg(long, value_parser = parse_bytes)]
    pub memory_budget: Option<u64>,
    /// Where automatic brick caches of large .vdb inputs go (default: beside the input,
    /// or `$XDG_CACHE_HOME/plume` when that directory is not writable).
    #[arg(long)]
    pub cache_dir: Option<PathBuf>,
    /// Order of the samples (the image is the same): `progressive` passes over the whole
    /// image, or `tile-major`, every sample of a tile before the next, with the next
    /// tiles' bricks read ahead, so a volume larger than memory is read from disk about
    /// once. `auto`: tile-major for a brick cache larger than the memory available to
    /// the page cache, with --spp and no --time-limit. In tile-major order a stop signal
    /// or time limit abandons the frame (nothing of it is written).
    #[arg(long, value_enum, default_value_t = SampleOrderArg::Auto)]
    pub sample_order: SampleOrderArg,
    /// No progress bar or summary.
    #[arg(long, short)]
    pub quiet: bool,
    /// Frames to render: `1-100`, `1-100x2` (or `1-100:2`), `1,5,10-20`. One process
    /// renders them in order, each frame's grids loaded once; a frame that fails is
    /// reported and the others go on (exit code 7).
    #[arg(long, allow_hyphen_values = true)]
    pub frames: Option<String>,
    /// Render frames even when their output is already complete (default: skip them).
    #[arg(long)]
    pub overwrite: bool,
    /// Per-frame wall-clock limit in seconds (loading included): the frame stops between
    /// passes and its image is written with the spp reached (exit code 6); a rerun
    /// continues it.
    #[arg(long)]
    pub time_limit: Option<f64>,
    /// Render only these pixels: x0,y0,x1,y1 (columns x0..x1−1, rows y0..y1−1). Writes a
    /// part for `plume merge`.
    #[arg(long, value_parser = clap::value_parser!(crate::film::Crop), conflicts_with = "tile")]
    pub crop: Option<crate::film::Crop>,
    /// Render only tile i of n (0-based; a near-square grid, row by row). Writes a part
    /// for `plume merge`.
    #[arg(long, value_parser = crate::farm::split::parse_tile)]
    pub tile: Option<(u32, u32)>,
    /// Render only samples a..b−1 of every pixel (instead of --spp/--time). Writes a part
    /// for `plume merge`.
    #[arg(long, value_parser = crate::farm::split::parse_sample_range, conflicts_with_all = ["spp", "time"])]
    pub sample_range: Option<std::ops::Range<u64>>,
    /// Also store the exact sample sums in the EXR (implied by --crop, --tile and
    /// --sample-range), so that it can be merged with more samples later.
    #[arg(long)]
    pub sums: bool,
    /// Machine-readable progress on stdout (logs stay on stderr).
    #[arg(long, value_enum, default_value_t = ProgressArg::None)]
    pub progress: ProgressArg,
}

/// Parse `x,y,z`.
///
/// # Errors
/// A message for clap when the text is not three finite numbers.
pub fn parse_vec3(s: &str) -> Result<DVec3, String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(format!("expected x,y,z, got {s:?}"));
    }
    let mut v = [0.0; 3];
    for (d, p) in v.iter_mut().zip(&parts) {
        *d = p.parse::<f64>().map_err(|_| format!("{p:?} is not a number"))?;
        if !d.is_finite() {
            return Err(format!("{p:?} is not finite"));
        }
    }
    Ok(DVec3::from_array(v))
}

/// Parse a byte size: `1234`, `512MiB`, `8GiB`, `2GB`, `100K`.
///
/// # Errors
/// A message for clap on a malformed size.
pub fn parse_bytes(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let split = t.find(|c: char| !(c.is_ascii_digit() || c == '.')).unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let n: f64 = num.parse().map_err(|_| format!("{s:?} is not a size like 512MiB or 8GiB"))?;
    let mult: f64 = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 1.0,
        "k" | "kb" => 1e3,
        "kib" => 1024.0,
        "m" | "mb" => 1e6,
        "mib" => 1024.0 * 1024.0,
        "g" | "gb" => 1e9,
        "gib" => 1024.0 * 1024.0 * 1024.0,
        "t" | "tb" => 1e12,
        "tib" => 1024.0f64.powi(4),
        _ => return Err(format!("unknown unit in {s:?} (use B, KiB, MiB, GiB, TiB, KB, MB, GB, TB)")),
    };
    let v = n * mult;
    if !(v.is_finite() && v >= 1.0) {
        return Err(format!("{s:?} must be at least 1 byte"));
    }
    Ok(v as u64)
}

/// Parse `--debug-pixel X,Y,S`.
///
/// # Errors
/// A message naming the flag when the text is not three non-negative integers.
pub fn parse_debug_pixel(s: &str) -> Result<(u32, u32, u64), String> {
    let p: Vec<&str> = s.split(',').map(str::trim).collect();
    let bad = || format!("--debug-pixel: expected X,Y,S (pixel column, row, sample index), got {s:?}");
    if p.len() != 3 {
        return Err(bad());
    }
    Ok((p[0].parse().map_err(|_| bad())?, p[1].parse().map_err(|_| bad())?, p[2].parse().map_err(|_| bad())?))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_vectors_and_sizes() {
        assert_eq!(parse_vec3("1, -2,3.5").unwrap(), DVec3::new(1.0, -2.0, 3.5));
        assert!(parse_vec3("1,2").is_err());
        assert!(parse_vec3("1,2,nan").is_err());
        assert_eq!(parse_bytes("512MiB").unwrap(), 512 << 20);
        assert_eq!(parse_bytes("8GiB").unwrap(), 8 << 30);
        assert_eq!(parse_bytes("2GB").unwrap(), 2_000_000_000);
        assert!(parse_bytes("12 parsecs").is_err());
        assert!(parse_bytes("0").is_err());
    }
}
