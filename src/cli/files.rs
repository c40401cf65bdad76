//! `plume info`, `plume prepare`, `plume merge` and `plume synth …`: their flags and
//! the little each does besides calling the library.

use std::path::PathBuf;
use std::time::Instant;

use clap::{Args, Subcommand};
use plume::farm::merge::MergeOptions;
use plume::vdb;
use plume_core::error::{Error, Result};
use plume_engine::light::sky::{Sky, SkyParams};
use plume_scene::ReadSettings;

use super::render::GridArgs;

/// Bytes per GiB, for messages.
const GIB: f64 = 1024.0 * 1024.0 * 1024.0;

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

impl From<&MergeArgs> for MergeOptions {
    fn from(a: &MergeArgs) -> MergeOptions {
        MergeOptions {
            parts: a.parts.clone(),
            output: a.output.clone(),
            sums: a.sums,
            preview: a.preview.clone(),
            exposure: a.exposure,
            quiet: a.quiet,
            working_dir: super::environment::working_dir(),
        }
    }
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
    #[arg(long, default_value_t = ReadSettings::default().read_timeout)]
    pub read_timeout: f64,
    /// Read the file in this process, not in an isolated child (trusted files only).
    #[arg(long)]
    pub no_isolation: bool,
}

/// `plume synth …`.
#[derive(Debug, Subcommand)]
pub enum SynthCommand {
    /// A fireball: sparse `density` and Kelvin `temperature` grids in a 4 m cube, and its
    /// `velocity` (a vec3 grid, m/s: radial expansion plus curl noise) for motion blur.
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
    /// A daylight sky (Preetham et al. 1999) with its sun, as a lat-long environment map EXR.
    ///
    /// Pixels are radiance in W m⁻² sr⁻¹ per linear Rec.709 channel, scaled so that the
    /// luminance 0.2126 R + 0.7152 G + 0.0722 B is cd/m² / 683; alpha is 1. Lat-long as in
    /// Blender Cycles, +Z up: the top row is the zenith, the centre column +X, the column at
    /// a quarter of the width +Y. The ground (the bottom half) is black. The sun disc
    /// (0.53°) is put into the pixel containing it, brightened so that its energy is exact.
    Sky(SynthSkyArgs),
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

/// `plume synth sky`.
#[derive(Debug, Args)]
pub struct SynthSkyArgs {
    /// Output EXR (RGBA, 32-bit float), written atomically.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Sun elevation above the horizon, degrees, in [-90, 90]. Below 0 the sky fades to
    /// black at -6 (the model does not cover twilight) and the sun disc is gone.
    #[arg(long, default_value_t = SkyParams::default().elevation, allow_hyphen_values = true)]
    pub elevation: f64,
    /// Sun azimuth, degrees, from +X towards +Y.
    #[arg(long, default_value_t = SkyParams::default().azimuth, allow_hyphen_values = true)]
    pub azimuth: f64,
    /// Atmospheric turbidity, in [1.7, 10] (Preetham's fitted range): 2 very clear,
    /// 3 clear, 6 hazy, 10 thin fog.
    #[arg(long, default_value_t = SkyParams::default().turbidity, allow_hyphen_values = true)]
    pub turbidity: f64,
    /// Image width, pixels (1 to 16384).
    #[arg(long, default_value_t = 1024)]
    pub width: u32,
    /// Image height, pixels (1 to 16384); half the width gives square pixels.
    #[arg(long, default_value_t = 512)]
    pub height: u32,
    /// Sky only, without the sun disc.
    #[arg(long)]
    pub no_sun: bool,
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

/// `plume prepare`.
///
/// # Errors
/// As [`plume::cache::convert::convert`]; an output not ending in `.plume`.
pub fn prepare_command(args: &PrepareArgs) -> Result<()> {
    if !plume::cache::is_cache_path(&args.output) {
        return Err(Error::invalid(
            "--output",
            format!("{} must end in .{}", args.output.display(), plume::cache::EXTENSION),
        ));
    }
    // The grid flags set the same keys as for `plume render`
    let mut shot = plume_scene::Shot::new(&args.file, "");
    super::keys::apply_grids(&mut shot, &args.grids, &|_| true);
    let (scene, reading) = (&shot.scene, &shot.settings.reading);
    let input_bytes = std::fs::metadata(&args.file).map(|m| m.len()).unwrap_or(0);
    let flags = super::request::Origin { scene_file: None, given: Vec::new(), added_volumes: 0..0 };
    let what = plume::cache::convert::Conversion {
        volume: &scene.volume,
        emission: &scene.emission,
        reading,
        proxy_resolution: args.proxy_resolution,
    };
    let c = plume::cache::convert::convert(&args.file, &what, &args.output)
        .map_err(|e| flags.explain(e))?;
    if !args.quiet {
        eprintln!(
            "plume: wrote {} ({:.1} MiB) from {} ({:.1} MiB) in {:.2} s",
            c.path.display(),
            c.bytes as f64 / 1048576.0,
            args.file.display(),
            input_bytes as f64 / 1048576.0,
            c.seconds
        );
    }
    Ok(())
}

/// `plume synth explosion`.
///
/// # Errors
/// The file cannot be written.
pub fn synth_explosion_command(args: &SynthExplosionArgs) -> Result<()> {
    let t = Instant::now();
    let params = plume_synth::ExplosionParams {
        resolution: args.resolution,
        seed: args.seed,
        ..Default::default()
    };
    let ex = plume_synth::explosion(&params);
    // Velocity for motion blur, a vector grid as Blender writes it (`--velocity-grid velocity`)
    let [vx, vy, vz] = plume_synth::velocity::explosion_velocity(&params, &ex.density);
    let velocity = vdb::VectorGrid { name: "velocity", components: [&vx, &vy, &vz] };
    vdb::write_grids(&args.output, &[&ex.density, &ex.temperature], &[velocity])?;
    eprintln!(
        "plume: wrote {} ({}³, {} + {} leaves) in {:.2} s",
        args.output.display(),
        args.resolution,
        ex.density.leaf_count(),
        ex.temperature.leaf_count(),
        t.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Largest estimated in-core size for `plume synth flare -o x.vdb`.
const FLARE_VDB_LIMIT_BYTES: u64 = 8 << 30;

/// `plume synth flare`: build in memory and write a .vdb, refusing flares too large for that.
pub fn synth_flare_command(args: &SynthFlareArgs) -> Result<()> {
    let t = Instant::now();
    let params = plume_synth::FlareParams {
        resolution: args.resolution,
        seed: args.seed,
        ..Default::default()
    };
    if plume::cache::is_cache_path(&args.output) {
        let flare = plume_synth::Flare::new(&params);
        let estimate = flare.estimated_bytes();
        let progress = |bytes: u64, done: i32, slabs: i32| {
            if done % 64 == 0 || done == slabs {
                eprintln!(
                    "plume: {done}/{slabs} slabs, {:.2} GiB of {:.2} GiB estimated",
                    bytes as f64 / GIB,
                    estimate as f64 / GIB
                );
            }
        };
        let c = plume::cache::generate::write_flare(&flare, &args.output, None, &progress)?;
        eprintln!(
            "plume: wrote {} ({}³ flare, {:.2} GiB) in {:.1} s ({:.0} MB/s)",
            c.path.display(),
            args.resolution,
            c.bytes as f64 / GIB,
            c.seconds,
            c.bytes as f64 / 1e6 / c.seconds.max(1e-9)
        );
        return Ok(());
    }
    let is_vdb = args.output.extension().is_some_and(|e| e.eq_ignore_ascii_case("vdb"));
    if !is_vdb {
        return Err(Error::invalid(
            "--output",
            format!("{} must end in .vdb or .plume", args.output.display()),
        ));
    }
    let flare = plume_synth::Flare::new(&params);
    let bytes = flare.estimated_bytes();
    if bytes > FLARE_VDB_LIMIT_BYTES {
        return Err(Error::invalid(
            "--resolution",
            format!(
                "a {0}³ flare is up to about {1:.1} GiB of voxel data, more than the {2} GiB a .vdb may be built from \
                 in memory; lower --resolution or write a streamed .plume cache instead",
                args.resolution,
                bytes as f64 / f64::from(1u32 << 30),
                FLARE_VDB_LIMIT_BYTES >> 30
            ),
        ));
    }
    let (density, temperature) = flare.to_float_grids();
    vdb::write_float_grids(&args.output, &[&density, &temperature])?;
    eprintln!(
        "plume: wrote {} ({}³ flare, {} leaves) in {:.2} s",
        args.output.display(),
        args.resolution,
        density.leaf_count(),
        t.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Largest `--width` and `--height` of `plume synth sky`.
const SKY_MAX_SIZE: u32 = 16384;

/// `plume synth sky`: the sky as a lat-long EXR.
///
/// # Errors
/// A flag out of range (named as the flag; nothing is written), or the file cannot be
/// written.
pub fn synth_sky_command(args: &SynthSkyArgs) -> Result<()> {
    let t = Instant::now();
    if !args.output.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr")) {
        return Err(Error::invalid(
            "--output",
            format!("{} must end in .exr", args.output.display()),
        ));
    }
    for (flag, size) in [("--width", args.width), ("--height", args.height)] {
        if !(1..=SKY_MAX_SIZE).contains(&size) {
            return Err(Error::invalid(
                flag,
                format!("{size} pixels is outside 1..={SKY_MAX_SIZE}"),
            ));
        }
    }
    let params =
        SkyParams { elevation: args.elevation, azimuth: args.azimuth, turbidity: args.turbidity };
    // The library names scene-file keys; here they were flags
    let sky = Sky::new(&params).map_err(|e| match e {
        Error::InvalidArgument { flag, message } => {
            Error::invalid(&flag.replace("lights.sky.", "--"), message)
        }
        other => other,
    })?;
    let pixels: Vec<[f32; 4]> = sky
        .image(args.width, args.height, !args.no_sun)
        .iter()
        .map(|c| [c.0[0], c.0[1], c.0[2], 1.0])
        .collect();
    let sun = if args.no_sun {
        "none".to_string()
    } else {
        format!("{:?} W m^-2 sr^-1 over 0.53 deg", sky.sun_radiance().0)
    };
    let metadata = [
        ("plume:version", env!("CARGO_PKG_VERSION").to_string()),
        ("plume:synth", "sky (Preetham et al. 1999)".to_string()),
        ("plume:sky", serde_json::to_string(&params).expect("invariant: SkyParams serialises")),
        ("plume:sky_sun", sun),
        (
            "plume:units",
            "radiance, W m^-2 sr^-1 per linear Rec.709 channel; luminance = cd m^-2 / 683"
                .to_string(),
        ),
        (
            "plume:latlong",
            "+Z up; theta = pi v from +Z, phi = atan2(y, x) = pi (1 - 2u)".to_string(),
        ),
    ]
    .map(|(k, v)| (k.to_string(), v));
    plume::output::write_exr(&args.output, args.width, args.height, &pixels, &metadata)?;
    let zenith = sky.radiance(glam::DVec3::Z).luminance() * 683.0;
    eprintln!(
        "plume: wrote {} ({}x{} sky, zenith {zenith:.0} cd/m^2, sun {}) in {:.2} s",
        args.output.display(),
        args.width,
        args.height,
        if args.no_sun {
            "left out".to_string()
        } else {
            format!(
                "{:.0} lx at normal incidence",
                sky.sun_radiance().luminance() as f64 * Sky::sun_solid_angle() * 683.0
            )
        },
        t.elapsed().as_secs_f64()
    );
    Ok(())
}

pub fn info_command(args: &InfoArgs) -> Result<()> {
    if plume::cache::is_cache_path(&args.file) {
        return cache_info(args);
    }
    let reading = ReadSettings {
        max_input_memory: None,
        read_timeout: args.read_timeout,
        no_isolation: args.no_isolation,
    };
    let isolation = plume::load::bind::reader(&reading)?.isolation;
    let grids = isolation.list_grids(&args.file)?;
    if args.json {
        println!("{}", plume::info::to_json(&grids));
    } else {
        print!("{}", plume::info::format_table(&args.file, &grids));
    }
    Ok(())
}

/// `plume info X.plume`: the cache's metadata, after checking every checksum.
///
/// Everything read from the mapping (the brick counts read the mapped brick records) is
/// read before anything is printed: a file truncated under `info` ends it with one error
/// line and nothing on stdout, never with half a report.
fn cache_info(args: &InfoArgs) -> Result<()> {
    use std::fmt::Write as _;
    let cache = plume::cache::Cache::open(&args.file)?;
    cache.check.verified()?;
    let v = &cache.volume;
    let (bricks, dense) = (v.brick_count(), v.dense_brick_count());
    let report = if args.json {
        format!("{:#}\n", plume::info::cache_json(&args.file, &cache))
    } else {
        let m = &cache.meta;
        let mut r = String::new();
        let _ = writeln!(
            r,
            "{}: plume brick cache, {:.1} MiB, checksums ok",
            args.file.display(),
            cache.file_bytes as f64 / 1048576.0
        );
        let _ = writeln!(r, "  written by        {}", m.writer);
        let _ = writeln!(
            r,
            "  grids             density {:?}, source {:?}, albedo {:?}",
            m.density_grid, m.source_grid, m.albedo_grid
        );
        let _ = writeln!(r, "  source            {} ({})", m.emission_kind, m.source_key);
        let _ = writeln!(
            r,
            "  bricks            {bricks} ({dense} dense), table {:?} from brick {:?}",
            m.dims, m.brick_lo
        );
        let _ = writeln!(
            r,
            "  value blocks      {} ({:.1} MiB)",
            m.value_blocks,
            (m.value_blocks * 2048) as f64 / 1048576.0
        );
        let _ = match &m.proxy {
            Some(p) => writeln!(r, "  FNEE proxy        {}³ ({})", p.resolution, p.power_key),
            None => writeln!(r, "  FNEE proxy        none"),
        };
        let _ = match &m.input {
            Some(i) => writeln!(r, "  converted from    {} ({} bytes)", i.path, i.size),
            None => writeln!(r, "  converted from    (generated)"),
        };
        r
    };
    print!("{report}");
    Ok(())
}
