//! `plume bench compare`: methods at equal CPU time and at equal spp against a reference,
//! with several seeds per point.
//!
//! For each method: build its light-sampling structures (timed, not part of the render
//! budget), then `runs` progressive runs with seeds `seed, seed + 1, …`, each lasting
//! `--time` CPU seconds (and at least `--spp` spp when given). Every run records the
//! error curve at `T/2^k` and the errors at each power-of-two spp ([`super::progressive`]).
//! Figures are reported as mean ± sample std over the runs.
//!
//! **Reference.** Either given (`--reference REF.exr`) or computed (`--make-reference`):
//! for emission-only scenes (albedo 0 or `--max-depth 0`) the expected-value estimator
//! (ray-march, forward only), otherwise a long `line-fnee` run, each with seeds no method
//! run uses. A computed reference is rendered as two independent halves; their difference
//! estimates the reference's own noise: with `n_a`, `n_b` spp,
//! `RMSE_ref ≈ RMSE(a, b) · √(n_a n_b) / (n_a + n_b)`. Measured RMSEs include it
//! (`E[RMSE²] = MSE_method + MSE_ref`), so it is reported beside them.

use std::time::Instant;

use serde::Serialize;

use super::metrics::{mean_rgb, Errors, Spread, RELMSE_TRIM};
use super::progressive::{self, RunPlan, RunResult, Snapshot};
use super::spec::{BenchScene, MethodSpec};
use super::targets::{time_to_targets, AdaptivePoint, CurvePoint, SeriesPlan, TimeToError};
use super::{peak_rss_bytes, reset_peak_rss};
use plume_core::error::{Error, Result};
use plume_engine::integrator::{Integrator, LightSampling, Lights};
use plume_engine::medium::Estimator;

/// Seeds of the two reference halves (no method run uses seeds this large).
const REFERENCE_SEEDS: [u64; 2] = [0x7265_6600_0000_0001, 0x7265_6600_0000_0002];

/// A reference image and how it was made.
#[derive(Clone, Debug, Serialize)]
pub struct Reference {
    /// Row-major RGBA.
    #[serde(skip)]
    pub pixels: Vec<[f32; 4]>,
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
    /// How it was made, in words.
    pub description: String,
    /// Method used (`given` for a file).
    pub method: String,
    /// Samples per pixel (0 for a file).
    pub spp: u64,
    /// CPU seconds spent (0 for a file).
    pub cpu_seconds: f64,
    /// Wall seconds spent (0 for a file).
    pub wall_seconds: f64,
    /// Estimated RMSE of the reference itself (computed references only).
    pub noise_rmse: Option<f64>,
}

/// True when the scene's paths never scatter (emission–absorption only).
#[must_use]
pub fn emission_only(scene: &BenchScene) -> bool {
    !scene.shot.scene.scatters()
}

/// Build the light structures of `light_sampling` into the scene (nothing when paths do
/// not scatter); returns their heap bytes.
fn install_lights(
    scene: &mut BenchScene,
    light_sampling: LightSampling,
    proxy_resolution: u32,
) -> Result<u64> {
    let only = emission_only(scene);
    let s = &mut scene.loaded.scene;
    let lights = if only {
        Lights::default()
    } else {
        Lights::build_with(
            s.volume(),
            &s.medium().emission,
            light_sampling,
            proxy_resolution,
            scene.shot.scene.integrator.nee_table,
        )?
    };
    s.set_lights(lights);
    let l = scene.loaded.scene.lights();
    Ok((l.nee.as_ref().map_or(0, |n| n.memory_bytes())
        + l.proxy.as_ref().map_or(0, |p| p.memory_bytes())) as u64)
}

fn integrator_for(
    scene: &BenchScene,
    estimator: Estimator,
    light_sampling: LightSampling,
) -> Integrator {
    plume_engine::integrator::Integrator::for_scene_with(
        &scene.shot.scene,
        estimator,
        light_sampling,
    )
}

/// Read a reference EXR and check its size against the scene's.
///
/// # Errors
/// An unreadable file, or a size other than `--width`×`--height`.
pub fn read_reference(path: &std::path::Path, scene: &BenchScene) -> Result<Reference> {
    let crate::output::RgbaImage { width: w, height: h, pixels } = crate::output::read_exr(path)?;
    if (w, h) != (scene.shot.scene.camera.width, scene.shot.scene.camera.height) {
        return Err(Error::invalid(
            "--reference",
            format!(
                "{} is {w}x{h}, the scene renders {}x{}",
                path.display(),
                scene.shot.scene.camera.width,
                scene.shot.scene.camera.height
            ),
        ));
    }
    Ok(Reference {
        pixels,
        width: w,
        height: h,
        description: format!("given: {}", path.display()),
        method: "given".into(),
        spp: 0,
        cpu_seconds: 0.0,
        wall_seconds: 0.0,
        noise_rmse: None,
    })
}

/// Compute a reference with `cpu_seconds` CPU seconds (see the module docs).
///
/// # Errors
/// Light structures cannot be built (an invalid `--proxy-resolution`).
pub fn make_reference(
    scene: &mut BenchScene,
    cpu_seconds: f64,
    on_line: &dyn Fn(&str),
) -> Result<Reference> {
    let (method, estimator, ls, why) = if emission_only(scene) {
        (
            "ray-march",
            Estimator::RayMarch,
            LightSampling::None,
            "expected-value estimator (ray-march, forward only): the scene is emission-only",
        )
    } else {
        (
            "line-fnee",
            Estimator::Line,
            LightSampling::Fnee,
            "long line-fnee run: the scene scatters",
        )
    };
    install_lights(
        scene,
        ls,
        plume_volume::proxy::ProxyGrid::resolution_for(
            scene.loaded.scene.volume(),
            scene.shot.scene.integrator.proxy_resolution,
        ),
    )?;
    let integ = integrator_for(scene, estimator, ls);
    let wall = Instant::now();
    let halves: Vec<RunResult> = REFERENCE_SEEDS
        .iter()
        .map(|&seed| {
            let plan = RunPlan {
                cpu_checkpoints: vec![0.5 * cpu_seconds],
                min_spp: 1,
                seed,
                sampler: scene.shot.settings.render.sampler,
                threads: scene.shot.settings.render.threads,
            };
            plume_engine::with_scene!(&scene.loaded.scene, s => progressive::run(s, &integ, &plan, None, 0.0))
        })
        .collect();
    let (a, b) = (&halves[0], &halves[1]);
    let (na, nb) = (a.spp as f64, b.spp as f64);
    let sums: Vec<[f64; 4]> = a
        .sums
        .iter()
        .zip(&b.sums)
        .map(|(x, y)| [x[0] + y[0], x[1] + y[1], x[2] + y[2], x[3] + y[3]])
        .collect();
    let pixels = progressive::average(&sums, a.spp + b.spp);
    let noise = super::metrics::rmse(&a.image, &b.image) * (na * nb).sqrt() / (na + nb);
    let spp = a.spp + b.spp;
    let cpu = a.cpu_seconds + b.cpu_seconds;
    let wall = wall.elapsed().as_secs_f64();
    let description = format!("computed: {why}; {spp} spp in {cpu:.1} CPU s ({wall:.1} s wall), two halves with seeds unused by the runs");
    on_line(&format!("reference: {description}; estimated own RMSE {noise:.4e}"));
    Ok(Reference {
        pixels,
        width: scene.shot.scene.camera.width,
        height: scene.shot.scene.camera.height,
        description,
        method: method.into(),
        spp,
        cpu_seconds: cpu,
        wall_seconds: wall,
        noise_rmse: Some(noise),
    })
}

/// Settings of a comparison.
#[derive(Clone, Debug)]
pub struct CompareConfig {
    /// The methods, the first being the baseline of ratios.
    pub methods: Vec<MethodSpec>,
    /// CPU seconds per run (equal-time budget).
    pub cpu_seconds: f64,
    /// Equal-spp point; `None`: the largest power of two every run reaches.
    pub spp: Option<u32>,
    /// Runs (seeds) per method.
    pub runs: u32,
    /// relMSE ε.
    pub epsilon: f64,
    /// Points of the error-vs-time curve: `T/2^k`, `k < curve_points`.
    pub curve_points: u32,
    /// Also render each method adaptively at halving noise thresholds
    /// ([`super::targets::adaptive_series`]).
    pub adaptive: bool,
}

/// Statistics of one checkpoint over runs.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct Point {
    /// CPU seconds spent.
    pub cpu_seconds: Spread,
    /// Wall seconds spent.
    pub wall_seconds: Spread,
    /// Samples per pixel.
    pub spp: Spread,
    /// RMSE.
    pub rmse: Spread,
    /// relMSE (trimmed).
    pub relmse: Spread,
    /// Bias `mean(x) − mean(ref)`.
    pub bias: Spread,
}

impl Point {
    fn of(snaps: &[Snapshot]) -> Point {
        let f = |g: &dyn Fn(&Snapshot) -> f64| Spread::of(&snaps.iter().map(g).collect::<Vec<_>>());
        Point {
            cpu_seconds: f(&|s| s.cpu_seconds),
            wall_seconds: f(&|s| s.wall_seconds),
            spp: f(&|s| s.spp as f64),
            rmse: f(&|s| s.errors.rmse),
            relmse: f(&|s| s.errors.relmse),
            bias: f(&|s| s.errors.bias),
        }
    }

    /// The mean CPU time and relative RMSE (`√relMSE`) of this checkpoint: a point of the
    /// uniform error-against-time curve ([`super::targets`]).
    #[must_use]
    pub fn curve_point(&self) -> CurvePoint {
        CurvePoint { cpu_seconds: self.cpu_seconds.mean, rel_rmse: self.relmse.mean.sqrt() }
    }
}

/// One method's results.
#[derive(Clone, Debug, Serialize)]
pub struct MethodResult {
    /// Method name as given.
    pub method: String,
    /// Estimator.
    pub estimator: String,
    /// Light sampling.
    pub light_sampling: String,
    /// FNEE proxy resolution used (FNEE methods on scattering scenes).
    pub proxy_resolution: Option<u32>,
    /// At the CPU-time budget.
    pub equal_time: Point,
    /// At the equal-spp point.
    pub equal_spp: Point,
    /// The error-vs-CPU-time curve, ascending.
    pub curve: Vec<Point>,
    /// CPU seconds to reach each target relative RMSE on the uniform curve
    /// ([`super::targets`]).
    pub to_target: Vec<TimeToError>,
    /// The adaptive renders (with `adaptive`), by threshold.
    pub adaptive: Vec<AdaptivePoint>,
    /// CPU seconds to reach each target on the adaptive curve (empty without it).
    pub adaptive_to_target: Vec<TimeToError>,
    /// Camera samples per CPU second over the whole run.
    pub samples_per_cpu_second: Spread,
    /// Seconds to build the light-sampling structures (not in the render budget).
    pub light_build_seconds: f64,
    /// Heap bytes of the volume plus light-sampling structures.
    pub scene_bytes: u64,
    /// Peak resident set size while this method was built and run (bytes).
    pub peak_rss_bytes: u64,
    /// Whether `peak_rss_bytes` is this method's own peak (`/proc/self/clear_refs`), or the
    /// process's peak so far.
    pub peak_rss_per_method: bool,
    /// Non-finite samples dropped over all runs.
    pub nonfinite_samples: u64,
    /// Final image of the first run.
    #[serde(skip)]
    pub image: Vec<[f32; 4]>,
}

/// Everything one comparison measured.
#[derive(Clone, Debug, Serialize)]
pub struct CompareReport {
    /// Scene spec.
    pub scene: String,
    /// How the scene was given besides its spec (render flags or a scene file).
    pub flags: Vec<String>,
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
    /// Worker threads.
    pub threads: usize,
    /// Paths do not scatter.
    pub emission_only: bool,
    /// Seconds to generate and load the scene.
    pub load_seconds: f64,
    /// The reference.
    pub reference: Reference,
    /// Mean over all RGB values of the reference.
    pub reference_mean: f64,
    /// CPU seconds per run.
    pub cpu_seconds_per_run: f64,
    /// Runs per method.
    pub runs: u32,
    /// CPU-time checkpoints of the curve.
    pub curve_cpu_seconds: Vec<f64>,
    /// The equal-spp point.
    pub equal_spp: u64,
    /// relMSE ε.
    pub relmse_epsilon: f64,
    /// relMSE trim fraction.
    pub relmse_trim: f64,
    /// Per method, in the order given.
    pub methods: Vec<MethodResult>,
}

/// Run the comparison on `scene` (whose light structures it replaces) against `reference`.
///
/// # Errors
/// A reference of the wrong size, or light structures that cannot be built.
pub fn compare(
    scene: &mut BenchScene,
    reference: &Reference,
    cfg: &CompareConfig,
    on_line: &dyn Fn(&str),
) -> Result<CompareReport> {
    let (w, h) = check_inputs(scene, reference, cfg)?;
    let curve: Vec<f64> = (0..cfg.curve_points.max(1))
        .rev()
        .map(|k| cfg.cpu_seconds / f64::from(1u32 << k))
        .collect();
    let mut raw: Vec<(MethodResult, Vec<RunResult>)> = Vec::new();
    for m in &cfg.methods {
        raw.push(measure_method(scene, m, reference, cfg, &curve, on_line)?);
    }
    let equal_spp = equal_spp_point(cfg, &raw);
    let mut methods = Vec::new();
    for (mut result, runs) in raw {
        let snaps: Vec<Snapshot> = runs
            .iter()
            .filter_map(|r| r.spp_points.iter().find(|s| s.spp == equal_spp).copied())
            .collect();
        result.equal_spp = Point::of(&snaps);
        methods.push(result);
    }
    Ok(CompareReport {
        scene: scene.spec.clone(),
        flags: scene.flags.clone(),
        width: w,
        height: h,
        threads: if scene.shot.settings.render.threads == 0 {
            rayon::current_num_threads()
        } else {
            scene.shot.settings.render.threads
        },
        emission_only: emission_only(scene),
        load_seconds: scene.load_seconds,
        reference: reference.clone(),
        reference_mean: mean_rgb(&reference.pixels),
        cpu_seconds_per_run: cfg.cpu_seconds,
        runs: cfg.runs,
        curve_cpu_seconds: curve,
        equal_spp,
        relmse_epsilon: cfg.epsilon,
        relmse_trim: RELMSE_TRIM,
        methods,
    })
}

/// The image size, after checking that the reference has it and that the budget is
/// positive.
fn check_inputs(
    scene: &BenchScene,
    reference: &Reference,
    cfg: &CompareConfig,
) -> Result<(u32, u32)> {
    let (w, h) = (scene.shot.scene.camera.width, scene.shot.scene.camera.height);
    if (reference.width, reference.height) != (w, h) {
        return Err(Error::invalid(
            "--reference",
            format!(
                "reference is {}x{}, the scene renders {w}x{h}",
                reference.width, reference.height
            ),
        ));
    }
    if !(cfg.cpu_seconds.is_finite() && cfg.cpu_seconds > 0.0) || cfg.runs == 0 {
        return Err(Error::invalid(
            "--time/--runs",
            "need a positive CPU time and at least one run",
        ));
    }
    Ok((w, h))
}

/// One method: its light structures built (timed), then `cfg.runs` progressive runs with
/// checkpoints `curve`; its result (without the equal-spp point) and the runs.
fn measure_method(
    scene: &mut BenchScene,
    m: &MethodSpec,
    reference: &Reference,
    cfg: &CompareConfig,
    curve: &[f64],
    on_line: &dyn Fn(&str),
) -> Result<(MethodResult, Vec<RunResult>)> {
    let per_method = reset_peak_rss();
    let proxy = plume_volume::proxy::ProxyGrid::resolution_for(
        scene.loaded.scene.volume(),
        m.proxy_resolution.or(scene.shot.scene.integrator.proxy_resolution),
    );
    let t = Instant::now();
    let light_bytes = install_lights(scene, m.light_sampling, proxy)?;
    let light_build_seconds = t.elapsed().as_secs_f64();
    let mut runs = method_runs(scene, m, reference, cfg, curve, on_line);
    let image = std::mem::take(&mut runs[0].image);
    for r in &mut runs {
        // Keep only the figures: the next method's peak RSS should not carry these
        r.sums = Vec::new();
        r.image = Vec::new();
    }
    let uses_proxy = m.light_sampling == LightSampling::Fnee && !emission_only(scene);
    let curve_points: Vec<Point> = (0..curve.len())
        .map(|k| Point::of(&runs.iter().map(|r| r.time_points[k]).collect::<Vec<_>>()))
        .collect();
    let uniform: Vec<CurvePoint> = curve_points.iter().map(Point::curve_point).collect();
    let adaptive = if cfg.adaptive {
        // Up to 4× the samples the uniform runs took where the error is
        let spp = runs.iter().map(|r| r.spp).max().unwrap_or(1);
        let cap = u32::try_from(4 * spp).unwrap_or(u32::MAX);
        adaptive_runs(scene, m, (reference, cap), cfg, curve, on_line)
    } else {
        Vec::new()
    };
    let adaptive_curve: Vec<CurvePoint> = adaptive.iter().map(|a| a.point).collect();
    let result = MethodResult {
        method: m.name.clone(),
        estimator: format!("{:?}", m.estimator),
        light_sampling: format!("{:?}", m.light_sampling),
        proxy_resolution: uses_proxy.then_some(proxy),
        equal_time: Point::of(
            &runs.iter().filter_map(|r| r.time_points.last().copied()).collect::<Vec<_>>(),
        ),
        equal_spp: Point::default(),
        to_target: time_to_targets(&uniform),
        adaptive_to_target: if cfg.adaptive {
            time_to_targets(&adaptive_curve)
        } else {
            Vec::new()
        },
        adaptive,
        curve: curve_points,
        samples_per_cpu_second: Spread::of(
            &runs
                .iter()
                .map(|r| r.counters.samples as f64 / r.cpu_seconds.max(1e-9))
                .collect::<Vec<_>>(),
        ),
        light_build_seconds,
        scene_bytes: scene.loaded.scene.volume().memory_bytes() as u64 + light_bytes,
        peak_rss_bytes: peak_rss_bytes(),
        peak_rss_per_method: per_method,
        nonfinite_samples: runs.iter().map(|r| r.counters.nonfinite_samples).sum(),
        image,
    };
    Ok((result, runs))
}

/// The `cfg.runs` progressive runs of method `m` (its lights installed), seeds `seed, seed
/// + 1, …`, each line of progress to `on_line`.
fn method_runs(
    scene: &BenchScene,
    m: &MethodSpec,
    reference: &Reference,
    cfg: &CompareConfig,
    curve: &[f64],
    on_line: &dyn Fn(&str),
) -> Vec<RunResult> {
    let integ = integrator_for(scene, m.estimator, m.light_sampling);
    let mut runs = Vec::new();
    for r in 0..cfg.runs {
        let plan = run_plan(scene, cfg, curve, r);
        let res = plume_engine::with_scene!(&scene.loaded.scene, s => progressive::run(s, &integ, &plan, Some(&reference.pixels), cfg.epsilon));
        let last = res.time_points.last().copied();
        if let Some(s) = last {
            on_line(&format!(
                "{}: run {}: {} spp in {:.1} CPU s, RMSE {:.4e}",
                m.name,
                r + 1,
                s.spp,
                s.cpu_seconds,
                s.errors.rmse
            ));
        }
        runs.push(res);
    }
    runs
}

/// The plan of run `r` (seed `seed + r`) to the checkpoints `curve`.
fn run_plan(scene: &BenchScene, cfg: &CompareConfig, curve: &[f64], r: u32) -> RunPlan {
    RunPlan {
        cpu_checkpoints: curve.to_vec(),
        min_spp: cfg.spp.map_or(1, u64::from),
        seed: scene.shot.settings.render.seed.unwrap_or(0) + u64::from(r),
        sampler: scene.shot.settings.render.sampler,
        threads: scene.shot.settings.render.threads,
    }
}

/// The adaptive series of method `m` (its lights installed), with the first run's seed,
/// each render's line to `on_line`.
fn adaptive_runs(
    scene: &BenchScene,
    m: &MethodSpec,
    (reference, cap): (&Reference, u32),
    cfg: &CompareConfig,
    curve: &[f64],
    on_line: &dyn Fn(&str),
) -> Vec<AdaptivePoint> {
    let integ = integrator_for(scene, m.estimator, m.light_sampling);
    let plan = run_plan(scene, cfg, curve, 0);
    let series_plan = SeriesPlan {
        budget: cfg.cpu_seconds,
        cap,
        reference: &reference.pixels,
        epsilon: cfg.epsilon,
    };
    let series = plume_engine::with_scene!(&scene.loaded.scene, s => super::targets::adaptive_series(s, &integ, &plan, &series_plan));
    for a in &series {
        on_line(&format!(
            "{}: adaptive, threshold {}: {:.1} spp on average (cap {cap}, reached by {} pixels) in {:.1} CPU s, relRMSE {:.4} (its own estimate: {})",
            m.name,
            a.threshold,
            a.mean_spp,
            a.pixels_at_cap,
            a.point.cpu_seconds,
            a.point.rel_rmse,
            a.estimated_rel_rmse.map_or("none".into(), |e| format!("{e:.4}"))
        ));
    }
    series
}

/// Equal spp: as asked, or the largest power of two every run reached.
fn equal_spp_point(cfg: &CompareConfig, raw: &[(MethodResult, Vec<RunResult>)]) -> u64 {
    match cfg.spp {
        Some(n) => u64::from(n),
        None => {
            let reached = raw
                .iter()
                .flat_map(|(_, runs)| runs.iter().map(|r| r.spp))
                .min()
                .unwrap_or(1)
                .max(1);
            1u64 << (63 - reached.leading_zeros())
        }
    }
}

impl CompareReport {
    /// Efficiency `1/(RMSE² · CPU s)` of `m` at equal time relative to the first method.
    #[must_use]
    pub fn efficiency(&self, m: &MethodResult) -> f64 {
        let base = &self.methods[0].equal_time;
        let e = &m.equal_time;
        (base.rmse.mean.powi(2) * base.cpu_seconds.mean)
            / (e.rmse.mean.powi(2) * e.cpu_seconds.mean)
    }

    /// Errors of a method's equal-time images as [`Errors`] means (for summaries).
    #[must_use]
    pub fn equal_time_errors(&self, method: &str) -> Option<Errors> {
        self.methods.iter().find(|m| m.method == method).map(|m| Errors {
            rmse: m.equal_time.rmse.mean,
            relmse: m.equal_time.relmse.mean,
            bias: m.equal_time.bias.mean,
        })
    }
}
