//! The commands behind the CLI: `render` (its farm side, frames and outputs, is in
//! `farm/`), `merge`, `info`, `synth`. `main.rs` only parses arguments, calls [`run`] and
//! turns an error into a one-line message and exit code.

use std::time::{Duration, Instant};

use glam::DVec3;

use crate::camera::Camera;
use crate::cli::{
    Cli, Command, ConventionArg, EmissionArg, EstimatorArg, InfoArgs, LightSamplingArg, MethodArg, MisArg, RenderArgs,
    SynthCommand, UpAxis,
};
use crate::color::Rgb;
use crate::error::{Error, Result};
use crate::integrator::{Integrator, LightSampling, Lights, MisHeuristic, Scene};
use crate::medium::{Convention, Emission, EmissionKind, Estimator, Medium, TemperatureMap};
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

/// Largest estimated in-core size for `plume synth flare -o x.vdb`.
const FLARE_VDB_LIMIT_BYTES: u64 = 8 << 30;

/// `plume synth flare`: build in memory and write a .vdb, refusing flares too large for that.
fn synth_flare_command(args: &crate::cli::SynthFlareArgs) -> Result<()> {
    let t = Instant::now();
    let is_vdb = args.output.extension().is_some_and(|e| e.eq_ignore_ascii_case("vdb"));
    if !is_vdb {
        return Err(Error::invalid(
            "--output",
            format!("{}: plume synth flare writes only .vdb files (no streamed .plume cache yet)", args.output.display()),
        ));
    }
    let params = crate::synth::FlareParams { resolution: args.resolution, seed: args.seed, ..Default::default() };
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
    let grids = read_isolation(args.no_isolation, args.read_timeout, &ReadLimits::default())?.list_grids(&args.file)?;
    if args.json {
        println!("{}", crate::info::to_json(&grids));
    } else {
        print!("{}", crate::info::format_table(&args.file, &grids));
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
    check_finite_nonneg("--temperature-cutoff", f64::from(args.temperature_cutoff))?;
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
}

/// Load the grids named by `args` and build the scene (volume, medium, camera).
///
/// # Errors
/// Missing or unreadable file or grid, invalid flags, incompatible grids.
pub fn load_scene(args: &RenderArgs) -> Result<LoadedScene> {
    validate(args)?;
    let limits = ReadLimits { max_bytes: args.max_input_memory.unwrap_or(ReadLimits::default().max_bytes) };
    let temperature_map: TemperatureMap = args.temperature_map.parse()?;
    // Every grid the render needs, in one read (one reader process when isolated)
    let emission_sels = || -> Result<Vec<GridSelector>> {
        match &args.emission_grid {
            Some(n) => Ok(vec![selector("--emission-grid", n)?]),
            None => EMISSION_GRID_CANDIDATES.iter().map(|n| selector("--emission-grid", n)).collect(),
        }
    };
    let temperature_sel = selector("--temperature-grid", &args.temperature_grid)?;
    let mut requests = vec![GridRequest::required(selector("--density-grid", &args.density_grid)?)];
    match args.emission {
        EmissionArg::None => {}
        EmissionArg::Blackbody => requests.push(GridRequest::required(temperature_sel)),
        EmissionArg::Grid => requests.push(GridRequest { alternatives: emission_sels()?, required: true }),
        EmissionArg::Auto => {
            let candidates = EMISSION_GRID_CANDIDATES.iter().map(|n| selector("--emission-grid", n));
            let alternatives = std::iter::once(Ok(temperature_sel)).chain(candidates).collect::<Result<_>>()?;
            requests.push(GridRequest { alternatives, required: false });
        }
    }
    let isolation = read_isolation(args.no_isolation, args.read_timeout, &limits)?;
    let mut found = isolation.read_grids(&args.file, &requests, &limits)?.into_iter();
    let density = found.next().flatten().expect("invariant: the density request is required").grid;
    let source = found.next().flatten();
    let kind = match (args.emission, &source) {
        (EmissionArg::None, _) | (EmissionArg::Auto, None) => EmissionKind::None,
        (EmissionArg::Blackbody, _) => EmissionKind::Blackbody,
        (EmissionArg::Grid, _) => EmissionKind::Grid,
        (EmissionArg::Auto, Some(f)) if f.alternative == 0 => EmissionKind::Blackbody,
        (EmissionArg::Auto, Some(_)) => EmissionKind::Grid,
    };
    let source = source.map(|f| f.grid);
    let c = args.emission_color.as_vec3();
    let emission = Emission {
        kind,
        convention: match args.convention {
            ConventionArg::Physical => Convention::Physical,
            ConventionArg::Cycles => Convention::Cycles,
        },
        scale: args.emission_scale,
        color: Rgb([c.x, c.y, c.z]),
        temperature_map,
        cutoff_kelvin: args.temperature_cutoff,
    };
    let albedo_grid = match &args.albedo_grid {
        Some(name) => Some(vdb::read_float_grid(&args.file, &selector("--albedo-grid", name)?, &limits)?),
        None => None,
    };
    let volume = Volume::build_with_albedo(&density, source.as_ref(), |v| emission.map_source(v), albedo_grid.as_ref())?;
    let up = args.camera_up.unwrap_or(match args.up_axis {
        UpAxis::Y => DVec3::Y,
        UpAxis::Z => DVec3::Z,
    });
    let (lo, hi) = if volume.is_empty() { (DVec3::splat(-1.0), DVec3::splat(1.0)) } else { volume.world_bounds() };
    let camera = match args.camera_from {
        Some(from) => Camera::look_at(from, args.camera_at.unwrap_or(0.5 * (lo + hi)), up, args.fov, args.width, args.height)?,
        None => {
            // Automatic framing: a three-quarter view from the front, slightly above
            let view = match args.up_axis {
                UpAxis::Y => DVec3::new(0.35, 0.25, 1.0),
                UpAxis::Z => DVec3::new(0.35, -1.0, 0.25),
            };
            let mut cam = Camera::frame_bounds(lo, hi, view, up, args.fov, args.width, args.height)?;
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
        Lights::build(&volume, &emission, light_sampling, proxy_resolution)?
    } else {
        Lights::default()
    };
    Ok(LoadedScene {
        scene: Scene { field: volume, medium, camera, lights },
        emission_kind: kind,
        source_grid: source.map(|g| g.name),
    })
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
