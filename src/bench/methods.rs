//! `plume bench methods`: the paper's equal-time comparison (METHOD.md §9) on generated
//! explosions, "thin" and "dense".
//!
//! For each regime: a converged reference (a long `line-fnee` render with its own seed and
//! a CPU-time budget),
//! then every method for the same CPU time (`SampleBudget::CpuTime`, so a loaded machine
//! does not favour one method),
//! reporting RMSE against the reference (over all RGB values), spp reached, samples per
//! CPU second and core-hours. The ratio `RMSE(line-fnee) / RMSE(point-nee)` is the
//! paper's figure (0.76 thin, 0.64 dense in the authors' slides).
//!
//! `plume bench compare` measures the same on any scene, with several seeds, CPU-time
//! budgets, relMSE and bias; this command is kept for its fixed, quick setup.

use std::time::Instant;

use glam::DVec3;
use serde::Serialize;

use plume_core::error::Result;
use plume_engine::camera::Camera;
use plume_engine::integrator::{Integrator, LightSampling, Lights, MisHeuristic, Scene, Tracking};
use plume_engine::medium::{Collision, Emission, Estimator, Medium};
use plume_engine::render::{render, RenderSettings, SampleBudget};
use plume_engine::stats::cpu_seconds;
use plume_synth::{explosion, ExplosionParams};
use plume_volume::{Field, Volume};

/// The methods compared, as (name, estimator, light sampling).
pub const METHODS: [(&str, Estimator, LightSampling); 5] = [
    ("point-nee", Estimator::Point, LightSampling::Nee),
    ("line-nee", Estimator::Line, LightSampling::Nee),
    ("line-fnee", Estimator::Line, LightSampling::Fnee),
    ("ray-march", Estimator::RayMarch, LightSampling::None),
    // METHOD §4's extension beyond the paper, measured beside it
    ("blend-fnee", Estimator::Blend { kappa: 4.0 }, LightSampling::Fnee),
];

/// One method's result in one regime.
#[derive(Debug, Serialize)]
pub struct MethodResult {
    /// Regime (`thin` or `dense`).
    pub regime: String,
    /// Method name.
    pub method: String,
    /// RMSE against the reference, all RGB values.
    pub rmse: f64,
    /// Samples per pixel reached.
    pub spp: u64,
    /// Camera samples per CPU second.
    pub samples_per_cpu_second: f64,
    /// CPU core-hours spent.
    pub core_hours: f64,
}

/// Everything `plume bench methods` measured.
#[derive(Debug, Serialize)]
pub struct MethodsReport {
    /// Explosion resolution.
    pub resolution: u32,
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
    /// CPU seconds per method.
    pub seconds_per_method: f64,
    /// Reference spp per regime.
    pub reference_spp: Vec<(String, u64)>,
    /// Results.
    pub results: Vec<MethodResult>,
}

fn scene(
    resolution: u32,
    sigma_t: f64,
    ls: LightSampling,
    width: u32,
    height: u32,
    proxy: u32,
) -> Result<Scene<Volume>> {
    let ex = explosion(&ExplosionParams { resolution, seed: 1, ..Default::default() });
    let e = Emission::blackbody(1.0);
    let vol = Volume::build(&ex.density, Some(&ex.temperature), |v| e.map_source(v))?;
    let lights = Lights::build(&vol, &e, ls, proxy.min(resolution.next_power_of_two()))?;
    let plume_volume::Bounds3 { lo, hi } = vol.world_bounds();
    let camera =
        Camera::frame_bounds(lo, hi, DVec3::new(0.35, 0.25, 1.0), DVec3::Y, 40.0, width, height)?;
    Ok(Scene {
        field: vol,
        medium: Medium {
            sigma_t,
            albedo: plume_core::color::Rgb::splat(0.8),
            g: 0.3,
            emission: e,
            extinction: Default::default(),
        },
        camera,
        lights,
        motion: None,
        majorants: None,
    })
}

fn integrator(
    estimator: Estimator,
    light_sampling: LightSampling,
    mis: MisHeuristic,
) -> Integrator {
    Integrator {
        estimator,
        camera_estimator: None,
        light_sampling,
        mis,
        max_depth: 64,
        tracking: Tracking::Regular,
        split: 1,
        camera_collision: Collision::Analog,
        point_lookup: plume_engine::integrator::PointLookup::Exact,
        split_by: plume_engine::integrator::SplitBy::Uniform,
    }
}

pub use super::metrics::rmse;

/// Parse `NAME=DENSITY_SCALE,…` (the regimes of the comparison).
///
/// # Errors
/// [`crate::Error::InvalidArgument`] for `regimes` naming the bad item.
pub fn parse_regimes(list: &str) -> Result<Vec<(String, f64)>> {
    let mut regimes = Vec::new();
    for part in list.split(',') {
        let bad = |m: String| crate::Error::invalid("regimes", m);
        let (name, v) = part
            .split_once('=')
            .ok_or_else(|| bad(format!("{part:?} is not NAME=DENSITY_SCALE")))?;
        let v: f64 = v.parse().map_err(|_| bad(format!("{v:?} is not a number")))?;
        regimes.push((name.to_string(), v));
    }
    Ok(regimes)
}

/// Run the comparison.
///
/// # Errors
/// Scene construction failures (not expected for generated data).
#[allow(clippy::too_many_arguments)] // one flag each
pub fn run(
    resolution: u32,
    width: u32,
    height: u32,
    seconds: f64,
    reference_seconds: f64,
    threads: usize,
    mis: MisHeuristic,
    proxy: u32,
    regimes: &[(&str, f64)],
    on_line: &dyn Fn(&str),
) -> Result<MethodsReport> {
    let mut results = Vec::new();
    let mut reference_spp = Vec::new();
    for &(regime, sigma_t) in regimes {
        let s = scene(resolution, sigma_t, LightSampling::Fnee, width, height, 64)?;
        let t = Instant::now();
        let reference = render(
            &s,
            &RenderSettings {
                budget: SampleBudget::CpuTime(reference_seconds),
                seed: 1_000_003,
                sampler: plume_core::sampling::SamplerKind::default(),
                threads,
                first_sample: 0,
                adaptive: None,
                integrator: integrator(Estimator::Line, LightSampling::Fnee, MisHeuristic::Power),
            },
            &|_, _| {},
        );
        on_line(&format!(
            "{regime}: reference line-fnee {} spp in {:.0} s",
            reference.spp,
            t.elapsed().as_secs_f64()
        ));
        reference_spp.push((regime.to_string(), reference.spp));
        let ref_px = reference.film.average();
        for (name, est, ls) in METHODS {
            let s = scene(resolution, sigma_t, ls, width, height, proxy)?;
            let cpu0 = cpu_seconds();
            let r = render(
                &s,
                &RenderSettings {
                    budget: SampleBudget::CpuTime(seconds),
                    seed: 7,
                    sampler: plume_core::sampling::SamplerKind::default(),
                    threads,
                    first_sample: 0,
                    adaptive: None,
                    integrator: integrator(est, ls, mis),
                },
                &|_, _| {},
            );
            let cpu = cpu_seconds() - cpu0;
            let res = MethodResult {
                regime: regime.into(),
                method: name.into(),
                rmse: rmse(&r.film.average(), &ref_px),
                spp: r.spp,
                samples_per_cpu_second: r.counters.samples as f64 / cpu.max(1e-9),
                core_hours: cpu / 3600.0,
            };
            on_line(&format!("{regime}: {name}: RMSE {:.5} at {} spp", res.rmse, res.spp));
            results.push(res);
        }
    }
    Ok(MethodsReport {
        resolution,
        width,
        height,
        seconds_per_method: seconds,
        reference_spp,
        results,
    })
}

impl std::fmt::Display for MethodsReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "Equal CPU time ({:.0} CPU s per method), {}³ explosion, {}x{}:",
            self.seconds_per_method, self.resolution, self.width, self.height
        )?;
        writeln!(
            f,
            "| regime | method | RMSE | RMSE / point-nee | spp | samples per CPU s | core-hours |"
        )?;
        writeln!(f, "|---|---|---|---|---|---|---|")?;
        for r in &self.results {
            let base = self
                .results
                .iter()
                .find(|b| b.regime == r.regime && b.method == "point-nee")
                .map_or(f64::NAN, |b| b.rmse);
            writeln!(
                f,
                "| {} | {} | {:.5} | {:.2} | {} | {:.0} | {:.5} |",
                r.regime,
                r.method,
                r.rmse,
                r.rmse / base,
                r.spp,
                r.samples_per_cpu_second,
                r.core_hours
            )?;
        }
        Ok(())
    }
}
