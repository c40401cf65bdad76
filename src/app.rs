//! The commands behind the CLI: `render` (its farm side, frames and outputs, is in
//! `farm/`), `merge`, `info`, `synth`. `main.rs` only parses arguments, calls [`run`] and
//! turns an error into a one-line message and exit code.

use std::time::{Duration, Instant};

use glam::DVec3;

use crate::camera::Camera;
use crate::cache::CacheCheck;
use crate::cli::{
    Cli, Command, ConventionArg, EmissionArg, EstimatorArg, GridArgs, InfoArgs, LightSamplingArg, MethodArg, MisArg,
    RenderArgs, SynthCommand, UpAxis,
};
use crate::color::Rgb;
use crate::error::{Error, Result};
use crate::integrator::{Integrator, LightSampling, Lights, MisHeuristic, Scene};
use crate::medium::{Convention, Emission, EmissionKind, Estimator, Medium};
use crate::vdb::{self, GridRequest, GridSelector, ReadIsolation, ReadLimits};
use crate::volume::{Field, Volume};

/// Emission grid names tried, in order, by `--emission auto` and by `--emission grid`
/// without `--emission-grid`.
pub const EMISSION_GRID_CANDIDATES: [&str; 4] = ["emission", "flame", "heat", "flame_noise"];

/// Run one parsed command line. `command_line` is recorded in outputs.
///
/// # Errors
/// Any input, argument or output error, with a message naming the file, grid or flag.
pub fn run(cli: Cli, command_line: &str) -> Result<()> {
    match cli.command {
        Command::Render(args) => crate::farm::job::render_command(&args, command_line),
        Command::Merge(args) => crate::farm::merge::merge_command(&args, command_line),
        Command::Info(args) => info_command(&args),
        Command::Prepare(args) => crate::cache::convert::prepare_command(&args),
        Command::Bench(command) => crate::bench::run(command),
        Command::Synth(SynthCommand::Explosion(args)) => {
            let t = Instant::now();
            let params = crate::synth::ExplosionParams { resolution: args.resolution, seed: args.seed, ..Default::default() };
            let ex = crate::synth::explosion(&params);
            vdb::write_float_grids(&args.output, &[&ex.density, &ex.temperature])?;
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
        Command::Synth(SynthCommand::Flare(args)) => synth_flare_command(&args),
    }
}

/// Bytes per GiB, for messages.
pub(crate) const GIB: f64 = 1024.0 * 1024.0 * 1024.0;

/// Largest estimated in-core size for `plume synth flare -o x.vdb`.
const FLARE_VDB_LIMIT_BYTES: u64 = 8 << 30;

/// `plume synth flare`: build in memory and write a .vdb, refusing flares too large for that.
fn synth_flare_command(args: &crate::cli::SynthFlareArgs) -> Result<()> {
    let t = Instant::now();
    let params = crate::synth::FlareParams { resolution: args.resolution, seed: args.seed, ..Default::default() };
    if crate::cache::is_cache_path(&args.output) {
        let flare = crate::synth::Flare::new(&params);
        let estimate = flare.estimated_bytes();
        let progress = |bytes: u64, done: i32, slabs: i32| {
            if done % 64 == 0 || done == slabs {
                eprintln!("plume: {done}/{slabs} slabs, {:.2} GiB of {:.2} GiB estimated", bytes as f64 / GIB, estimate as f64 / GIB);
            }
        };
        let c = crate::cache::generate::write_flare(&flare, &args.output, None, &progress)?;
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
        return Err(Error::invalid("--output", format!("{} must end in .vdb or .plume", args.output.display())));
    }
    let flare = crate::synth::Flare::new(&params);
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

fn info_command(args: &InfoArgs) -> Result<()> {
    if crate::cache::is_cache_path(&args.file) {
        return cache_info(args);
    }
    let grids = read_isolation(args.no_isolation, args.read_timeout, &ReadLimits::default())?.list_grids(&args.file)?;
    if args.json {
        println!("{}", crate::info::to_json(&grids));
    } else {
        print!("{}", crate::info::format_table(&args.file, &grids));
    }
    Ok(())
}

/// `plume info X.plume`: the cache's metadata, after checking every checksum.
fn cache_info(args: &InfoArgs) -> Result<()> {
    let cache = crate::cache::Cache::open(&args.file)?;
    cache.check.verified()?;
    let v = &cache.volume;
    if args.json {
        let json = serde_json::json!({
            "file": args.file,
            "bytes": cache.file_bytes,
            "checksums": "ok",
            "bricks": v.brick_count(),
            "dense_bricks": v.dense_brick_count(),
            "meta": cache.meta,
        });
        println!("{json:#}");
    } else {
        let m = &cache.meta;
        println!("{}: plume brick cache, {:.1} MiB, checksums ok", args.file.display(), cache.file_bytes as f64 / 1048576.0);
        println!("  written by        {}", m.writer);
        println!("  grids             density {:?}, source {:?}, albedo {:?}", m.density_grid, m.source_grid, m.albedo_grid);
        println!("  source            {} ({})", m.emission_kind, m.source_key);
        println!("  bricks            {} ({} dense), table {:?} from brick {:?}", v.brick_count(), v.dense_brick_count(), m.dims, m.brick_lo);
        println!("  value blocks      {} ({:.1} MiB)", m.value_blocks, (m.value_blocks * 2048) as f64 / 1048576.0);
        match &m.proxy {
            Some(p) => println!("  FNEE proxy        {}³ ({})", p.resolution, p.power_key),
            None => println!("  FNEE proxy        none"),
        }
        match &m.input {
            Some(i) => println!("  converted from    {} ({} bytes)", i.path, i.size),
            None => println!("  converted from    (generated)"),
        }
    }
    Ok(())
}

fn selector(flag: &str, s: &str) -> Result<GridSelector> {
    s.parse::<GridSelector>().map_err(|_| Error::invalid(flag, format!("{s:?} is not a grid name or name[N]")))
}

/// Where to read VDB files: in an isolated child unless `--no-isolation`.
fn read_isolation(no_isolation: bool, timeout: f64, limits: &ReadLimits) -> Result<ReadIsolation> {
    let timeout = Duration::try_from_secs_f64(timeout)
        .ok()
        .filter(|t| !t.is_zero())
        .ok_or_else(|| Error::invalid("--read-timeout", format!("{timeout} is not a positive number of seconds")))?;
    Ok(ReadIsolation::from_flags(no_isolation, limits, timeout))
}

fn check_finite_nonneg(flag: &str, v: f64) -> Result<()> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(Error::invalid(flag, format!("{v} must be a finite number ≥ 0")))
    }
}

/// Validate the render flags that clap cannot.
///
/// # Errors
/// [`Error::InvalidArgument`] naming the flag.
pub fn validate(args: &RenderArgs) -> Result<()> {
    if args.spp == Some(0) {
        return Err(Error::invalid("--spp", "must be at least 1"));
    }
    if let Some(t) = args.time {
        if !(t.is_finite() && t > 0.0) {
            return Err(Error::invalid("--time", format!("{t} must be a positive number of seconds")));
        }
    }
    if args.width == 0 || args.height == 0 || args.width > 32768 || args.height > 32768 {
        return Err(Error::invalid("--width/--height", format!("{}x{} must be between 1x1 and 32768x32768", args.width, args.height)));
    }
    check_finite_nonneg("--density-scale", args.density_scale)?;
    check_finite_nonneg("--emission-scale", f64::from(args.emission_scale))?;
    check_finite_nonneg("--kappa", args.kappa)?;
    check_finite_nonneg("--temperature-cutoff", f64::from(args.grids.temperature_cutoff))?;
    if args.emission_color.min_element() < 0.0 {
        return Err(Error::invalid("--emission-color", "components must be ≥ 0"));
    }
    if !(0.0..=1.0).contains(&args.albedo()) {
        return Err(Error::invalid("--albedo", format!("{} is not in [0, 1]", args.albedo())));
    }
    if !(args.g > -1.0 && args.g < 1.0) {
        return Err(Error::invalid("--g", format!("{} is not in (-1, 1)", args.g)));
    }
    if let Some(env) = args.environment {
        if env.min_element() < 0.0 {
            return Err(Error::invalid("--environment", "components must be ≥ 0"));
        }
    }
    if let Some(dp) = &args.debug_pixel {
        let (x, y, _) = crate::cli::parse_debug_pixel(dp).map_err(|m| Error::invalid("--debug-pixel", m))?;
        if x >= args.width || y >= args.height {
            return Err(Error::invalid("--debug-pixel", format!("pixel {x},{y} is outside the {}x{} image", args.width, args.height)));
        }
    }
    if let Some(e) = args.exposure {
        if !e.is_finite() {
            return Err(Error::invalid("--exposure", "must be finite"));
        }
    }
    if !args.output.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr")) {
        return Err(Error::invalid("--output", format!("{} must end in .exr", args.output.display())));
    }
    Ok(())
}

/// Everything `render` reads from disk and flags: the scene plus what the outputs report.
pub struct LoadedScene {
    /// The scene.
    pub scene: Scene<Volume>,
    /// Emission kind actually used (after `auto`).
    pub emission_kind: EmissionKind,
    /// Name of the source grid used, if any.
    pub source_grid: Option<String>,
    /// When the volume is mapped from a brick cache: its background checksum check, which
    /// must pass before any output is written ([`CacheCheck::verified`]).
    pub cache: Option<CacheCheck>,
}

/// The grids a volume is built from, as read requests: density, then the source
/// (temperature or emission grid, per `--emission`; none for `--emission none`), then the
/// albedo grid if any. See [`split_found`].
///
/// # Errors
/// A selector that does not parse.
pub(crate) fn grid_requests(grids: &GridArgs) -> Result<Vec<GridRequest>> {
    let emission_sels = || -> Result<Vec<GridSelector>> {
        match &grids.emission_grid {
            Some(n) => Ok(vec![selector("--emission-grid", n)?]),
            None => EMISSION_GRID_CANDIDATES.iter().map(|n| selector("--emission-grid", n)).collect(),
        }
    };
    let temperature_sel = selector("--temperature-grid", &grids.temperature_grid)?;
    let mut requests = vec![GridRequest::required(selector("--density-grid", &grids.density_grid)?)];
    match grids.emission {
        EmissionArg::None => {}
        EmissionArg::Blackbody => requests.push(GridRequest::required(temperature_sel)),
        EmissionArg::Grid => requests.push(GridRequest { alternatives: emission_sels()?, required: true }),
        EmissionArg::Auto => {
            let candidates = EMISSION_GRID_CANDIDATES.iter().map(|n| selector("--emission-grid", n));
            let alternatives = std::iter::once(Ok(temperature_sel)).chain(candidates).collect::<Result<_>>()?;
            requests.push(GridRequest { alternatives, required: false });
        }
    }
    if let Some(name) = &grids.albedo_grid {
        requests.push(GridRequest::required(selector("--albedo-grid", name)?));
    }
    Ok(requests)
}

/// The density, source and albedo grids of what [`grid_requests`] read.
pub(crate) fn split_found(
    grids: &GridArgs,
    found: Vec<Option<vdb::FoundGrid>>,
) -> (vdb::FloatGrid, Option<vdb::FoundGrid>, Option<vdb::FloatGrid>) {
    let mut found = found.into_iter();
    let density = found.next().flatten().expect("invariant: the density request is required").grid;
    let source = if grids.emission == EmissionArg::None { None } else { found.next().flatten() };
    let albedo = found.next().flatten().map(|f| f.grid);
    (density, source, albedo)
}

/// The emission kind `--emission` resolves to, given which source alternative was found.
pub(crate) fn emission_kind(arg: EmissionArg, found_alternative: Option<usize>) -> EmissionKind {
    match (arg, found_alternative) {
        (EmissionArg::None, _) | (EmissionArg::Auto, None) => EmissionKind::None,
        (EmissionArg::Blackbody, _) => EmissionKind::Blackbody,
        (EmissionArg::Grid, _) => EmissionKind::Grid,
        (EmissionArg::Auto, Some(0)) => EmissionKind::Blackbody,
        (EmissionArg::Auto, Some(_)) => EmissionKind::Grid,
    }
}

/// The emission model of the grid flags with `kind`, scale and tint.
///
/// # Errors
/// An unparsable `--temperature-map`.
pub(crate) fn emission(grids: &GridArgs, kind: EmissionKind, scale: f32, color: Rgb) -> Result<Emission> {
    Ok(Emission {
        kind,
        convention: match grids.convention {
            ConventionArg::Physical => Convention::Physical,
            ConventionArg::Cycles => Convention::Cycles,
        },
        scale,
        color,
        temperature_map: grids.temperature_map.parse()?,
        cutoff_kelvin: grids.temperature_cutoff,
    })
}

/// Read limits and reader isolation of the grid flags.
pub(crate) fn reading(grids: &GridArgs) -> Result<(ReadLimits, ReadIsolation)> {
    let limits = ReadLimits { max_bytes: grids.max_input_memory.unwrap_or(ReadLimits::default().max_bytes) };
    let isolation = read_isolation(grids.no_isolation, grids.read_timeout, &limits)?;
    Ok((limits, isolation))
}

/// `--memory-budget`, or half of physical memory.
#[must_use]
pub fn memory_budget(args: &RenderArgs) -> u64 {
    args.memory_budget.unwrap_or_else(|| ReadLimits::default().max_bytes)
}

/// The volume of a render and what it was built with.
struct LoadedVolume {
    volume: Volume,
    emission: Emission,
    source_grid: Option<String>,
    /// From a cache: the stored proxy power and its key.
    proxy_power: Option<(crate::volume::proxy::CellPower, String)>,
    cache: Option<CacheCheck>,
}

/// Read a .vdb's grids into memory and build the volume.
fn load_vdb(args: &RenderArgs, color: Rgb) -> Result<LoadedVolume> {
    let (limits, isolation) = reading(&args.grids)?;
    // Validate the flags before any reading
    emission(&args.grids, EmissionKind::None, args.emission_scale, color)?;
    let requests = grid_requests(&args.grids)?;
    let found = isolation.read_grids(&args.file, &requests, &limits)?;
    let (density, source, albedo) = split_found(&args.grids, found);
    let kind = emission_kind(args.grids.emission, source.as_ref().map(|f| f.alternative));
    let emission = emission(&args.grids, kind, args.emission_scale, color)?;
    let source = source.map(|f| f.grid);
    let volume = Volume::build_with_albedo(&density, source.as_ref(), |v| emission.map_source(v), albedo.as_ref())?;
    Ok(LoadedVolume { volume, emission, source_grid: source.map(|g| g.name), proxy_power: None, cache: None })
}

/// Open a brick cache and check it against the render's flags.
fn load_cache(args: &RenderArgs, cache: crate::cache::Cache, color: Rgb) -> Result<LoadedVolume> {
    let kind = crate::cache::convert::check_flags(&cache, &args.grids)?;
    let emission = emission(&args.grids, kind, args.emission_scale, color)?;
    crate::cache::convert::check_source_key(&cache, &emission)?;
    crate::cache::convert::check_not_stale(&cache)?;
    let proxy_power = cache.proxy_power.zip(cache.meta.proxy.map(|p| p.power_key));
    Ok(LoadedVolume { volume: cache.volume, emission, source_grid: cache.meta.source_grid, proxy_power, cache: Some(cache.check) })
}

/// Load the grids named by `args` and build the scene (volume, medium, camera).
///
/// A `.plume` input is mapped; a `.vdb` larger than a quarter of the memory budget goes
/// through an automatic brick cache (`cache::convert`); any other is read into memory.
///
/// # Errors
/// Missing or unreadable file or grid, invalid flags, incompatible grids, a stale or
/// damaged cache, or light-sampling tables beyond `--memory-budget`.
pub fn load_scene(args: &RenderArgs) -> Result<LoadedScene> {
    validate(args)?;
    let c = args.emission_color.as_vec3();
    let color = Rgb([c.x, c.y, c.z]);
    let loaded = if crate::cache::is_cache_path(&args.file) {
        load_cache(args, crate::cache::Cache::open(&args.file)?, color)?
    } else if let Some(cache) = crate::cache::convert::auto_cache(args)? {
        load_cache(args, cache, color)?
    } else {
        load_vdb(args, color)?
    };
    let LoadedVolume { volume, emission, source_grid, proxy_power, cache } = loaded;
    let up = args.camera_up.unwrap_or(match args.up_axis {
        UpAxis::Y => DVec3::Y,
        UpAxis::Z => DVec3::Z,
    });
    let (lo, hi) = if volume.is_empty() { (DVec3::splat(-1.0), DVec3::splat(1.0)) } else { let b = volume.world_bounds(); (b.lo, b.hi) };
    let camera = match args.camera_from {
        Some(from) => Camera::look_at(from, args.camera_at.unwrap_or(0.5 * (lo + hi)), up, args.fov, args.width, args.height)?,
        None => {
            // Automatic framing: a three-quarter view from the front, slightly above
            let view = match args.up_axis {
                UpAxis::Y => DVec3::new(0.35, 0.25, 1.0),
                UpAxis::Z => DVec3::new(0.35, -1.0, 0.25),
            };
            // Bounds too far out for f64 rays come from a corrupt transform, not from flags
            let mut cam = Camera::frame_bounds(lo, hi, view, up, args.fov, args.width, args.height).map_err(|_| {
                let v = |p: DVec3| format!("({:.3e}, {:.3e}, {:.3e})", p.x, p.y, p.z);
                Error::Scene(format!(
                    "{}: grid {:?} lies at world coordinates {} .. {}, too far out to frame a camera; its transform is probably corrupt",
                    args.file.display(),
                    args.grids.density_grid,
                    v(lo),
                    v(hi)
                ))
            })?;
            if let Some(at) = args.camera_at {
                cam = Camera::look_at(cam.origin, at, up, args.fov, args.width, args.height)?;
            }
            cam
        }
    };
    let medium = Medium { sigma_t: args.density_scale, albedo: args.albedo(), g: args.g, emission };
    // Light-sampling structures, only for the technique in use and only when paths scatter
    let (_, light_sampling) = method(args);
    let lights = if args.albedo() > 0.0 && args.max_depth > 0 {
        let proxy_resolution = crate::volume::proxy::ProxyGrid::resolution_for(&volume, args.proxy_resolution);
        crate::cache::convert::check_light_budget(&volume, light_sampling, memory_budget(args))?;
        match proxy_power {
            Some((power, key)) if light_sampling == LightSampling::Fnee && power.resolution == proxy_resolution && key == emission.light_key() => {
                Lights { nee: None, proxy: crate::volume::proxy::ProxyGrid::from_cell_power(&volume, &power)? }
            }
            _ => Lights::build(&volume, &emission, light_sampling, proxy_resolution)?,
        }
    } else {
        Lights::default()
    };
    Ok(LoadedScene { scene: Scene { field: volume, medium, camera, lights }, emission_kind: emission.kind, source_grid, cache })
}

/// The estimator and light sampling of `--method`, overridden by `--estimator` and
/// `--light-sampling`.
#[must_use]
pub fn method(args: &RenderArgs) -> (Estimator, LightSampling) {
    let (est, ls) = match args.method {
        MethodArg::PointNee => (EstimatorArg::Point, LightSamplingArg::Nee),
        MethodArg::LineNee => (EstimatorArg::Line, LightSamplingArg::Nee),
        MethodArg::LineFnee => (EstimatorArg::Line, LightSamplingArg::Fnee),
        MethodArg::RayMarch => (EstimatorArg::RayMarch, LightSamplingArg::None),
    };
    let estimator = match args.estimator.unwrap_or(est) {
        EstimatorArg::Point => Estimator::Point,
        EstimatorArg::Line => Estimator::Line,
        EstimatorArg::RayMarch => Estimator::RayMarch,
        EstimatorArg::Blend => Estimator::Blend { kappa: args.kappa },
    };
    let light_sampling = match args.light_sampling.unwrap_or(ls) {
        LightSamplingArg::None => LightSampling::None,
        LightSamplingArg::Nee => LightSampling::Nee,
        LightSamplingArg::Fnee => LightSampling::Fnee,
    };
    (estimator, light_sampling)
}

/// The integrator described by the render flags.
#[must_use]
pub fn integrator(args: &RenderArgs) -> Integrator {
    let (estimator, light_sampling) = method(args);
    Integrator {
        estimator,
        light_sampling,
        mis: match args.mis {
            MisArg::Balance => MisHeuristic::Balance,
            MisArg::Power => MisHeuristic::Power,
        },
        max_depth: if args.albedo() > 0.0 { args.max_depth } else { 0 },
        environment: args.environment.map(|e| {
            let e = e.as_vec3();
            Rgb([e.x, e.y, e.z])
        }),
    }
}
