//! What `plume bench compare`, `plume bench extremes` and `plume bench interpolation` are
//! asked to do, as plain settings (the binary fills them from flags), and the commands
//! they run. Each returns what it shows (the binary prints it); progress goes through the
//! `log` facade. (`plume bench report`'s are [`super::report::ReportOptions`].)

use std::path::PathBuf;

use super::compare::{compare, make_reference, read_reference, CompareConfig, CompareReport};
use super::extremes::ExtremesReport;
use super::spec::{parse_methods, BenchScene};
use plume_core::error::{Error, Result};

/// How `plume bench compare` compares (the scene comes apart).
#[derive(Clone, Debug)]
pub struct CompareOptions {
    /// Methods, comma-separated: presets (point-nee, line-nee, line-fnee, ray-march) or
    /// ESTIMATOR+LIGHTS (point|line|ray-march|blend + none|nee|fnee, e.g. line+none,
    /// blend+fnee), each optionally @N for an N³ FNEE proxy (line-fnee@16). The first is
    /// the baseline of ratios.
    pub methods: String,
    /// CPU seconds per method and run (the equal-time budget; user + system time of all
    /// threads).
    pub time: f64,
    /// Equal-spp point: runs continue to at least this spp. Default: the largest power of
    /// two that every run reaches within --time.
    pub spp: Option<u32>,
    /// Runs (seeds) per method; figures are mean ± std over runs.
    pub runs: u32,
    /// Reference image (EXR of the same size, e.g. a long `plume render`).
    pub reference: Option<PathBuf>,
    /// Compute the reference: ray-march (expected value, forward only) for emission-only
    /// scenes, a long line-fnee run otherwise.
    pub make_reference: bool,
    /// CPU seconds for --make-reference (default: 16 × --time).
    pub reference_time: Option<f64>,
    /// Also save the computed reference as EXR here.
    pub save_reference: Option<PathBuf>,
    /// ε of relMSE, (x − ref)²/(ref² + ε), an absolute radiance².
    pub epsilon: f64,
    /// Points on the error-vs-time curve (at T/2^k).
    pub curve_points: u32,
    /// Also render each method adaptively at halving noise thresholds, for the CPU time
    /// to a target error with adaptive sampling.
    pub adaptive: bool,
    /// Write NAME.csv, NAME.json, NAME-error.png and NAME-crops.png here.
    pub out: Option<PathBuf>,
    /// NAME of the output files (default: `compare`).
    pub name: String,
}

impl CompareOptions {
    /// Run the comparison; returns the report (its `Display` is the table; [`Self::write`]
    /// writes its files).
    ///
    /// # Errors
    /// Bad flags, unreadable scene or reference, unwritable outputs.
    pub fn run(&self, mut scene: BenchScene) -> Result<CompareReport> {
        if self.reference.is_none() && !self.make_reference {
            return Err(Error::invalid(
                "--reference",
                "give a reference (--reference REF.exr) or --make-reference",
            ));
        }
        if !(self.epsilon.is_finite() && self.epsilon > 0.0) {
            return Err(Error::invalid(
                "--epsilon",
                format!("{} must be a positive number", self.epsilon),
            ));
        }
        if let Some(dir) = &self.out {
            std::fs::create_dir_all(dir)
                .map_err(|source| Error::Write { path: dir.clone(), source })?;
        }
        let log = |l: &str| log::info!("{l}");
        let methods = parse_methods(&self.methods, scene.shot.scene.integrator.kappa)?;
        let reference = match &self.reference {
            Some(p) => read_reference(p, &scene)?,
            None => {
                let t = self.reference_time.unwrap_or(16.0 * self.time);
                if !(t.is_finite() && t > 0.0) {
                    return Err(Error::invalid(
                        "--reference-time",
                        format!("{t} must be a positive number of CPU seconds"),
                    ));
                }
                let r = make_reference(&mut scene, t, &log)?;
                if let Some(p) = &self.save_reference {
                    let meta = vec![("plume:reference".to_string(), r.description.clone())];
                    crate::output::write_exr(p, r.width, r.height, &r.pixels, &meta)?;
                }
                r
            }
        };
        let cfg = CompareConfig {
            methods,
            cpu_seconds: self.time,
            spp: self.spp,
            runs: self.runs,
            epsilon: self.epsilon,
            curve_points: self.curve_points,
            adaptive: self.adaptive,
        };
        compare(&mut scene, &reference, &cfg, &log)
    }

    /// Write NAME.csv, NAME.json and the plots of `report` under `out`, if given.
    ///
    /// # Errors
    /// An unwritable file.
    pub fn write(&self, report: &CompareReport) -> Result<()> {
        if let Some(dir) = &self.out {
            for p in report.write(dir, &self.name, true)? {
                log::info!("wrote {}", p.display());
            }
        }
        Ok(())
    }
}

/// `plume bench extremes`.
#[derive(Clone, Debug)]
pub struct ExtremesOptions {
    /// Voxels along each edge of the test boxes (a multiple of 8).
    pub box_voxels: u32,
    /// Resolution of the generated explosion of the voxel-size and cost sweeps.
    pub explosion_resolution: u32,
    /// Image width and height.
    pub size: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Also write the rows as JSON here.
    pub json: Option<PathBuf>,
}

impl ExtremesOptions {
    /// Run the sweep and write the JSON; returns the report (its table is
    /// [`ExtremesReport::table`]; failed checks are [`ExtremesReport::verdict`]).
    ///
    /// # Errors
    /// A sweep that cannot run, or an unwritable JSON file.
    pub fn run(&self) -> Result<ExtremesReport> {
        let cfg = super::extremes::ExtremesConfig {
            box_voxels: self.box_voxels,
            explosion_resolution: self.explosion_resolution,
            size: self.size,
            spp: self.spp,
        };
        let report = super::extremes::run(&cfg)?;
        if let Some(p) = &self.json {
            let json =
                serde_json::to_string_pretty(&report).map_err(|e| Error::Scene(e.to_string()))?;
            plume_core::fs::write_atomic(p, |w| std::io::Write::write_all(w, json.as_bytes()))?;
        }
        Ok(report)
    }
}

/// `plume bench interpolation`.
#[derive(Clone, Debug)]
pub struct InterpolationOptions {
    /// What to measure.
    pub config: super::interpolation::InterpolationConfig,
    /// Also write the figures as JSON here.
    pub json: Option<PathBuf>,
}

impl InterpolationOptions {
    /// Run the benchmark, writing the JSON and picture files; returns the Markdown.
    ///
    /// # Errors
    /// See [`super::interpolation::run`]; an unwritable JSON file.
    pub fn run(&self) -> Result<String> {
        let report = super::interpolation::run(&self.config, &|l| log::info!("{l}"))?;
        let picture = self.config.closeup.as_ref().map(|c| c.path.display().to_string());
        let markdown = report.markdown(&self.config.command(), picture.as_deref());
        super::write_json(&self.json, &report)?;
        Ok(markdown)
    }
}
