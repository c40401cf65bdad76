//! `plume bench interpolation`: trilinear reconstruction (`--interpolation linear`,
//! METHOD.md §12) against nearest on real files.
//!
//! - **Cost per sample.** Each file is loaded once; the same scene (same camera, image,
//!   spp and seed) is rendered with nearest and with linear reconstruction, alternately
//!   (`N L`, then `L N`, …) so that a change in the machine's load hits both, and the
//!   medians of samples per CPU second are compared: `cost ratio = rate(nearest) /
//!   rate(linear)`. Methods: emission–absorption (`ray-march`, `line`) and scattering
//!   (albedo 0.8: `line-fnee`, `point-nee`). The spp is calibrated once per method so that
//!   a nearest render takes about `--time` CPU seconds; linear renders the same spp.
//!   Light structures are built outside the timed renders. One thread by default, so CPU
//!   time is the work done and not idle-worker spinning.
//! - **Memory.** The dual pyramid (`volume::trilinear`) is all that trilinear adds: its
//!   bytes against the volume's (bricks, table, values, pyramid).
//! - **Emission rule** ([`rule`]): plume interpolates the per-voxel emission
//!   `L_e(ρ_i, T_i)`; Cycles interpolates ρ and T and applies the blackbody after. Both
//!   rules on the same deterministic march.
//! - **Close-up** ([`closeup`]): nearest | linear, a voxel about 6 pixels across.

pub mod closeup;
pub mod rule;
mod switch;

use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use serde::Serialize;

use super::numbers::num;
use super::spec::{bench_shot, load_file};
use plume_core::error::{Error, Result};
use plume_engine::integrator::{AnyScene, Counters, Integrator, LightSampling, Lights};
use plume_engine::medium::Estimator;
use plume_engine::render::{render, RenderSettings, SampleBudget};
use plume_engine::stats::cpu_seconds;
use plume_scene::file::with_keys;
use plume_volume::proxy::ProxyGrid;
use plume_volume::Interpolation;
use switch::Switch;

/// A real file of the cost and memory tables, and how it is lit.
#[derive(Clone, Copy, Debug)]
pub struct CostFile {
    /// Short name (`--files`).
    pub name: &'static str,
    /// Path under the data directory.
    pub file: &'static str,
    /// Scene-file keys besides the bench's own (grids, emission, density scale).
    pub keys: &'static str,
    /// How the file is lit, in words.
    pub about: &'static str,
}

/// The files of `--files`, in table order.
pub const COST_FILES: [CostFile; 4] = [
    CostFile {
        name: "kelvin40",
        file: "explosion/mantaflow_explosion_kelvin_0040.vdb",
        keys: "[emission]\nconvention = \"cycles\"\n[camera]\nup_axis = \"z\"",
        about: "Blender Mantaflow explosion, frame 40 (192×192×256 voxels of 1/32 m): blackbody from the Kelvin grid, `--convention cycles`",
    },
    CostFile {
        name: "blender40",
        file: "explosion/blender_fluid_noise_0040.vdb",
        keys: "[volume]\ndensity_grid = \"density_noise\"\nemission_grid = \"flame_noise\"\n[emission]\nsource = \"grid\"\nconvention = \"cycles\"\n[camera]\nup_axis = \"z\"",
        about: "Blender's own cache of the same frame: `--density-grid density_noise --emission grid --emission-grid flame_noise --convention cycles`",
    },
    CostFile {
        name: "r192",
        file: "explosion/mantaflow_explosion_r192n2_kelvin_0040.vdb",
        keys: "[emission]\nconvention = \"cycles\"\n[camera]\nup_axis = \"z\"",
        about: "the larger Mantaflow run (288×288×384), frame 40: blackbody, `--convention cycles`",
    },
    CostFile {
        name: "smoke1",
        file: "smoke/openvdb_org_smoke1.vdb",
        keys: "[volume]\nemission_grid = \"density\"\n[emission]\nsource = \"grid\"\ncolor = [1, 0.45, 0.15]\n[medium]\ndensity_scale = 0.5",
        about: "openvdb.org smoke1 (half floats), lit by its own density (`--emission grid --emission-grid density`), σ_t = 0.5, as in the smoke section",
    },
];

/// The file of the close-up picture, under the data directory.
pub const CLOSEUP_FILE: &str = "explosion/mantaflow_explosion_kelvin_0040.vdb";

/// The methods of the cost table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum CostMethod {
    RayMarch,
    Line,
    LineFnee,
    PointNee,
}

impl CostMethod {
    const ALL: [CostMethod; 4] =
        [CostMethod::RayMarch, CostMethod::Line, CostMethod::LineFnee, CostMethod::PointNee];

    fn name(self) -> &'static str {
        match self {
            CostMethod::RayMarch => "ray-march (EA)",
            CostMethod::Line => "line (EA)",
            CostMethod::LineFnee => "line-fnee (albedo 0.8)",
            CostMethod::PointNee => "point-nee (albedo 0.8)",
        }
    }

    /// The integrator, from the scene's (MIS, depth, environment).
    fn integrator(self, base: Integrator) -> Integrator {
        match self {
            CostMethod::RayMarch => Integrator::emission_only(Estimator::RayMarch),
            CostMethod::Line => Integrator::emission_only(Estimator::Line),
            CostMethod::LineFnee => Integrator {
                estimator: Estimator::Line,
                light_sampling: LightSampling::Fnee,
                ..base
            },
            CostMethod::PointNee => Integrator {
                estimator: Estimator::Point,
                light_sampling: LightSampling::Nee,
                ..base
            },
        }
    }
}

/// What `plume bench interpolation` measures (the binary fills it from flags).
#[derive(Clone, Debug)]
pub struct InterpolationConfig {
    /// Directory of the shared data.
    pub data: PathBuf,
    /// Names of [`COST_FILES`] to measure (empty: none).
    pub files: Vec<String>,
    /// Image size of the cost renders.
    pub width: u32,
    /// Image size of the cost renders.
    pub height: u32,
    /// Target CPU seconds of one timed nearest render (sets the spp).
    pub cpu_seconds: f64,
    /// Timed renders per reconstruction and method (alternated).
    pub repeats: u32,
    /// Render threads of the cost renders (0 = all cores).
    pub threads: usize,
    /// The emission-rule comparison.
    pub rule: rule::RuleConfig,
    /// The close-up picture, if wanted.
    pub closeup: Option<closeup::CloseupConfig>,
}

impl InterpolationConfig {
    /// The defaults of `plume bench interpolation` (every file, 160×120, 0.5 CPU s per
    /// timed render, 3 repeats, one thread; the rule on every Kelvin frame at 320×240,
    /// ⅛ voxel; the close-up 400×300 at 8 spp if `picture` is given).
    #[must_use]
    pub fn standard(data: PathBuf, picture: Option<PathBuf>) -> InterpolationConfig {
        InterpolationConfig {
            data,
            files: COST_FILES.iter().map(|f| f.name.to_string()).collect(),
            width: 160,
            height: 120,
            cpu_seconds: 0.5,
            repeats: 3,
            threads: 1,
            rule: rule::RuleConfig {
                files: Vec::new(),
                width: 320,
                height: 240,
                step_voxels: 0.125,
            },
            closeup: picture.map(|path| closeup::CloseupConfig {
                path,
                file: PathBuf::from(CLOSEUP_FILE),
                width: 400,
                height: 300,
                spp: 8,
                pixels_per_voxel: 6.0,
                threads: 0,
            }),
        }
    }

    /// The data files this configuration reads that do not exist.
    #[must_use]
    pub fn missing_files(&self) -> Vec<PathBuf> {
        let mut files: Vec<PathBuf> = COST_FILES
            .iter()
            .filter(|f| self.files.iter().any(|n| n == f.name))
            .map(|f| self.data.join(f.file))
            .collect();
        files.extend(self.rule.files.iter().map(|f| self.data.join(f)));
        files.extend(self.closeup.iter().map(|c| self.data.join(&c.file)));
        files.retain(|f| !f.exists());
        files
    }

    /// The `plume bench interpolation` command line that runs this configuration.
    #[must_use]
    pub fn command(&self) -> String {
        let mut c = format!(
            "plume bench interpolation --data {} --files {} --width {} --height {} --time {} --repeats {} --threads {} --rule-width {} --rule-height {} --rule-step {}",
            self.data.display(),
            if self.files.is_empty() { "''".to_string() } else { self.files.join(",") },
            self.width,
            self.height,
            num(self.cpu_seconds),
            self.repeats,
            self.threads,
            self.rule.width,
            self.rule.height,
            num(self.rule.step_voxels)
        );
        if !self.rule.files.is_empty() {
            let files: Vec<String> =
                self.rule.files.iter().map(|f| f.display().to_string()).collect();
            let _ = write!(c, " --rule-files {}", files.join(","));
        }
        if let Some(p) = &self.closeup {
            let _ = write!(
                c,
                " --pictures {} --closeup-width {} --closeup-height {} --closeup-spp {} --closeup-pixels-per-voxel {}",
                p.path.display(),
                p.width,
                p.height,
                p.spp,
                num(p.pixels_per_voxel)
            );
        }
        c
    }
}

/// Samples per CPU second of one reconstruction over the repeats.
#[derive(Clone, Debug, Serialize)]
pub struct Rates {
    /// Median samples per CPU second.
    pub median: f64,
    /// Every repeat, in order.
    pub runs: Vec<f64>,
    /// DDA pieces per camera sample (voxel steps, or dual cells, plus skipped nodes).
    pub pieces_per_sample: f64,
    /// Segments (merged pieces) per camera sample.
    pub segments_per_sample: f64,
}

/// One row of the cost table.
#[derive(Clone, Debug, Serialize)]
pub struct CostRow {
    /// File name ([`CostFile::name`]).
    pub file: String,
    /// Method.
    pub method: String,
    /// Samples per pixel of every timed render.
    pub spp: u32,
    /// Nearest reconstruction.
    pub nearest: Rates,
    /// Trilinear reconstruction.
    pub linear: Rates,
    /// Cost of linear relative to nearest: `nearest.median / linear.median`.
    pub cost_ratio: f64,
    /// Smallest and largest ratio of the repeats' pairs.
    pub cost_ratio_range: [f64; 2],
}

/// One row of the memory table.
#[derive(Clone, Debug, Serialize)]
pub struct MemoryRow {
    /// File name.
    pub file: String,
    /// Bytes of the volume: bricks, table, values and pyramid.
    pub volume_bytes: u64,
    /// Bytes of the dual pyramid and the block masks (all that trilinear adds).
    pub dual_bytes: u64,
    /// `100 · dual / volume`.
    pub percent: f64,
}

/// Everything `plume bench interpolation` measured.
#[derive(Clone, Debug, Serialize)]
pub struct InterpolationReport {
    /// Image size of the cost renders.
    pub width: u32,
    /// Image size of the cost renders.
    pub height: u32,
    /// Render threads of the cost renders.
    pub threads: usize,
    /// Timed renders per reconstruction and method.
    pub repeats: u32,
    /// Cost rows, per file and method.
    pub cost: Vec<CostRow>,
    /// Memory rows, per file.
    pub memory: Vec<MemoryRow>,
    /// The emission-rule comparison.
    pub rule: rule::RuleReport,
    /// The close-up picture, when made.
    pub closeup: Option<closeup::CloseupReport>,
    /// Wall seconds of the whole benchmark.
    pub wall_seconds: f64,
}

/// CPU seconds and counters of one render of `spp` at seed 0.
fn timed_render(
    scene: &AnyScene,
    integrator: Integrator,
    spp: u32,
    threads: usize,
) -> (f64, Counters) {
    let settings = RenderSettings {
        budget: SampleBudget::Spp(spp),
        seed: 0,
        sampler: plume_core::sampling::SamplerKind::default(),
        threads,
        first_sample: 0,
        adaptive: None,
        integrator,
    };
    plume_engine::with_scene!(scene, s => {
        let c0 = cpu_seconds();
        let r = render(s, &settings, &|_, _| {});
        (cpu_seconds() - c0, r.counters)
    })
}

fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    match s.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => s[n / 2],
        n => 0.5 * (s[n / 2 - 1] + s[n / 2]),
    }
}

/// Measure one method on a loaded scene: calibrate the spp, then alternate.
fn measure(
    scene: &mut Switch,
    file: &str,
    method: CostMethod,
    base: Integrator,
    cfg: &InterpolationConfig,
) -> CostRow {
    let integrator = method.integrator(base);
    let pixels = f64::from(cfg.width) * f64::from(cfg.height);
    // Calibration (and warm-up of both): one spp each
    let (c_nearest, _) = timed_render(scene.to(Interpolation::Nearest), integrator, 1, cfg.threads);
    let _ = timed_render(scene.to(Interpolation::Linear), integrator, 1, cfg.threads);
    let spp = (cfg.cpu_seconds / c_nearest.max(1e-6)).round().clamp(1.0, 65536.0) as u32;
    let samples = pixels * f64::from(spp);
    let mut runs = [Vec::new(), Vec::new()];
    let mut counters = [Counters::default(), Counters::default()];
    for k in 0..cfg.repeats.max(1) {
        let order = if k % 2 == 0 {
            [Interpolation::Nearest, Interpolation::Linear]
        } else {
            [Interpolation::Linear, Interpolation::Nearest]
        };
        for i in order {
            let (cpu, c) = timed_render(scene.to(i), integrator, spp, cfg.threads);
            let slot = usize::from(i == Interpolation::Linear);
            runs[slot].push(samples / cpu.max(1e-9));
            counters[slot].merge(&c);
        }
    }
    let rates = |slot: usize| {
        let c = &counters[slot];
        let n = c.samples.max(1) as f64;
        Rates {
            median: median(&runs[slot]),
            runs: runs[slot].clone(),
            pieces_per_sample: c.voxel_steps as f64 / n,
            segments_per_sample: c.segments as f64 / n,
        }
    };
    let (nearest, linear) = (rates(0), rates(1));
    let pairs: Vec<f64> = nearest.runs.iter().zip(&linear.runs).map(|(n, l)| n / l).collect();
    let lo = pairs.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = pairs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    CostRow {
        file: file.into(),
        method: method.name().into(),
        spp,
        cost_ratio: nearest.median / linear.median,
        cost_ratio_range: [lo, hi],
        nearest,
        linear,
    }
}

/// Load `file` (nearest; albedo 0.8) and measure its memory and every method's cost.
fn measure_file(
    file: &CostFile,
    cfg: &InterpolationConfig,
    log: &dyn Fn(&str),
) -> Result<(MemoryRow, Vec<CostRow>)> {
    let path = cfg.data.join(file.file);
    let own = format!("[volume]\ninterpolation = \"nearest\"\n[medium]\nalbedo = 0.8\n[camera]\nwidth = {}\nheight = {}", cfg.width, cfg.height);
    // Two fragments: both may name the same table
    let shot = with_keys(&with_keys(&bench_shot(&path.display().to_string()), file.keys)?, &own)?;
    let loaded = load_file(shot, vec![])?;
    let base = plume_engine::integrator::Integrator::for_scene(&loaded.shot.scene);
    let proxy_resolution = ProxyGrid::resolution_for(
        loaded.loaded.scene.volume(),
        loaded.shot.scene.integrator.proxy_resolution,
    );
    let mut scene = Switch(Some(loaded.loaded.scene));
    let volume_bytes = scene.to(Interpolation::Nearest).volume().memory_bytes() as u64;
    let dual_bytes = match scene.to(Interpolation::Linear) {
        AnyScene::Linear(s) => s.field.dual_bytes() as u64,
        _ => unreachable!("invariant: one volume, switched to linear"),
    };
    let memory = MemoryRow {
        file: file.name.into(),
        volume_bytes,
        dual_bytes,
        percent: 100.0 * dual_bytes as f64 / volume_bytes.max(1) as f64,
    };
    let mut rows = Vec::new();
    for method in CostMethod::ALL {
        // Light structures for this method, outside the timed renders
        let current = scene.0.as_mut().expect("invariant: the scene is in place");
        let lights = Lights::build(
            current.volume(),
            &current.medium().emission,
            method.integrator(base).light_sampling,
            proxy_resolution,
        )?;
        current.set_lights(lights);
        let row = measure(&mut scene, file.name, method, base, cfg);
        log(&format!(
            "{} {}: {} spp, nearest {} / linear {} samples per CPU s: linear costs {:.2}×",
            file.name,
            row.method,
            row.spp,
            num(row.nearest.median),
            num(row.linear.median),
            row.cost_ratio
        ));
        rows.push(row);
    }
    Ok((memory, rows))
}

/// Run the benchmark: cost and memory per file, the emission rule, the close-up.
///
/// # Errors
/// An unknown `--files` name, a missing or unreadable file, an unwritable picture.
pub fn run(cfg: &InterpolationConfig, log: &dyn Fn(&str)) -> Result<InterpolationReport> {
    let start = Instant::now();
    let mut files = Vec::new();
    for name in &cfg.files {
        let f = COST_FILES.iter().find(|f| f.name == name).ok_or_else(|| {
            Error::invalid(
                "--files",
                format!(
                    "{name:?}: expected some of {}",
                    COST_FILES.iter().map(|f| f.name).collect::<Vec<_>>().join(", ")
                ),
            )
        })?;
        files.push(*f);
    }
    let mut cost = Vec::new();
    let mut memory = Vec::new();
    for f in &files {
        log(&format!("== cost and memory: {}", f.file));
        let (m, rows) = measure_file(f, cfg, log)?;
        memory.push(m);
        cost.extend(rows);
    }
    log("== emission rule: plume's against Cycles'");
    let rule = rule::run(&cfg.data, &cfg.rule, log)?;
    let closeup = match &cfg.closeup {
        Some(c) => {
            log("== close-up picture");
            Some(closeup::run(&cfg.data, c, log)?)
        }
        None => None,
    };
    Ok(InterpolationReport {
        width: cfg.width,
        height: cfg.height,
        threads: cfg.threads,
        repeats: cfg.repeats.max(1),
        cost,
        memory,
        rule,
        closeup,
        wall_seconds: start.elapsed().as_secs_f64(),
    })
}

impl InterpolationReport {
    /// The cost table (Markdown).
    #[must_use]
    pub fn cost_table(&self) -> String {
        let mut s = String::from(
            "| file | method | spp | nearest samples / CPU s | linear samples / CPU s | linear cost ÷ nearest (range) | DDA pieces per sample, nearest → linear | ≤ 2× |\n|---|---|---|---|---|---|---|---|\n",
        );
        for r in &self.cost {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | **{:.2}×** ({:.2}–{:.2}) | {:.0} → {:.0} | {} |",
                r.file,
                r.method,
                r.spp,
                num(r.nearest.median),
                num(r.linear.median),
                r.cost_ratio,
                r.cost_ratio_range[0],
                r.cost_ratio_range[1],
                r.nearest.pieces_per_sample,
                r.linear.pieces_per_sample,
                if r.cost_ratio <= 2.0 { "yes" } else { "**no**" }
            );
        }
        s
    }

    /// The memory table (Markdown).
    #[must_use]
    pub fn memory_table(&self) -> String {
        let mut s =
            String::from("| file | volume (bricks, table, values, pyramid) | dual pyramid and block masks | dual ÷ volume | ≤ 10 % |\n|---|---|---|---|---|\n");
        for m in &self.memory {
            let _ = writeln!(
                s,
                "| {} | {:.2} MiB | {:.1} KiB | **{:.2} %** | {} |",
                m.file,
                m.volume_bytes as f64 / 1048576.0,
                m.dual_bytes as f64 / 1024.0,
                m.percent,
                if m.percent <= 10.0 { "yes" } else { "**no**" }
            );
        }
        s
    }

    /// The whole section (Markdown): setup, tables, the command that reproduces them
    /// (`command`), picture (linked as `picture_link`).
    #[must_use]
    pub fn markdown(&self, command: &str, picture_link: Option<&str>) -> String {
        let mut md = String::new();
        if !self.cost.is_empty() {
            let _ = writeln!(
                md,
                "**Cost per sample.** Each file loaded once and rendered {}×{}, {} thread{}, seed 0, the same camera and spp for both reconstructions; {} timed renders each, nearest and linear alternated (N L, L N, …); medians of samples per CPU second. The spp was set so that a nearest render takes the target CPU time. Scattering rows: albedo 0.8, max depth 64; light structures built outside the timed renders. DDA pieces are voxels (nearest) or dual cells (linear) crossed plus skipped pyramid nodes.\n",
                self.width,
                self.height,
                self.threads,
                if self.threads == 1 { "" } else { "s" },
                self.repeats
            );
            let _ = writeln!(md, "Files:\n");
            for f in COST_FILES.iter().filter(|f| self.memory.iter().any(|m| m.file == f.name)) {
                let _ = writeln!(md, "- `{}`: `{}`, {}.", f.name, f.file, f.about);
            }
            let _ = writeln!(md, "\n{}", self.cost_table());
            let _ =
                writeln!(md, "**Memory.** Trilinear reads the corners from the volume's own bricks; it adds only the dual pyramid and 8 bytes per brick of block masks.\n\n{}", self.memory_table());
        }
        let _ = writeln!(md, "{}", self.rule.markdown());
        let _ = writeln!(md, "Every table and the close-up:\n\n```sh\n{command}\n```\n");
        if let (Some(c), Some(link)) = (&self.closeup, picture_link) {
            let _ = writeln!(md, "{}\n\n![nearest | linear close-up]({link})\n", c.caption());
        }
        let _ = writeln!(md, "Wall time {:.0} s.\n", self.wall_seconds);
        md
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_of_odd_and_even_counts() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, 3.0, 2.0]), 2.5);
        assert!(median(&[]).is_nan());
    }

    #[test]
    fn cost_files_have_unique_names() {
        for (i, a) in COST_FILES.iter().enumerate() {
            assert!(COST_FILES[i + 1..].iter().all(|b| b.name != a.name));
        }
    }
}
