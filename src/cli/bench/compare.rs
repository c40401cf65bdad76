//! `plume bench compare` and `plume bench flare` (a compare with a preset): their flags,
//! the scene of a comparison read through the `plume render` conversion (every render
//! flag, scene file and validation applies), and the run.

use std::path::PathBuf;

use clap::{Args, CommandFactory, FromArgMatches};
use plume::bench::metrics::RELMSE_EPSILON;
use plume::bench::options::CompareOptions;
use plume_core::error::{Error, Result};

use crate::cli::environment::bench_work_dir;
use crate::cli::files::{synth_flare_command, SynthFlareArgs};
use crate::cli::logger::{set_key_names, KeyNames};
use crate::cli::request::RenderRequest;
use crate::cli::{Cli, Command};

/// `plume bench flare`.
#[derive(Debug, Args)]
pub struct FlareArgs {
    /// Flare resolution (voxels per axis): 4096 is the paper's ≈30 GB.
    #[arg(long, default_value_t = 4096, value_parser = clap::value_parser!(u32).range(8..=65536))]
    pub resolution: u32,
    /// Equal-spp point of both methods (the paper: 128).
    #[arg(long, default_value_t = 16)]
    pub spp: u32,
    /// CPU seconds of the line-fnee reference (two independent halves).
    #[arg(long, default_value_t = 1800.0)]
    pub reference_time: f64,
    /// Scattering albedo.
    #[arg(long, default_value_t = 0.5)]
    pub albedo: f64,
    /// Image size.
    #[arg(long, default_value_t = 320)]
    pub width: u32,
    /// Image size.
    #[arg(long, default_value_t = 240)]
    pub height: u32,
    /// Write flare.csv, flare.json and the plots here.
    #[arg(long, short)]
    pub out: Option<PathBuf>,
    /// Where the flare cache is made (once; reused while it is current).
    #[arg(long, default_value_os_t = bench_work_dir())]
    pub work_dir: PathBuf,
    /// More `plume render` flags after `--` (e.g. `-- --interpolation nearest`).
    #[arg(last = true)]
    pub render_flags: Vec<String>,
}

/// `plume bench compare`.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct CompareArgs {
    /// The scene: a .vdb file, `explosion:RES[:SEED]` (a generated explosion), or a
    /// scene file (.toml; its volume file may be such a spec).
    pub scene: String,
    /// Methods, comma-separated: presets (point-nee, line-nee, line-fnee, ray-march) or
    /// ESTIMATOR+LIGHTS (point|line|ray-march|blend + none|nee|fnee, e.g. line+none,
    /// blend+fnee), each optionally @N for an N³ FNEE proxy (line-fnee@16). The first is
    /// the baseline of ratios.
    #[arg(long, default_value = "point-nee,line-nee,line-fnee,ray-march")]
    pub methods: String,
    /// CPU seconds per method and run (the equal-time budget; user + system time of all
    /// threads).
    #[arg(long, default_value_t = 8.0)]
    pub time: f64,
    /// Equal-spp point: runs continue to at least this spp. Default: the largest power of
    /// two that every run reaches within --time.
    #[arg(long)]
    pub spp: Option<u32>,
    /// Runs (seeds) per method; figures are mean ± std over runs.
    #[arg(long, default_value_t = 3)]
    pub runs: u32,
    /// Reference image (EXR of the same size, e.g. a long `plume render`).
    #[arg(long, conflicts_with = "make_reference")]
    pub reference: Option<PathBuf>,
    /// Compute the reference: ray-march (expected value, forward only) for emission-only
    /// scenes, a long line-fnee run otherwise.
    #[arg(long)]
    pub make_reference: bool,
    /// CPU seconds for --make-reference (default: 16 × --time).
    #[arg(long)]
    pub reference_time: Option<f64>,
    /// Also save the computed reference as EXR here.
    #[arg(long)]
    pub save_reference: Option<PathBuf>,
    /// ε of relMSE, (x − ref)²/(ref² + ε), an absolute radiance².
    #[arg(long, default_value_t = RELMSE_EPSILON)]
    pub epsilon: f64,
    /// Points on the error-vs-time curve (at T/2^k).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..=12))]
    pub curve_points: u32,
    /// Also render each method adaptively (--noise-threshold 0.1, 0.05, 0.025, … until a
    /// render spends --time), for the CPU time to relRMSE 0.05/0.02/0.01 with adaptive
    /// sampling, and each adaptive render against uniform sampling at equal CPU.
    #[arg(long)]
    pub adaptive: bool,
    /// Write NAME.csv, NAME.json, NAME-error.png and NAME-crops.png here.
    #[arg(long, short)]
    pub out: Option<PathBuf>,
    /// NAME of the output files (default: `compare`).
    #[arg(long, default_value = "compare")]
    pub name: String,
    /// Where generated explosions are written.
    #[arg(long, default_value_os_t = bench_work_dir())]
    pub work_dir: PathBuf,
    /// `plume render` flags after `--`, e.g. `-- --density-scale 20 --albedo 0.8 --width
    /// 320 --height 240 --threads 2`. --method, --spp, --time and -o are not used here.
    #[arg(last = true)]
    pub render_flags: Vec<String>,
}

/// `plume bench flare`: make the cache if it is missing, then `bench compare` of line-fnee
/// and line-nee (brick table: the voxel table of a 4096³ flare would need about 90 GiB)
/// at `--spp`, one run each, against a computed line-fnee reference.
pub(super) fn flare(args: &FlareArgs) -> Result<()> {
    let cache = args.work_dir.join(format!("flare{}.plume", args.resolution));
    if !cache.exists() {
        std::fs::create_dir_all(&args.work_dir).map_err(|e| {
            Error::invalid("--work-dir", format!("{}: {e}", args.work_dir.display()))
        })?;
        eprintln!("plume: making {} (once)", cache.display());
        synth_flare_command(&SynthFlareArgs {
            resolution: args.resolution,
            output: cache.clone(),
            seed: 1,
        })?;
    }
    let mut render_flags: Vec<String> = [
        "--nee-table",
        "brick",
        "--albedo",
        &args.albedo.to_string(),
        "--width",
        &args.width.to_string(),
        "--height",
        &args.height.to_string(),
    ]
    .iter()
    .map(ToString::to_string)
    .collect();
    render_flags.extend(args.render_flags.iter().cloned());
    let compare = CompareArgs {
        scene: cache.display().to_string(),
        methods: "line-fnee,line-nee".into(),
        // Equal spp: every run stops at --spp (the CPU budget is reached at once)
        time: 1e-3,
        spp: Some(args.spp),
        runs: 1,
        reference: None,
        make_reference: true,
        reference_time: Some(args.reference_time),
        save_reference: args.out.as_ref().map(|o| o.join("flare-reference.exr")),
        epsilon: RELMSE_EPSILON,
        curve_points: 1,
        adaptive: false,
        out: args.out.clone(),
        name: "flare".into(),
        work_dir: args.work_dir.clone(),
        render_flags,
    };
    self::compare(&compare)
}

/// `plume bench compare`: the table on stdout, then the files under `--out`.
pub(super) fn compare(args: &CompareArgs) -> Result<()> {
    let options = compare_options(args);
    let report = options.run(compare_scene(args)?)?;
    print!("{report}");
    options.write(&report)
}

/// The library's options of `plume bench compare`.
fn compare_options(args: &CompareArgs) -> CompareOptions {
    CompareOptions {
        methods: args.methods.clone(),
        time: args.time,
        spp: args.spp,
        runs: args.runs,
        reference: args.reference.clone(),
        make_reference: args.make_reference,
        reference_time: args.reference_time,
        save_reference: args.save_reference.clone(),
        epsilon: args.epsilon,
        curve_points: args.curve_points,
        adaptive: args.adaptive,
        out: args.out.clone(),
        name: args.name.clone(),
    }
}

/// The scene of `plume bench compare`: SCENE and the render flags after `--`, through
/// the `plume render` conversion (the output is a placeholder, never written).
pub(super) fn compare_scene(args: &CompareArgs) -> Result<plume::bench::spec::BenchScene> {
    let placeholder = std::env::temp_dir().join("plume-bench-unused.exr");
    let mut argv: Vec<String> = vec![
        "plume".into(),
        "render".into(),
        args.scene.clone(),
        "-o".into(),
        placeholder.display().to_string(),
    ];
    argv.extend(args.render_flags.iter().cloned());
    let bad = |e: clap::Error| {
        let msg = e.to_string();
        Error::invalid(
            "render flags",
            msg.lines().next().unwrap_or_default().trim_start_matches("error: ").to_string(),
        )
    };
    let matches = Cli::command().try_get_matches_from(&argv).map_err(bad)?;
    let cli = Cli::from_arg_matches(&matches).map_err(bad)?;
    let Command::Render(render) = cli.command else {
        unreachable!("invariant: parsed a render command")
    };
    let sub = matches.subcommand().map(|(_, m)| m).expect("invariant: a render subcommand");
    let request = RenderRequest::try_from((&*render, sub))?;
    set_key_names(KeyNames::of(&request.origin));
    plume::bench::spec::load(
        request.shot.clone().into_inner(),
        args.render_flags.clone(),
        &args.work_dir,
    )
    .map_err(|e| request.origin.explain(e))
}
