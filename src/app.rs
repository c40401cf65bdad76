//! The commands behind the CLI: `render`, `info`, `synth`. `main.rs` only parses
//! arguments, calls [`run`] and turns an error into a one-line message and exit code.

use std::io::IsTerminal;
use std::path::Path;
use std::time::Instant;

use glam::DVec3;
use indicatif::{ProgressBar, ProgressStyle};

use crate::camera::Camera;
use crate::cli::{
    Cli, Command, ConventionArg, EmissionArg, EstimatorArg, InfoArgs, LightSamplingArg, MethodArg, MisArg, RenderArgs,
    SynthCommand, UpAxis,
};
use crate::color::Rgb;
use crate::error::{Error, Result};
use crate::integrator::{Integrator, LightSampling, Lights, LineTrace, MisHeuristic, Scene};
use crate::medium::{Convention, Emission, EmissionKind, Estimator, Medium, TemperatureMap};
use crate::render::{render, RenderSettings, SampleBudget};
use crate::stats::{cpu_seconds, peak_rss_bytes, RenderStats};
use crate::vdb::{self, FloatGrid, GridSelector, ReadLimits};
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
        Command::Render(args) => render_command(&args, command_line),
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
    }
}

fn info_command(args: &InfoArgs) -> Result<()> {
    let grids = vdb::list_grids(&args.file)?;
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

/// Read a grid, mapping "not found" to `Ok(None)`.
fn read_optional(path: &Path, sel: &GridSelector, limits: &ReadLimits) -> Result<Option<FloatGrid>> {
    match vdb::read_float_grid(path, sel, limits) {
        Ok(g) => Ok(Some(g)),
        Err(Error::GridNotFound { .. }) => Ok(None),
        Err(e) => Err(e),
    }
}

fn check_finite_nonneg(flag: &str, v: f64) -> Result<()> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(Error::invalid(flag, format!("{v} must be a finite number ≥ 0")))
    }
}

/// Validate the render flags that clap cannot.
fn validate(args: &RenderArgs) -> Result<()> {
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
    if !(0.0..=1.0).contains(&args.albedo) {
        return Err(Error::invalid("--albedo", format!("{} is not in [0, 1]", args.albedo)));
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
    if args.output.extension().is_none_or(|e| !e.eq_ignore_ascii_case("exr")) {
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
    let density = vdb::read_float_grid(&args.file, &selector("--density-grid", &args.density_grid)?, &limits)?;
    let temperature_sel = selector("--temperature-grid", &args.temperature_grid)?;
    let (kind, source) = match args.emission {
        EmissionArg::None => (EmissionKind::None, None),
        EmissionArg::Blackbody => (EmissionKind::Blackbody, Some(vdb::read_float_grid(&args.file, &temperature_sel, &limits)?)),
        EmissionArg::Grid => {
            let names: Vec<String> = match &args.emission_grid {
                Some(n) => vec![n.clone()],
                None => EMISSION_GRID_CANDIDATES.iter().map(|s| (*s).to_string()).collect(),
            };
            let mut found = None;
            for n in &names {
                if let Some(g) = read_optional(&args.file, &selector("--emission-grid", n)?, &limits)? {
                    found = Some(g);
                    break;
                }
            }
            match found {
                Some(g) => (EmissionKind::Grid, Some(g)),
                None => {
                    // Report the first candidate as missing, listing what exists
                    vdb::read_float_grid(&args.file, &selector("--emission-grid", &names[0])?, &limits)?;
                    unreachable!("invariant: the grid was just not found");
                }
            }
        }
        EmissionArg::Auto => {
            if let Some(t) = read_optional(&args.file, &temperature_sel, &limits)? {
                (EmissionKind::Blackbody, Some(t))
            } else {
                let mut found = None;
                for n in EMISSION_GRID_CANDIDATES {
                    if let Some(g) = read_optional(&args.file, &selector("--emission-grid", n)?, &limits)? {
                        found = Some(g);
                        break;
                    }
                }
                match found {
                    Some(g) => (EmissionKind::Grid, Some(g)),
                    None => (EmissionKind::None, None),
                }
            }
        }
    };
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
    let volume = Volume::build(&density, source.as_ref(), |v| emission.map_source(v))?;
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
    let medium = Medium { sigma_t: args.density_scale, albedo: args.albedo, g: args.g, emission };
    // Light-sampling structures, only for the technique in use and only when paths scatter
    let (_, light_sampling) = method(args);
    let lights = if args.albedo > 0.0 && args.max_depth > 0 {
        Lights::build(&volume, &emission, light_sampling, args.proxy_resolution)?
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
        max_depth: if args.albedo > 0.0 { args.max_depth } else { 0 },
        environment: args.environment.map(|e| {
            let e = e.as_vec3();
            Rgb([e.x, e.y, e.z])
        }),
    }
}

fn estimator(args: &RenderArgs) -> Estimator {
    method(args).0
}

fn render_command(args: &RenderArgs, command_line: &str) -> Result<()> {
    let start = Instant::now();
    validate(args)?;
    // Fail before loading or rendering if an output cannot be written
    for path in std::iter::once(&args.output).chain(args.preview.iter()).chain(args.stats.iter()) {
        crate::output::check_writable(path)?;
    }
    let loaded = load_scene(args)?;
    let scene = &loaded.scene;
    let volume = &scene.field;
    let quiet = args.quiet;
    let warn = |msg: String| {
        eprintln!("plume: warning: {msg}");
    };
    if volume.report.density_clamped > 0 {
        warn(format!("{}: {} density voxels were NaN, infinite or negative and were set to 0", args.file.display(), volume.report.density_clamped));
    }
    if volume.report.source_invalid > 0 {
        warn(format!("{}: {} emission-source voxels were NaN, infinite or negative and were set to 0", args.file.display(), volume.report.source_invalid));
    }
    if volume.is_empty() {
        warn(format!("{}: grid {:?} is empty; the image will be transparent black", args.file.display(), args.density_grid));
    }
    if loaded.emission_kind == EmissionKind::None && args.emission == EmissionArg::Auto {
        warn(format!("{}: no temperature or emission grid found; rendering absorption only", args.file.display()));
    }
    if estimator(args) == Estimator::Point && scene.medium.emission.emits_without_density() {
        warn("--estimator point scores only at collisions: emission where density is 0 (allowed by --convention cycles) is not rendered".into());
    }
    let settings = RenderSettings {
        budget: match (args.spp, args.time) {
            (_, Some(t)) => SampleBudget::Time(t),
            (Some(n), None) => SampleBudget::Spp(n),
            (None, None) => SampleBudget::Spp(64),
        },
        seed: args.seed,
        threads: args.threads,
        first_sample: 0,
        integrator: integrator(args),
    };
    if let Some(dp) = &args.debug_pixel {
        // Replay one pixel sample and print its path
        let (x, y, s) = crate::cli::parse_debug_pixel(dp).map_err(|m| Error::invalid("--debug-pixel", m))?;
        let (ray, mut sampler) = crate::render::pixel_sample(scene, args.seed, x, y, s);
        let mut trace = LineTrace::default();
        let mut counters = crate::integrator::Counters::default();
        let l = settings.integrator.li(scene, &ray, &mut sampler, &mut counters, &mut trace);
        for line in &trace.0 {
            eprintln!("plume: debug {x},{y},{s}: {line}");
        }
        println!("{:?}", l);
        return Ok(());
    }
    let bar = if !quiet && std::io::stderr().is_terminal() {
        let total = match settings.budget {
            SampleBudget::Spp(n) => u64::from(n),
            SampleBudget::Time(_) => 0,
        };
        let pb = if total > 0 { ProgressBar::new(total) } else { ProgressBar::new_spinner() };
        pb.set_style(
            ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} spp {msg}")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        Some(pb)
    } else {
        None
    };
    let time_to_first_sample = start.elapsed().as_secs_f64();
    let result = render(scene, &settings, &|done, _| {
        if let Some(pb) = &bar {
            pb.set_position(done);
        }
    });
    if let Some(pb) = &bar {
        pb.finish_and_clear();
    }
    let pixels = result.film.average(result.spp);
    let cpu = cpu_seconds();
    let est_name = format!("{:?}", settings.integrator.estimator);
    let metadata: Vec<(String, String)> = vec![
        ("plume:version".into(), env!("CARGO_PKG_VERSION").into()),
        ("plume:commandLine".into(), command_line.into()),
        ("plume:input".into(), args.file.display().to_string()),
        ("plume:spp".into(), result.spp.to_string()),
        ("plume:seed".into(), args.seed.to_string()),
        ("plume:estimator".into(), est_name.clone()),
        ("plume:renderSeconds".into(), format!("{:.3}", result.render_seconds)),
        ("plume:cpuSeconds".into(), format!("{cpu:.3}")),
    ];
    crate::output::write_exr(&args.output, args.width, args.height, &pixels, &metadata)?;
    if let Some(p) = &args.preview {
        let exposure = args.exposure.map_or_else(|| crate::output::auto_exposure(&pixels), |ev| 2f32.powf(ev));
        crate::output::write_png(p, args.width, args.height, &pixels, exposure)?;
    }
    let wall = start.elapsed().as_secs_f64();
    let samples = result.counters.samples as f64;
    if let Some(c) = result.counters.first_nonfinite {
        warn(format!("{} non-finite samples dropped; first at --debug-pixel {},{},{}", result.counters.nonfinite_samples, c.0, c.1, c.2));
    }
    if let Some(path) = &args.stats {
        let stats = RenderStats {
            plume_version: env!("CARGO_PKG_VERSION").into(),
            input: args.file.display().to_string(),
            spp: result.spp,
            seed: args.seed,
            wall_seconds: wall,
            render_seconds: result.render_seconds,
            time_to_first_sample_seconds: time_to_first_sample,
            cpu_seconds: cpu,
            core_hours: cpu / 3600.0,
            samples_per_second: samples / result.render_seconds.max(1e-9),
            samples_per_cpu_second: samples / cpu.max(1e-9),
            peak_rss_bytes: peak_rss_bytes(),
            threads: if args.threads == 0 { rayon::current_num_threads() } else { args.threads },
            width: args.width,
            height: args.height,
            estimator: est_name,
            volume_bytes: volume.memory_bytes() as u64,
            counters: result.counters,
            density_voxels_clamped: volume.report.density_clamped,
            source_voxels_clamped: volume.report.source_invalid,
        };
        let json = serde_json::to_string_pretty(&stats).map_err(|e| Error::Scene(e.to_string()))?;
        crate::output::write_atomic(path, |w| std::io::Write::write_all(w, json.as_bytes()))?;
    }
    if !quiet {
        eprintln!(
            "plume: {} ({}x{}, {} spp, {:?}) in {:.2} s ({:.2} s to first sample, {:.3} core-h)",
            args.output.display(),
            args.width,
            args.height,
            result.spp,
            settings.integrator.estimator,
            wall,
            time_to_first_sample,
            cpu / 3600.0
        );
    }
    Ok(())
}
