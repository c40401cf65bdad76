//! `plume bench …`: flags of the benchmarks, turned into the library's options. The
//! render flags of `plume bench compare` (after `--`) go through the `plume render`
//! conversion, so every render flag, scene file and validation applies.
//!
//! `plume bench compare` and `plume bench flare` are in `bench/compare.rs`; the other
//! commands' flags are here.

use std::path::PathBuf;

use clap::{ArgMatches, Args, Subcommand};
use plume::bench::interpolation::{closeup::CloseupConfig, rule::RuleConfig, InterpolationConfig};
use plume::bench::options::{ExtremesOptions, InterpolationOptions};
use plume::bench::report::{Budgets, ReportOptions};
use plume::bench::write_json;
use plume_core::error::{Error, Result};
use plume_engine::integrator::MisHeuristic;

use super::environment::{bench_work_dir, working_dir};
use super::flags::choice;

mod compare;

use compare::{compare, flare};
pub use compare::{CompareArgs, FlareArgs};

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
    Compare(Box<CompareArgs>),
    /// Numerical extremes: density scales, temperatures, voxel sizes and NaN/inf/negative
    /// voxels, checked against closed forms; and the cost of a walk from 1e-6 to 1e6 times
    /// the density, per method.
    Extremes(ExtremesArgs),
    /// Trilinear against nearest reconstruction on real files: cost per sample (linear ÷
    /// nearest, samples per CPU second), dual-pyramid memory, plume's emission rule
    /// against Cycles', and a close-up picture pair (--pictures).
    Interpolation(InterpolationArgs),
    /// Several volumes: cost per sample (samples per CPU second, relative to the fewest)
    /// and memory per instance of one shared explosion placed 1 … 1000 times.
    Volumes(VolumesArgs),
    /// The paper's solar-flare experiment: a generated flare brick cache
    /// (≈33 GB at 4096³, made once in --work-dir) rendered out of core with scattering,
    /// FNEE against classic NEE (brick table) at equal spp: RMSE against a longer
    /// reference, core-hours, picture. `bench compare` with this preset.
    Flare(FlareArgs),
    /// The README's demo (the clean first picture): the sample scene file rendered
    /// as `scripts/demo.sh` renders it, timed per seed, and its relRMSE against long
    /// references (rendered once into --work-dir, then kept), with the largest speck.
    Demo(DemoArgs),
    /// The whole benchmark suite: writes docs/BENCHMARKS.md, its plots and data (--quick:
    /// the short form, under 20 minutes on 2 cores).
    Report(ReportArgs),
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
    #[arg(long, value_parser = choice::<MisHeuristic>(), default_value_t = MisHeuristic::Power)]
    pub mis: MisHeuristic,
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

/// `plume bench extremes`.
#[derive(Debug, Args)]
pub struct ExtremesArgs {
    /// Voxels along each edge of the test boxes (a multiple of 8).
    #[arg(long, default_value_t = 32)]
    pub box_voxels: u32,
    /// Resolution of the generated explosion of the voxel-size and cost sweeps.
    #[arg(long, default_value_t = 64)]
    pub explosion_resolution: u32,
    /// Image width and height.
    #[arg(long, default_value_t = 48)]
    pub size: u32,
    /// Samples per pixel.
    #[arg(long, default_value_t = 16)]
    pub spp: u32,
    /// Also write the rows as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// `plume bench volumes`.
#[derive(Debug, Args)]
pub struct VolumesArgs {
    /// Resolution of the generated explosion.
    #[arg(long, default_value_t = 32)]
    pub resolution: u32,
    /// Numbers of instances, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "1,10,100,1000")]
    pub instances: Vec<usize>,
    /// Image width and height.
    #[arg(long, default_value_t = 64)]
    pub size: u32,
    /// Samples per pixel.
    #[arg(long, default_value_t = 8)]
    pub spp: u32,
    /// Renders per number of instances (the least CPU time is kept).
    #[arg(long, default_value_t = 3)]
    pub repeats: u32,
    /// Also write the figures as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// `plume bench demo`.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// The scene file the README's main command renders (run scripts/demo.sh once first:
    /// it makes the volume).
    #[arg(long, default_value = "data/explosion.toml")]
    pub scene: PathBuf,
    /// Seeds of the timed renders, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "0,2,3")]
    pub seeds: Vec<u64>,
    /// Samples per pixel of each reference render.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..))]
    pub reference_spp: u32,
    /// Seeds of the reference renders (at least 2; none of --seeds).
    #[arg(long, value_delimiter = ',', default_value = "11,12")]
    pub reference_seeds: Vec<u64>,
    /// Converged renders of the same scene with other seeds, made elsewhere (at least 2,
    /// comma-separated): used instead of rendering --reference-seeds.
    #[arg(long, value_delimiter = ',')]
    pub references: Vec<PathBuf>,
    /// Where the renders go and the references are kept.
    #[arg(long, default_value_os_t = bench_work_dir().join("demo"))]
    pub work_dir: PathBuf,
    /// The time target: wall seconds of one render.
    #[arg(long, default_value_t = 60.0)]
    pub target_seconds: f64,
    /// The error target: relRMSE over the smoke.
    #[arg(long, default_value_t = 0.03)]
    pub target_rel_rmse: f64,
    /// Also write the figures as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// `plume bench interpolation`.
#[derive(Debug, Args)]
pub struct InterpolationArgs {
    /// Directory of the shared data (explosion/, smoke/).
    #[arg(long, default_value = "../shared/data")]
    pub data: PathBuf,
    /// Files of the cost and memory tables, comma-separated: kelvin40 (Mantaflow explosion,
    /// Kelvin), blender40 (Blender's cache, flame_noise), r192 (the larger run), smoke1
    /// (openvdb.org).
    #[arg(long, value_delimiter = ',', default_value = "kelvin40,blender40,r192,smoke1")]
    pub files: Vec<String>,
    /// Image width of the cost renders.
    #[arg(long, default_value_t = 160)]
    pub width: u32,
    /// Image height of the cost renders.
    #[arg(long, default_value_t = 120)]
    pub height: u32,
    /// Target CPU seconds of one timed nearest render (sets the spp; linear renders the
    /// same spp).
    #[arg(long, default_value_t = 0.5)]
    pub time: f64,
    /// Timed renders per reconstruction and method, alternated; medians are reported.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=100))]
    pub repeats: u32,
    /// Threads of the cost renders (0 = all cores). One by default: CPU time is then the
    /// work done, not idle workers.
    #[arg(long, default_value_t = 1)]
    pub threads: usize,
    /// Files of the emission-rule comparison, under --data, comma-separated (default:
    /// every explosion/mantaflow_explosion_kelvin_*.vdb).
    #[arg(long, value_delimiter = ',')]
    pub rule_files: Vec<PathBuf>,
    /// Image width of the emission-rule comparison.
    #[arg(long, default_value_t = 320)]
    pub rule_width: u32,
    /// Image height of the emission-rule comparison.
    #[arg(long, default_value_t = 240)]
    pub rule_height: u32,
    /// Largest index-space step of the emission-rule march, in voxels.
    #[arg(long, default_value_t = 0.125)]
    pub rule_step: f64,
    /// Write the close-up pair (nearest | linear) as this PNG.
    #[arg(long)]
    pub pictures: Option<PathBuf>,
    /// Width of each half of the close-up.
    #[arg(long, default_value_t = 400)]
    pub closeup_width: u32,
    /// Height of the close-up.
    #[arg(long, default_value_t = 300)]
    pub closeup_height: u32,
    /// Samples per pixel of the close-up.
    #[arg(long, default_value_t = 8)]
    pub closeup_spp: u32,
    /// Voxel edge at the close-up's focus, in pixels.
    #[arg(long, default_value_t = 6.0)]
    pub closeup_pixels_per_voxel: f64,
    /// Also write the figures as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

impl InterpolationArgs {
    /// The library's configuration.
    fn config(&self) -> InterpolationConfig {
        InterpolationConfig {
            data: self.data.clone(),
            files: self.files.iter().filter(|f| !f.is_empty()).cloned().collect(),
            width: self.width,
            height: self.height,
            cpu_seconds: self.time,
            repeats: self.repeats,
            threads: self.threads,
            rule: RuleConfig {
                files: self.rule_files.clone(),
                width: self.rule_width,
                height: self.rule_height,
                step_voxels: self.rule_step,
            },
            closeup: self.pictures.as_ref().map(|path| CloseupConfig {
                path: path.clone(),
                file: PathBuf::from(plume::bench::interpolation::CLOSEUP_FILE),
                width: self.closeup_width,
                height: self.closeup_height,
                spp: self.closeup_spp,
                pixels_per_voxel: self.closeup_pixels_per_voxel,
                threads: 0,
            }),
        }
    }
}

/// `plume bench report`.
#[derive(Debug, Args)]
pub struct ReportArgs {
    /// Directory of BENCHMARKS.md; plots go to DIR/img, CSV, JSON and scene files to
    /// DIR/bench.
    #[arg(long, short, default_value = "docs")]
    pub out: PathBuf,
    /// The quick form: a quarter of the CPU-time budgets, a 128³ explosion, no README demo.
    #[arg(long)]
    pub quick: bool,
    /// Multiply every CPU-time budget by this (default: 1, or 0.25 with --quick).
    #[arg(long)]
    pub time_scale: Option<f64>,
    /// Explosion resolution of the thin, dense and proxy sections (default: 256, or 128
    /// with --quick).
    #[arg(long, value_parser = clap::value_parser!(u32).range(8..=4096))]
    pub resolution: Option<u32>,
    /// Directory of the shared data (smoke, cloud and Blender files).
    #[arg(long, default_value = "../shared/data")]
    pub data: PathBuf,
    /// Where generated explosions, saved references and the demo's renders are written.
    #[arg(long, default_value_os_t = bench_work_dir())]
    pub work_dir: PathBuf,
}

/// Run one `plume bench …` command.
///
/// # Errors
/// Bad flags, unreadable inputs, unwritable outputs, failed extremes checks.
pub fn run(command: BenchCommand, _matches: Option<&ArgMatches>) -> Result<()> {
    match command {
        BenchCommand::Methods(args) => {
            let regimes = plume::bench::methods::parse_regimes(&args.regimes)
                .map_err(|e| rename(e, "regimes", "--regimes"))?;
            let regimes: Vec<(&str, f64)> = regimes.iter().map(|(n, v)| (n.as_str(), *v)).collect();
            let report = plume::bench::methods::run(
                args.resolution,
                args.width,
                args.height,
                args.time,
                args.reference_time,
                args.threads,
                args.mis,
                args.proxy_resolution,
                &regimes,
                &|l| log::info!("{l}"),
            )?;
            print!("{report}");
            write_json(&args.json, &report)
        }
        BenchCommand::Core(args) => {
            let report = plume::bench::core::run(args.resolution, args.threads, &args.ttfs_file)?;
            print!("{report}");
            write_json(&args.json, &report)
        }
        BenchCommand::Compare(args) => compare(&args),
        BenchCommand::Extremes(args) => {
            let report = ExtremesOptions {
                box_voxels: args.box_voxels,
                explosion_resolution: args.explosion_resolution,
                size: args.size,
                spp: args.spp,
                json: args.json,
            }
            .run()?;
            print!("{}\n{}", report.table(), plume::bench::extremes::cost_table(&report.cost));
            report.verdict()
        }
        BenchCommand::Interpolation(args) => interpolation(&args),
        BenchCommand::Volumes(args) => {
            let report = plume::bench::volumes::run(&plume::bench::volumes::VolumesConfig {
                resolution: args.resolution,
                instances: args.instances,
                size: args.size,
                spp: args.spp,
                repeats: args.repeats,
            })?;
            print!("{}", report.table());
            write_json(&args.json, &report)?;
            report.verdict()
        }
        BenchCommand::Flare(args) => flare(&args),
        BenchCommand::Demo(args) => demo(args),
        BenchCommand::Report(args) => ReportOptions {
            out: args.out,
            budgets: Budgets::form(args.quick).with_overrides(args.time_scale, args.resolution),
            data: args.data,
            work_dir: args.work_dir,
            working_dir: working_dir(),
            exe: std::env::current_exe().ok(),
        }
        .run(),
    }
}

/// `plume bench interpolation`: the budgets checked, then the tables on stdout.
fn interpolation(args: &InterpolationArgs) -> Result<()> {
    if !(args.time.is_finite() && args.time > 0.0) {
        return Err(Error::invalid(
            "--time",
            format!("{} must be a positive number of CPU seconds", args.time),
        ));
    }
    if !(args.closeup_pixels_per_voxel.is_finite() && args.closeup_pixels_per_voxel > 0.0) {
        return Err(Error::invalid(
            "--closeup-pixels-per-voxel",
            format!("{} must be positive", args.closeup_pixels_per_voxel),
        ));
    }
    let markdown = InterpolationOptions { config: args.config(), json: args.json.clone() }.run()?;
    print!("{markdown}");
    Ok(())
}

/// `plume bench demo`: the targets checked, then the README's demo rendered by this binary.
fn demo(args: DemoArgs) -> Result<()> {
    for (flag, v) in
        [("--target-seconds", args.target_seconds), ("--target-rel-rmse", args.target_rel_rmse)]
    {
        if !(v.is_finite() && v > 0.0) {
            return Err(Error::invalid(flag, format!("{v} must be a positive number")));
        }
    }
    let exe = std::env::current_exe()
        .map_err(|e| Error::Scene(format!("cannot find the plume binary: {e}")))?;
    let config = plume::bench::demo::DemoConfig {
        exe,
        scene: args.scene,
        seeds: args.seeds,
        reference_spp: args.reference_spp,
        reference_seeds: args.reference_seeds,
        references: args.references,
        work_dir: args.work_dir,
        working_dir: working_dir(),
        target_seconds: args.target_seconds,
        target_rel_rmse: args.target_rel_rmse,
    };
    let report = plume::bench::demo::run(&config)?;
    print!("{}", report.table());
    write_json(&args.json, &report)
}

/// An error's key renamed to the flag.
fn rename(e: Error, key: &str, flag: &str) -> Error {
    match e {
        Error::InvalidArgument { flag: k, message } if k == key => Error::invalid(flag, message),
        e => e,
    }
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::compare::compare_scene;
    use super::*;
    use crate::cli::{Cli, Command};

    #[test]
    fn render_flags_go_through_the_render_parser() {
        let args = |flags: &[&str]| -> CompareArgs {
            let argv = ["plume", "bench", "compare", "x.vdb", "--make-reference", "--"]
                .into_iter()
                .chain(flags.iter().copied());
            match Cli::try_parse_from(argv).unwrap().command {
                Command::Bench(BenchCommand::Compare(a)) => *a,
                _ => unreachable!(),
            }
        };
        let e = compare_scene(&args(&["--no-such-flag"])).err().unwrap();
        assert!(e.to_string().contains("no-such-flag"), "{e}");
        let e = compare_scene(&args(&["--albedo", "3"])).err().unwrap();
        assert!(e.to_string().contains("--albedo"), "{e}");
    }
}
