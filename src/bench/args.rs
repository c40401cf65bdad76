//! Flags of `plume bench compare`, `plume bench extremes` and `plume bench report`
//! (clap derive; doc comments are the `--help` text), and the commands they run.

use std::path::PathBuf;

use clap::Args;

use super::compare::{compare, make_reference, read_reference, CompareConfig};
use super::metrics::RELMSE_EPSILON;
use super::spec::{load, parse_methods};
use crate::error::{Error, Result};

/// Where generated scenes are written by default.
fn default_work_dir() -> PathBuf {
    std::env::temp_dir().join("plume-bench")
}

/// `plume bench compare`.
#[derive(Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct CompareArgs {
    /// The scene: a .vdb file, or `explosion:RES[:SEED]` (a generated explosion).
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
    /// Write NAME.csv, NAME.json, NAME-error.png and NAME-crops.png here.
    #[arg(long, short)]
    pub out: Option<PathBuf>,
    /// NAME of the output files (default: `compare`).
    #[arg(long, default_value = "compare")]
    pub name: String,
    /// Where generated explosions are written.
    #[arg(long, default_value_os_t = default_work_dir())]
    pub work_dir: PathBuf,
    /// `plume render` flags after `--`, e.g. `-- --density-scale 20 --albedo 0.8 --width
    /// 320 --height 240 --threads 2`. --method, --spp, --time and -o are not used here.
    #[arg(last = true)]
    pub render_flags: Vec<String>,
}

impl CompareArgs {
    /// Run the comparison: table on stdout, progress on stderr, files under `--out`.
    ///
    /// # Errors
    /// Bad flags, unreadable scene or reference, unwritable outputs.
    pub fn run(&self) -> Result<()> {
        if self.reference.is_none() && !self.make_reference {
            return Err(Error::invalid("--reference", "give a reference (--reference REF.exr) or --make-reference"));
        }
        if !(self.epsilon.is_finite() && self.epsilon > 0.0) {
            return Err(Error::invalid("--epsilon", format!("{} must be a positive number", self.epsilon)));
        }
        if let Some(dir) = &self.out {
            std::fs::create_dir_all(dir).map_err(|source| Error::Write { path: dir.clone(), source })?;
        }
        let log = |l: &str| eprintln!("plume: {l}");
        let mut scene = load(&self.scene, &self.render_flags, &self.work_dir)?;
        let methods = parse_methods(&self.methods, scene.args.kappa)?;
        let reference = match &self.reference {
            Some(p) => read_reference(p, &scene)?,
            None => {
                let t = self.reference_time.unwrap_or(16.0 * self.time);
                if !(t.is_finite() && t > 0.0) {
                    return Err(Error::invalid("--reference-time", format!("{t} must be a positive number of CPU seconds")));
                }
                let r = make_reference(&mut scene, t, &log)?;
                if let Some(p) = &self.save_reference {
                    let meta = vec![("plume:reference".to_string(), r.description.clone())];
                    crate::output::write_exr(p, r.width, r.height, &r.pixels, &meta)?;
                }
                r
            }
        };
        let cfg = CompareConfig { methods, cpu_seconds: self.time, spp: self.spp, runs: self.runs, epsilon: self.epsilon, curve_points: self.curve_points };
        let report = compare(&mut scene, &reference, &cfg, &log)?;
        print!("{report}");
        if let Some(dir) = &self.out {
            for p in report.write(dir, &self.name, true)? {
                log(&format!("wrote {}", p.display()));
            }
        }
        Ok(())
    }
}

/// `plume bench extremes`.
#[derive(Debug, Args)]
pub struct ExtremesArgs {
    /// Voxels along each edge of the test boxes (a multiple of 8).
    #[arg(long, default_value_t = 32)]
    pub box_voxels: u32,
    /// Resolution of the generated explosion of the voxel-size sweep.
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

impl ExtremesArgs {
    /// Run the sweep and print its table; exit code 4 when a check fails.
    ///
    /// # Errors
    /// A failed check, or an unwritable JSON file.
    pub fn run(&self) -> Result<()> {
        let cfg = super::extremes::ExtremesConfig { box_voxels: self.box_voxels, explosion_resolution: self.explosion_resolution, size: self.size, spp: self.spp };
        let report = super::extremes::run(&cfg)?;
        print!("{}", report.table());
        if let Some(p) = &self.json {
            let json = serde_json::to_string_pretty(&report).map_err(|e| Error::Scene(e.to_string()))?;
            crate::output::write_atomic(p, |w| std::io::Write::write_all(w, json.as_bytes()))?;
        }
        let failed = report.rows.iter().filter(|r| !r.pass).count();
        if failed > 0 {
            return Err(Error::Scene(format!("{failed} extremes checks failed (see the table)")));
        }
        Ok(())
    }
}

/// `plume bench report`.
#[derive(Debug, Args)]
pub struct ReportArgs {
    /// Directory of BENCHMARKS.md; plots go to DIR/img, CSV and JSON to DIR/bench.
    #[arg(long, short, default_value = "docs")]
    pub out: PathBuf,
    /// Multiply every CPU-time budget by this (e.g. 0.05 for a smoke test).
    #[arg(long, default_value_t = 1.0)]
    pub time_scale: f64,
    /// Explosion resolution of the thin/dense scenes.
    #[arg(long, default_value_t = 256)]
    pub resolution: u32,
    /// Directory of the shared data (smoke and cloud files).
    #[arg(long, default_value = "../shared/data")]
    pub data: PathBuf,
    /// Where generated explosions are written.
    #[arg(long, default_value_os_t = default_work_dir())]
    pub work_dir: PathBuf,
}

impl ReportArgs {
    /// Run the suite and write the report.
    ///
    /// # Errors
    /// See [`super::report::run`].
    pub fn run(&self) -> Result<()> {
        super::report::run(self)
    }
}
