//! The report being written ([`Suite`]): its options, the document so far, what was
//! skipped, the references and comparisons shared between sections; the commands that
//! reproduce a comparison, the scene files they read, and one comparison of methods
//! written as a section ([`Suite::section`]).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use super::budgets::ReportOptions;
use super::groups::Base;
use crate::bench::compare::{compare, CompareConfig, CompareReport, Reference};
use crate::bench::numbers::{arg, num};
use crate::bench::spec::{bench_shot, load, parse_methods, BenchScene};
use plume_core::error::{Error, Result};
use plume_scene::file::{to_toml_as_is, with_keys};

/// CPU seconds per run (× the time scale).
pub(super) const RUN_SECONDS: f64 = 6.0;
/// CPU seconds of each computed reference (× the time scale).
pub(super) const REFERENCE_SECONDS: f64 = 96.0;
/// Runs (seeds) per method.
pub(super) const RUNS: u32 = 3;
/// Points of the error-vs-time curves of the method sections.
pub(super) const CURVE_POINTS: u32 = 4;

/// Where a comparison's reference comes from, as its command says it.
pub(super) enum RefArg<'a> {
    /// Computed with this many CPU seconds.
    Make(f64),
    /// Computed, then saved here (for the commands that read it).
    MakeAndSave(f64, &'a Path),
    /// Read from this file.
    Given(&'a Path),
}

/// The report being written.
pub(super) struct Suite<'a> {
    /// What to run and where to write.
    pub(super) args: &'a ReportOptions,
    /// The sections so far.
    pub(super) md: String,
    /// What was not run, in words, for the header.
    pub(super) skipped: Vec<String>,
    /// The references of the option groups' base scenes, made once.
    pub(super) references: Vec<(Base, Reference)>,
    /// The option groups' comparisons by scene-file text: a default that several groups
    /// share is measured once.
    pub(super) measured: Vec<(String, CompareReport)>,
    /// Where progress lines go.
    pub(super) log: &'a dyn Fn(&str),
}

impl Suite<'_> {
    pub(super) fn seconds(&self, s: f64) -> f64 {
        s * self.args.budgets.time_scale
    }

    pub(super) fn bench_dir(&self) -> PathBuf {
        self.args.out.join("bench")
    }

    /// The `plume bench compare` command that reproduces a comparison of `scene_file`;
    /// with `name`, it writes its files beside the report's.
    pub(super) fn compare_command(
        &self,
        scene_file: &Path,
        methods: &str,
        curve_points: u32,
        reference: &RefArg<'_>,
        name: Option<&str>,
    ) -> String {
        let run_seconds = self.seconds(RUN_SECONDS);
        self.compare_command_at(run_seconds, scene_file, methods, curve_points, reference, name)
    }

    /// [`Suite::compare_command`] with runs of `run_seconds` CPU seconds.
    pub(super) fn compare_command_at(
        &self,
        run_seconds: f64,
        scene_file: &Path,
        methods: &str,
        curve_points: u32,
        reference: &RefArg<'_>,
        name: Option<&str>,
    ) -> String {
        let mut c = format!(
            "plume bench compare {} --methods {methods} --time {} --runs {RUNS} --curve-points {curve_points}",
            scene_file.display(),
            arg(run_seconds)
        );
        match reference {
            RefArg::Make(s) => {
                let _ = write!(c, " --make-reference --reference-time {}", arg(*s));
            }
            RefArg::MakeAndSave(s, p) => {
                let _ = write!(
                    c,
                    " --make-reference --reference-time {} --save-reference {}",
                    arg(*s),
                    p.display()
                );
            }
            RefArg::Given(p) => {
                let _ = write!(c, " --reference {}", p.display());
            }
        }
        if let Some(n) = name {
            let _ = write!(c, " -o {} --name {n}", self.bench_dir().display());
        }
        c
    }

    /// The scene `spec` with `keys` (a scene-file fragment), loaded, and written as the
    /// scene file `DIR/bench/scenes/NAME.toml` that the section's command reads.
    /// `keys` are fragments applied in order (each may name the same tables).
    pub(super) fn scene(
        &mut self,
        name: &str,
        spec: &str,
        keys: &[&str],
    ) -> Result<(BenchScene, PathBuf)> {
        let (shot, path, _) = self.write_scene(name, spec, keys)?;
        let summary = keys
            .iter()
            .flat_map(|k| k.lines())
            .map(str::trim)
            .filter(|l| !l.is_empty())
            .collect::<Vec<_>>()
            .join(" ");
        Ok((load(shot, vec![summary], &self.args.work_dir)?, path))
    }

    /// The shot of `spec` with the fragments `keys`, written as the scene file
    /// `DIR/bench/scenes/NAME.toml` (its volume file as seen from there); returns the shot,
    /// the file and its text.
    pub(super) fn write_scene(
        &self,
        name: &str,
        spec: &str,
        keys: &[&str],
    ) -> Result<(plume_scene::Shot, PathBuf, String)> {
        let mut shot = bench_shot(spec);
        for k in keys {
            shot = with_keys(&shot, k)?;
        }
        let dir = self.bench_dir().join("scenes");
        // The spec as seen from the scene file's directory (relative paths in a scene
        // file are relative to it)
        let mut written = shot.clone();
        let up: PathBuf = dir.components().map(|_| "..").collect();
        if !spec.starts_with("explosion:") && Path::new(spec).is_relative() {
            written.scene.volume.file =
                if dir.is_relative() { up.join(spec) } else { self.args.working_dir.join(spec) };
        }
        std::fs::create_dir_all(&dir)
            .map_err(|source| Error::Write { path: dir.clone(), source })?;
        let text = to_toml_as_is(&written)?;
        let path = dir.join(format!("{name}.toml"));
        plume_core::fs::write_atomic(&path, |w| std::io::Write::write_all(w, text.as_bytes()))?;
        Ok((shot, path, text))
    }

    pub(super) fn config(
        &self,
        scene: &BenchScene,
        methods: &str,
        curve_points: u32,
    ) -> Result<CompareConfig> {
        Ok(CompareConfig {
            methods: parse_methods(methods, scene.shot.scene.integrator.kappa)?,
            cpu_seconds: self.seconds(RUN_SECONDS),
            spp: None,
            runs: RUNS,
            epsilon: crate::bench::metrics::RELMSE_EPSILON,
            curve_points,
            adaptive: false,
        })
    }

    /// Run one comparison of methods and append its section; returns the report and the
    /// command that reproduces it.
    #[allow(clippy::too_many_arguments)] // one per section property
    pub(super) fn section(
        &mut self,
        title: &str,
        name: &str,
        intro: &str,
        (scene, scene_file): (&mut BenchScene, &Path),
        reference: &Reference,
        reference_seconds: f64,
        methods: &str,
    ) -> Result<(CompareReport, String)> {
        (self.log)(&format!("== {title}"));
        let cfg = self.config(scene, methods, CURVE_POINTS)?;
        let wall = Instant::now();
        let report = compare(scene, reference, &cfg, self.log)?;
        let wall = wall.elapsed().as_secs_f64();
        let crops = name != "proxy"; // every proxy variant looks alike
        self.write_section_files(&report, name, crops)?;
        let command = self.compare_command(
            scene_file,
            methods,
            CURVE_POINTS,
            &RefArg::Make(reference_seconds),
            Some(name),
        );
        let md = &mut self.md;
        let _ = writeln!(md, "## {title}\n\n{intro}\n");
        section_tables(md, &report, &command);
        section_notes(md, &report);
        let _ = writeln!(md, "![error vs CPU time, {name}](img/{name}-error.png)\n");
        if crops {
            let _ = writeln!(md, "![equal-time crops, {name}](img/{name}-crops.png)\n");
        }
        let _ = writeln!(md, "Data: [`bench/{name}.csv`](bench/{name}.csv), [`bench/{name}.json`](bench/{name}.json). Section wall time {wall:.0} s.\n");
        Ok((report, command))
    }

    /// A comparison's files: tables in `DIR/bench`, plots moved to `DIR/img`.
    fn write_section_files(&self, report: &CompareReport, name: &str, crops: bool) -> Result<()> {
        let files = report.write(&self.bench_dir(), name, crops)?;
        // Plots live in img/, tables in bench/
        let img = self.args.out.join("img");
        std::fs::create_dir_all(&img)
            .map_err(|source| Error::Write { path: img.clone(), source })?;
        for f in &files[2..] {
            let to = img.join(f.file_name().unwrap_or_default());
            std::fs::rename(f, &to).map_err(|source| Error::Write { path: to.clone(), source })?;
        }
        Ok(())
    }
}

/// A comparison's setup, its three tables and the command that reproduces them.
fn section_tables(md: &mut String, report: &CompareReport, command: &str) {
    let _ = writeln!(md, "{}\n", report.setup());
    let _ = writeln!(
        md,
        "**Equal CPU time** ({} CPU s per run, mean ± std over {} seeds):\n\n{}",
        num(report.cpu_seconds_per_run),
        report.runs,
        report.equal_time_table()
    );
    let _ = writeln!(
        md,
        "**Equal spp** ({} spp, the largest power of two every run reached):\n\n{}",
        report.equal_spp,
        report.equal_spp_table()
    );
    let _ = writeln!(md, "**Cost of the light structures** (built once per method, outside the render budget):\n\n{}", report.cost_table());
    let _ =
        writeln!(md, "All three tables, and the files linked below:\n\n```sh\n{command}\n```\n");
}

/// The most efficient method, and a note on methods whose relMSE grows with CPU time.
fn section_notes(md: &mut String, report: &CompareReport) {
    let best =
        report.methods.iter().max_by(|a, b| report.efficiency(a).total_cmp(&report.efficiency(b)));
    if let Some(b) = best {
        let _ = writeln!(
            md,
            "Most efficient at equal CPU time: `{}` ({:.2}× the efficiency of `{}`).\n",
            b.method,
            report.efficiency(b),
            report.methods[0].method
        );
    }
    let growing: Vec<&str> = report
        .methods
        .iter()
        .filter(|m| {
            m.curve.len() > 1 && m.curve[m.curve.len() - 1].relmse.mean > m.curve[0].relmse.mean
        })
        .map(|m| m.method.as_str())
        .collect();
    if !growing.is_empty() {
        let _ = writeln!(
            md,
            "Note: relMSE *grows* with CPU time here for {}. The reference is noisiest, relative to its value, in dark pixels, where (x − ref)²/(ref² + ε) weighs most; a method converging to the true image moves away from the reference's noise there. For these, read RMSE; the relMSE columns still rank methods at one budget, loosely.\n",
            growing.iter().map(|m| format!("`{m}`")).collect::<Vec<_>>().join(", ")
        );
    }
}
