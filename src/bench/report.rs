//! `plume bench report`: the benchmark suite behind `docs/BENCHMARKS.md`.
//!
//! One command renders every section and writes the Markdown, the plots (`DIR/img`) and
//! the CSV/JSON (`DIR/bench`):
//! 1. the generated explosion, thin (σ_t = 1) and dense (σ_t = 20), the paper's two
//!    regimes, at `--resolution` (256³ by default), scattering (albedo 0.8, g 0.3);
//! 2. the FNEE proxy-resolution sweep (8³ … full) on the dense explosion;
//! 3. the openvdb.org smoke and the Disney cloud (1/16), each lit by its own density as
//!    emission (`--emission grid --emission-grid density`), scattering;
//! 4. trilinear against nearest reconstruction on the real explosions and smoke
//!    ([`super::interpolation`]): cost per sample, memory, emission rule, close-up;
//! 5. the numerical-extremes sweep ([`super::extremes`]).
//!
//! Budgets are CPU seconds (see [`super::progressive`]); `--time-scale` multiplies them
//! all, for a quick smoke test of the pipeline.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use super::compare::{compare, make_reference, CompareConfig, CompareReport, Reference};
use super::numbers::num;
use super::plot::{loglog_panels, Series};
use super::spec::{bench_shot, load, parse_methods, BenchScene};
use plume_core::error::{Error, Result};
use plume_scene::file::{to_toml_as_is, with_keys};

/// Methods of the explosion, smoke and cloud sections; the first is the baseline.
const METHODS: &str = "point-nee,line-nee,line-fnee,ray-march,line+none,blend+fnee";
/// CPU seconds per run (× `--time-scale`).
const RUN_SECONDS: f64 = 6.0;
/// CPU seconds of each computed reference (× `--time-scale`).
const REFERENCE_SECONDS: f64 = 96.0;
/// Runs (seeds) per method.
const RUNS: u32 = 3;

/// `plume bench report`.
#[derive(Clone, Debug)]
pub struct ReportOptions {
    /// Directory of BENCHMARKS.md; plots go to DIR/img, CSV and JSON to DIR/bench.
    pub out: PathBuf,
    /// Multiply every CPU-time budget by this (e.g. 0.05 for a smoke test).
    pub time_scale: f64,
    /// Explosion resolution of the thin/dense scenes.
    pub resolution: u32,
    /// Directory of the shared data (smoke and cloud files).
    pub data: PathBuf,
    /// Where generated explosions are written.
    pub work_dir: PathBuf,
}

impl ReportOptions {
    /// Run the suite and write the report.
    ///
    /// # Errors
    /// See [`run`].
    pub fn run(&self) -> Result<()> {
        run(self)
    }
}

/// The authors' equal-time RMSE ratios FNEE/NEE (METHOD.md §9).
const PAPER_RATIO: [(&str, f64); 2] = [("thin", 0.748 / 0.983), ("dense", 0.572 / 0.892)];

fn git(args: &[&str]) -> Option<String> {
    let o = std::process::Command::new("git").args(args).output().ok()?;
    o.status.success().then(|| String::from_utf8_lossy(&o.stdout).trim().to_string())
}

fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg").map_or_else(|_| "unknown".into(), |s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
}

struct Suite<'a> {
    args: &'a ReportOptions,
    /// The scene file of the scene loaded last ([`Suite::scene`]).
    scene_file: std::path::PathBuf,
    md: String,
    log: &'a dyn Fn(&str),
}

impl Suite<'_> {
    fn seconds(&self, s: f64) -> f64 {
        s * self.args.time_scale
    }

    fn compare_command(&self, report: &CompareReport, methods: &str, name: &str) -> String {
        format!(
            "plume bench compare {} --methods {methods} --time {} --runs {RUNS} --make-reference --reference-time {} -o docs/bench --name {name}",
            self.scene_file.display(),
            num(self.seconds(RUN_SECONDS)),
            num(report.reference.cpu_seconds.round()),
        )
    }

    /// The scene `spec` with `keys` (a scene-file fragment), loaded, and written as the
    /// scene file `DIR/bench/NAME.toml` that the section's command reproduces it from.
    fn scene(&mut self, name: &str, spec: &str, keys: &str) -> Result<BenchScene> {
        let shot = with_keys(&bench_shot(spec), keys)?;
        let dir = self.args.out.join("bench");
        // The spec as seen from the scene file's directory (relative paths in a scene
        // file are relative to it)
        let mut written = shot.clone();
        let up: std::path::PathBuf = dir.components().map(|_| "..").collect();
        if !spec.starts_with("explosion:") && std::path::Path::new(spec).is_relative() && dir.is_relative() {
            written.scene.volume.file = up.join(spec);
        }
        std::fs::create_dir_all(&dir).map_err(|source| Error::Write { path: dir.clone(), source })?;
        let text = to_toml_as_is(&written)?;
        let path = dir.join(format!("{name}.toml"));
        plume_core::fs::write_atomic(&path, |w| std::io::Write::write_all(w, text.as_bytes()))?;
        self.scene_file = path;
        let summary = keys.lines().map(str::trim).filter(|l| !l.is_empty()).collect::<Vec<_>>().join(" ");
        load(shot, vec![summary], &self.args.work_dir)
    }

    /// Run one comparison and append its section; returns the report.
    #[allow(clippy::too_many_arguments)] // one per section property
    fn section(&mut self, title: &str, name: &str, intro: &str, scene: &mut BenchScene, reference: &Reference, methods: &str) -> Result<CompareReport> {
        (self.log)(&format!("== {title}"));
        let cfg = CompareConfig {
            methods: parse_methods(methods, scene.shot.scene.integrator.kappa)?,
            cpu_seconds: self.seconds(RUN_SECONDS),
            spp: None,
            runs: RUNS,
            epsilon: super::metrics::RELMSE_EPSILON,
            curve_points: 4,
        };
        let wall = Instant::now();
        let report = compare(scene, reference, &cfg, self.log)?;
        let wall = wall.elapsed().as_secs_f64();
        let out = &self.args.out;
        let crops = name != "proxy"; // every proxy variant looks alike
        let files = report.write(&out.join("bench"), name, crops)?;
        // Plots live in img/, tables in bench/
        let img = out.join("img");
        std::fs::create_dir_all(&img).map_err(|source| Error::Write { path: img.clone(), source })?;
        for f in &files[2..] {
            let to = img.join(f.file_name().unwrap_or_default());
            std::fs::rename(f, &to).map_err(|source| Error::Write { path: to.clone(), source })?;
        }
        let command = self.compare_command(&report, methods, name);
        let md = &mut self.md;
        let _ = writeln!(md, "## {title}\n\n{intro}\n");
        let _ = writeln!(md, "{}\n", report.setup());
        let _ = writeln!(md, "Reproduce this section alone:\n\n```sh\n{command}\n```\n");
        let _ = writeln!(
            md,
            "**Equal CPU time** ({} CPU s per run, mean ± std over {} seeds):\n\n{}",
            num(report.cpu_seconds_per_run),
            report.runs,
            report.equal_time_table()
        );
        let _ = writeln!(md, "**Equal spp** ({} spp, the largest power of two every run reached):\n\n{}", report.equal_spp, report.equal_spp_table());
        let _ = writeln!(md, "**Cost of the light structures** (built once per method, outside the render budget):\n\n{}", report.cost_table());
        let best = report.methods.iter().max_by(|a, b| report.efficiency(a).total_cmp(&report.efficiency(b)));
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
            .filter(|m| m.curve.len() > 1 && m.curve[m.curve.len() - 1].relmse.mean > m.curve[0].relmse.mean)
            .map(|m| m.method.as_str())
            .collect();
        if !growing.is_empty() {
            let _ = writeln!(
                md,
                "Note: relMSE *grows* with CPU time here for {}. The reference is noisiest, relative to its value, in dark pixels, where (x − ref)²/(ref² + ε) weighs most; a method converging to the true image moves away from the reference's noise there. For these, read RMSE; the relMSE columns still rank methods at one budget, loosely.\n",
                growing.iter().map(|m| format!("`{m}`")).collect::<Vec<_>>().join(", ")
            );
        }
        let _ = writeln!(md, "![error vs CPU time, {name}](img/{name}-error.png)\n");
        if crops {
            let _ = writeln!(md, "![equal-time crops, {name}](img/{name}-crops.png)\n");
        }
        let _ = writeln!(md, "Data: [`bench/{name}.csv`](bench/{name}.csv), [`bench/{name}.json`](bench/{name}.json). Section wall time {wall:.0} s.\n");
        Ok(report)
    }
}

fn ratio_line(regime: &str, r: &CompareReport) -> String {
    let find = |m: &str| r.methods.iter().find(|x| x.method == m);
    match (find("line-fnee"), find("point-nee")) {
        (Some(f), Some(p)) => {
            let paper = PAPER_RATIO.iter().find(|x| x.0 == regime).map_or(f64::NAN, |x| x.1);
            // Remove the reference's own noise from both MSEs (E[RMSE²] = MSE + MSE_ref)
            let floor = r.reference.noise_rmse.unwrap_or(0.0).powi(2);
            let corrected = ((f.equal_time.rmse.mean.powi(2) - floor).max(0.0) / (p.equal_time.rmse.mean.powi(2) - floor).max(f64::MIN_POSITIVE)).sqrt();
            format!(
                "| {regime} | {:.3} ± {:.3} | {corrected:.3} | {:.3} | {:.2}× | {} vs {} | {:.3} |",
                f.equal_time.rmse.mean / p.equal_time.rmse.mean,
                // Spread of the ratio from the relative spreads (independent runs)
                (f.equal_time.rmse.mean / p.equal_time.rmse.mean)
                    * ((f.equal_time.rmse.std / f.equal_time.rmse.mean).powi(2) + (p.equal_time.rmse.std / p.equal_time.rmse.mean).powi(2)).sqrt(),
                f.equal_spp.rmse.mean / p.equal_spp.rmse.mean,
                r.efficiency(f) / r.efficiency(p),
                super::numbers::pm_count(&f.equal_time.spp),
                super::numbers::pm_count(&p.equal_time.spp),
                paper
            )
        }
        _ => format!("| {regime} | – | – | – | – | – | – |"),
    }
}

/// Run the suite and write `BENCHMARKS.md`, plots and data under `args.out`.
///
/// # Errors
/// Missing data files, unwritable outputs, failed extremes checks are *reported* in the
/// document, not errors.
pub fn run(args: &ReportOptions) -> Result<()> {
    let start = Instant::now();
    let load_start = load_average();
    let log = |l: &str| log::info!("{l}");
    let mut suite = Suite { args, scene_file: Default::default(), md: String::new(), log: &log };
    let res = args.resolution;
    let explosion = format!("explosion:{res}");
    let common = "albedo = 0.8\ng = 0.3\n[camera]\nwidth = 200\nheight = 150";
    let mut regimes = Vec::new();
    for (regime, sigma, intro) in [
        ("thin", 1.0, "Optical depth across the fireball ≈ 1: most paths escape, the point estimator scores rarely, line integration collects emission along every segment (the paper's thin explosion)."),
        ("dense", 20.0, "Optical depth ≈ 20: free paths are short, NEE shadow rays toward a bright core behind soot are long and mostly blocked; FNEE's free path stops after about one mean free path (the paper's dense explosion)."),
    ] {
        let mut scene = suite.scene(regime, &explosion, &format!("[medium]\ndensity_scale = {sigma:?}\n{common}"))?;
        let reference = make_reference(&mut scene, suite.seconds(REFERENCE_SECONDS), &log)?;
        let title = format!("Generated explosion {res}³, {regime} (σ_t = {sigma})");
        let report = suite.section(&title, regime, intro, &mut scene, &reference, METHODS)?;
        if regime == "dense" {
            // Proxy-resolution sweep against the same reference
            let mut proxies = Vec::new();
            let mut p = 8;
            while p <= res.next_power_of_two() {
                proxies.push(format!("line-fnee@{p}"));
                p *= 2;
            }
            let methods = proxies.join(",");
            let sweep = suite.section(
                &format!("FNEE proxy resolution, dense explosion {res}³"),
                "proxy",
                "The paper's FNEE test: the same line-fnee method with proxy grids from 8³ cells to the full data resolution. FNEE is unbiased at any proxy resolution (METHOD.md §7); the proxy changes only variance and cost. The baseline of ratios is the 8³ proxy.",
                &mut scene,
                &reference,
                &methods,
            )?;
            let pts = |f: &dyn Fn(&super::compare::MethodResult) -> (f64, f64)| sweep.methods.iter().map(|m| {
                let (y, sd) = f(m);
                (f64::from(m.proxy_resolution.unwrap_or(0)), y, sd)
            }).collect::<Vec<_>>();
            loglog_panels(
                &args.out.join("img").join("proxy-sweep.png"),
                &[
                    ("RMSE vs proxy resolution", "proxy cells per axis", "RMSE", vec![
                        Series { label: "equal CPU time".into(), points: pts(&|m| (m.equal_time.rmse.mean, m.equal_time.rmse.std)) },
                        Series { label: format!("equal spp ({})", sweep.equal_spp), points: pts(&|m| (m.equal_spp.rmse.mean, m.equal_spp.rmse.std)) },
                    ]),
                    ("Cost vs proxy resolution", "proxy cells per axis", "samples per CPU second", vec![
                        Series { label: "samples / CPU s".into(), points: pts(&|m| (m.samples_per_cpu_second.mean, m.samples_per_cpu_second.std)) },
                    ]),
                ],
                440,
                330,
            )?;
            let _ = writeln!(suite.md, "![proxy sweep](img/proxy-sweep.png)\n");
        }
        regimes.push((regime, report));
    }
    // Real files, lit by their own density as emission
    for (name, file, extra, intro) in [
        (
            "smoke",
            "smoke/openvdb_org_smoke1.vdb",
            "[volume]\nemission_grid = \"density\"\n[emission]\nsource = \"grid\"\ncolor = [1, 0.45, 0.15]\nscale = 1\n[medium]\ndensity_scale = 0.5\nalbedo = 0.7\ng = 0.2\n[camera]\nwidth = 150\nheight = 200",
            "The openvdb.org smoke plume (111×222×112 voxels of 0.48 units), glowing where it is dense: emission density `L_e = s_e c ρ²` (its own density as the emission grid, physical convention), σ_t = 0.5, albedo 0.7. We light each file by its own density rather than by a generated fireball because plume renders one volume per scene; this keeps the comparison a property of the data.",
        ),
        (
            "cloud",
            "cloud/wdas_cloud_sixteenth.vdb",
            "[volume]\nemission_grid = \"density\"\n[emission]\nsource = \"grid\"\ncolor = [1, 0.6, 0.3]\nscale = 0.05\n[medium]\ndensity_scale = 0.02\nalbedo = 0.8\ng = 0.5\n[camera]\nwidth = 200\nheight = 150",
            "The Disney cloud at 1/16 resolution (126×86×154 voxels of 3.3 units), self-luminous with `L_e = s_e c ρ²`, σ_t = 0.02 per unit (optical depth ≈ 4 across), albedo 0.8, forward scattering g = 0.5.",
        ),
    ] {
        let path = args.data.join(file);
        if !path.exists() {
            let _ = writeln!(suite.md, "## {name}\n\nSkipped: {} not found.\n", path.display());
            continue;
        }
        let spec = path.display().to_string();
        let mut scene = suite.scene(name, &spec, extra)?;
        let reference = make_reference(&mut scene, suite.seconds(REFERENCE_SECONDS) / 2.0, &log)?;
        let title = format!("{} ({})", if name == "smoke" { "openvdb.org smoke" } else { "Disney cloud, 1/16" }, file);
        suite.section(&title, name, intro, &mut scene, &reference, METHODS)?;
    }
    interpolation_section(&mut suite)?;
    // Extremes
    (suite.log)("== extremes");
    let cfg = super::extremes::ExtremesConfig { box_voxels: 32, explosion_resolution: 64, size: 48, spp: 16 };
    let ex = super::extremes::run(&cfg)?;
    let ex_json = serde_json::to_string_pretty(&ex).map_err(|e| Error::Scene(e.to_string()))?;
    plume_core::fs::write_atomic(&args.out.join("bench").join("extremes.json"), |w| std::io::Write::write_all(w, ex_json.as_bytes()))?;
    let _ = writeln!(
        suite.md,
        "## Numerical extremes\n\n{}\n\nReproduce: `plume bench extremes --box-voxels {} --explosion-resolution {} --size {} --spp {}` (a smaller version runs in `cargo test`, `tests/bench.rs`).\n\n{}",
        EXTREMES_INTRO, cfg.box_voxels, cfg.explosion_resolution, cfg.size, cfg.spp, ex.table()
    );
    write_document(args, &suite.md, &regimes, start.elapsed().as_secs_f64(), &load_start)
}

/// Trilinear against nearest ([`super::interpolation`]), its picture in `DIR/img`, its
/// JSON in `DIR/bench`; skipped when a data file is missing.
fn interpolation_section(suite: &mut Suite<'_>) -> Result<()> {
    (suite.log)("== interpolation");
    let out = &suite.args.out;
    let picture = out.join("img").join("interpolation-closeup.png");
    let mut cfg = super::interpolation::InterpolationConfig::standard(suite.args.data.clone(), Some(picture));
    cfg.cpu_seconds = suite.seconds(cfg.cpu_seconds);
    let title = "## Interpolation: trilinear vs nearest";
    let missing = cfg.missing_files();
    if !missing.is_empty() {
        let names: Vec<String> = missing.iter().map(|p| p.display().to_string()).collect();
        let _ = writeln!(suite.md, "{title}\n\nSkipped: {} not found.\n", names.join(", "));
        return Ok(());
    }
    let report = super::interpolation::run(&cfg, suite.log)?;
    let json = out.join("bench").join("interpolation.json");
    super::write_json(&Some(json.clone()), &report)?;
    let command = format!("{} --json {}", cfg.command(), json.display());
    let _ = writeln!(
        suite.md,
        "{title}\n\n`--interpolation linear` (the default) against `nearest` on the real files: what trilinear reconstruction costs per sample, what memory it adds, how its emission rule differs from Cycles', and what it looks like (METHOD.md §12; README, \"Interpolation\").\n\n{}Data: [`bench/interpolation.json`](bench/interpolation.json).\n",
        report.markdown(&command, Some("img/interpolation-closeup.png"))
    );
    Ok(())
}

const EXTREMES_INTRO: &str = "Boxes of constant density and emission seen head-on, where `L = L_e (1 − e^{−μd})/μ` (METHOD.md §11.1), and the generated explosion at voxel sizes from 1e-4 to 1e4.\n\n\
- *density*: σ_t from 1e-6 to 1e6 per metre in a 1 m box (optical depth 1e-6 … 1e6), emission 1 per metre; with scattering (albedo 0.5, line-fnee) the mean must lie between the emission-only value and `L_e/μ_a`.\n\
- *temperature*: blackbody box via `--temperature-map linear:0,T` up to 1e7 K (solar-flare plasma), against the f64 Planck × CIE integral; 300 K is below the 500 K cutoff and must be black.\n\
- *voxel size*: the explosion with voxel edge `h` = 1e-4 … 1e4 (its `world_from_index` scaled), **σ_t and the emission scale both multiplied by h₀/h** so optical depth and radiance do not change: images must match the generator's own voxel size `h₀` to float rounding, 1e-5 (ray-march: largest pixel difference; point/line: image mean, since a near-tie can flip one collision).\n\
- *invalid voxels*: NaN, ±inf and negative density and emission voxels must be clamped to 0 by the volume builder and counted exactly, and the image must be bit-identical to the box with zeros there. Through `plume render`, negative voxels in a file are clamped with a warning that gives the exact count (checked through the binary in `tests/bench.rs`); NaN and ±inf in a *file* are currently refused earlier, by the VDB reader, as a corrupt file (exit 3, naming the file and the count), so they never reach the clamp.\n\
Stochastic tolerances are 5 standard errors (the larger of the pixel spread and METHOD.md §4's variance for a homogeneous segment); ray-march 1e-4 relative (2e-3 for blackbody: the table's accuracy).";

fn write_document(args: &ReportOptions, body: &str, regimes: &[(&str, CompareReport)], seconds: f64, load_start: &str) -> Result<()> {
    let super::Machine { cpus, model } = super::machine();
    let commit = git(&["rev-parse", "HEAD"]).unwrap_or_else(|| "unknown".into());
    let dirty = git(&["status", "--porcelain", "--untracked-files=no"]).is_some_and(|s| !s.is_empty());
    let mut md = String::new();
    let _ = writeln!(md, "# plume benchmarks\n\nGenerated by one command (builds the release binary, then runs `plume bench report`, whose default output is `docs/`):\n\n```sh\nscripts/benchmarks.sh\n```\n");
    let _ = writeln!(
        md,
        "Machine: {cpus} logical CPUs, {model}. Commit `{commit}`{}. Total wall time {:.0} s; load average (1, 5, 15 min) {load_start} at the start and {} at the end: the machine is shared, so budgets are **CPU seconds** (user + system of all threads), which other processes do not consume, though they do compete for caches and memory bandwidth. CPU-time budgets × {}.\n",
        if dirty { " (with uncommitted changes)" } else { "" },
        seconds,
        load_average(),
        args.time_scale
    );
    let _ = writeln!(md, "**Metrics.** RMSE over all RGB values; relMSE = per-pixel mean over RGB of (x − ref)²/(ref² + ε), ε = {}, with the top 0.1 % of pixel values trimmed; bias = mean(x) − mean(ref); spread = sample std over seeds. Efficiency = 1/(RMSE² · CPU s) relative to the first method. Core-hours = CPU s / 3600. Peak RSS is per method (the kernel's high-water mark reset before each method) and includes the loaded volume and reference. The computed references' own noise is estimated from two independent halves and stated; it is included in every RMSE.\n", super::metrics::RELMSE_EPSILON);
    let _ = writeln!(md, "**Methods.** `point-nee`: collision estimator + classic NEE (MIS in volume measure). `line-nee`: line integration + classic NEE (no MIS partner). `line-fnee`: line integration + forward NEE with MIS (the paper's method). `ray-march`: expected-value estimator, forward paths only. `line+none`: line integration, forward paths only. `blend+fnee`: our line/point blend (κ = 4) + FNEE. FNEE proxy 64³ unless stated.\n");
    let _ = writeln!(md, "## Headline: line-fnee against point-nee\n\n| regime | RMSE ratio at equal time | same, reference noise removed | RMSE ratio at equal spp | efficiency gain | spp at equal time (line-fnee vs point-nee) | paper's equal-time ratio |\n|---|---|---|---|---|---|---|");
    for (regime, r) in regimes {
        let _ = writeln!(md, "{}", ratio_line(regime, r));
    }
    let _ = writeln!(md, "\nThe paper's ratios are from the authors' slides (METHOD.md §9: thin 0.748/0.983 at 48 vs 43 spp, dense 0.572/0.892 at 196 vs 73 spp), on their explosion and machine with 10 and 30 minute budgets; ours are seconds on a generated explosion, so compare directions and orders, not digits.\n");
    md.push_str(body);
    let path = args.out.join("BENCHMARKS.md");
    plume_core::fs::write_atomic(&path, |w| std::io::Write::write_all(w, md.as_bytes()))?;
    log::info!("wrote {}", path.display());
    Ok(())
}
