//! The cost of an accuracy, in the units a farm pays for: for each method, the CPU time
//! (and core-hours) it needs to reach a relative RMSE of 0.05, 0.02 and 0.01 against the
//! reference, read off its error-against-CPU-time curve, uniform and adaptive.
//!
//! - **Uniform**: the curve of `plume bench compare`'s progressive runs (means over runs).
//! - **Adaptive**: one render per noise threshold `T = 0.1, 0.05, 0.025, …` (halving),
//!   each with `min_spp` 16, the relMSE's floor (`√ε`) and a cap of 4× the spp the uniform
//!   runs reached in the budget; the series ends with the first render that spends the
//!   run's CPU budget, or after eight.
//!
//! The relative RMSE is `√relMSE` (trimmed, with the comparison's `ε`). Between two curve
//! points the time is interpolated on log–log axes; past the last point it is extrapolated
//! with the Monte Carlo rate `relRMSE ∝ t^(−1/2)` (`t = t_last · (e_last / target)²`) and
//! marked as extrapolated; before the first point likewise, backwards.

use serde::Serialize;

use super::metrics::Errors;
use plume_engine::integrator::{Integrator, Scene};
use plume_engine::noise::Adaptive;
use plume_engine::render::{render_with, RenderControl, RenderSettings, SampleBudget};
use plume_engine::stats::cpu_seconds;
use plume_volume::Field;

/// The relative RMSEs whose cost is reported.
pub const TARGETS: [f64; 3] = [0.05, 0.02, 0.01];

/// The first noise threshold of the adaptive series.
const FIRST_THRESHOLD: f64 = 0.1;

/// At most this many adaptive renders per method.
const MAX_THRESHOLDS: usize = 8;

/// A point of an error-against-CPU-time curve.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct CurvePoint {
    /// CPU seconds spent.
    pub cpu_seconds: f64,
    /// Relative RMSE against the reference (`√relMSE`).
    pub rel_rmse: f64,
}

/// One adaptive render of the series.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct AdaptivePoint {
    /// The noise threshold.
    pub threshold: f64,
    /// CPU seconds and measured relative RMSE.
    pub point: CurvePoint,
    /// The render's own estimate of its relative RMSE over the pixels the measurement
    /// takes (all of them): its pooled standard errors (`noise::FrameNoise`) relative to
    /// its pixel values with the relMSE's `ε`.
    pub estimated_rel_rmse: Option<f64>,
    /// Mean samples per pixel.
    pub mean_spp: f64,
    /// Pixels that reached the cap without converging.
    pub pixels_at_cap: u64,
}

/// The CPU time a method needs for one target.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TimeToError {
    /// The relative RMSE aimed at.
    pub target: f64,
    /// CPU seconds (`None` without a curve).
    pub cpu_seconds: Option<f64>,
    /// Whether the time lies outside the measured curve (extrapolated at `t^(−1/2)`).
    pub extrapolated: bool,
}

/// The points of a curve that have a time and an error, in increasing CPU time.
fn measured(points: &[CurvePoint]) -> Vec<CurvePoint> {
    let mut p: Vec<CurvePoint> = points
        .iter()
        .copied()
        .filter(|q| q.cpu_seconds > 0.0 && q.rel_rmse.is_finite() && q.rel_rmse > 0.0)
        .collect();
    p.sort_by(|a, b| a.cpu_seconds.total_cmp(&b.cpu_seconds));
    p
}

/// The CPU time to each of [`TARGETS`] on the curve `points` (any order).
#[must_use]
pub fn time_to_targets(points: &[CurvePoint]) -> Vec<TimeToError> {
    let p = measured(points);
    TARGETS.iter().map(|&target| time_to(&p, target)).collect()
}

/// The relative RMSE a curve reaches at a CPU time.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ErrorAt {
    /// Relative RMSE.
    pub rel_rmse: f64,
    /// Whether the time lies outside the measured curve (extrapolated at `t^(−1/2)`).
    pub extrapolated: bool,
}

/// The relative RMSE at `cpu_seconds` on the curve `points` (any order): interpolated on
/// log–log axes between the points around it, extrapolated at `t^(−1/2)` outside it
/// (module docs); `None` without a curve. What an adaptive render is compared with at
/// equal CPU.
#[must_use]
pub fn error_at(points: &[CurvePoint], cpu_seconds: f64) -> Option<ErrorAt> {
    let p = measured(points);
    let mc = |q: &CurvePoint| q.rel_rmse * (q.cpu_seconds / cpu_seconds).sqrt();
    let (first, last) = (p.first()?, p.last()?);
    if cpu_seconds < first.cpu_seconds {
        return Some(ErrorAt { rel_rmse: mc(first), extrapolated: true });
    }
    for w in p.windows(2) {
        let (a, b) = (w[0], w[1]);
        if cpu_seconds <= b.cpu_seconds {
            let f = (cpu_seconds / a.cpu_seconds).ln() / (b.cpu_seconds / a.cpu_seconds).ln();
            let e = (a.rel_rmse.ln() + f * (b.rel_rmse / a.rel_rmse).ln()).exp();
            return Some(ErrorAt { rel_rmse: e, extrapolated: false });
        }
    }
    Some(ErrorAt { rel_rmse: mc(last), extrapolated: cpu_seconds > last.cpu_seconds })
}

/// The CPU time to `target` on the ascending curve `p` (module docs).
fn time_to(p: &[CurvePoint], target: f64) -> TimeToError {
    let mc = |q: &CurvePoint| q.cpu_seconds * (q.rel_rmse / target).powi(2);
    let (Some(first), Some(last)) = (p.first(), p.last()) else {
        return TimeToError { target, cpu_seconds: None, extrapolated: false };
    };
    if first.rel_rmse <= target {
        return TimeToError { target, cpu_seconds: Some(mc(first)), extrapolated: true };
    }
    for w in p.windows(2) {
        let (a, b) = (w[0], w[1]);
        if a.rel_rmse > target && b.rel_rmse <= target {
            // Log–log interpolation between a and b
            let f = (a.rel_rmse / target).ln() / (a.rel_rmse / b.rel_rmse).ln();
            let t = (a.cpu_seconds.ln() + f * (b.cpu_seconds / a.cpu_seconds).ln()).exp();
            return TimeToError { target, cpu_seconds: Some(t), extrapolated: false };
        }
    }
    TimeToError { target, cpu_seconds: Some(mc(last)), extrapolated: true }
}

/// How an adaptive series runs: the CPU seconds that end it, the spp cap of every
/// render, and the reference and relMSE `epsilon` it is measured with.
#[derive(Clone, Copy, Debug)]
pub struct SeriesPlan<'a> {
    /// A render spending this many CPU seconds or more is the last.
    pub budget: f64,
    /// Samples per pixel at most.
    pub cap: u32,
    /// The reference, row-major RGBA.
    pub reference: &'a [[f32; 4]],
    /// ε of relMSE.
    pub epsilon: f64,
}

/// The adaptive series of one method (module docs): renders at halving thresholds.
#[must_use]
pub fn adaptive_series<F: Field>(
    scene: &Scene<F>,
    integrator: &Integrator,
    run: &super::progressive::RunPlan,
    plan: &SeriesPlan<'_>,
) -> Vec<AdaptivePoint> {
    let SeriesPlan { budget, cap, reference, epsilon } = *plan;
    let floor = epsilon.sqrt();
    let mut out = Vec::new();
    let mut threshold = FIRST_THRESHOLD;
    while out.len() < MAX_THRESHOLDS {
        let settings = RenderSettings {
            budget: SampleBudget::Spp(cap),
            seed: run.seed,
            sampler: run.sampler,
            threads: run.threads,
            first_sample: 0,
            adaptive: Some(Adaptive { threshold, min_spp: 16, floor }),
            integrator: *integrator,
        };
        let c0 = cpu_seconds();
        let r = render_with(scene, &settings, RenderControl::default(), &|_, _| {});
        let cpu = cpu_seconds() - c0;
        let image = r.film.average();
        let errors = Errors::of(&image, reference, epsilon);
        let moments = r.film.moments();
        let noise =
            plume_engine::noise::FrameNoise::of(&r.film.sums(), &moments, r.film.crop, floor);
        out.push(AdaptivePoint {
            threshold,
            point: CurvePoint { cpu_seconds: cpu, rel_rmse: errors.relmse.sqrt() },
            estimated_rel_rmse: estimated_rel_rmse(&image, &noise.errors, epsilon),
            mean_spp: moments.iter().map(|m| m.count as f64).sum::<f64>()
                / moments.len().max(1) as f64,
            pixels_at_cap: moments.iter().filter(|m| m.count >= u64::from(cap)).count() as u64,
        });
        if cpu >= budget {
            break;
        }
        threshold /= 2.0;
    }
    out
}

/// `sqrt(mean e²)` over every pixel of `image`, `e² = (1/3) Σ_c σ̄_c² / (x_c² + ε)` with
/// the pooled standard errors `errors` (the measurement's pixels and `ε`); `None` where a
/// pixel has no estimate.
fn estimated_rel_rmse(image: &[[f32; 4]], errors: &[[f64; 3]], epsilon: f64) -> Option<f64> {
    let mut total = 0.0;
    for (x, e) in image.iter().zip(errors) {
        total += (0..3)
            .map(|c| e[c] * e[c] / (f64::from(x[c]) * f64::from(x[c]) + epsilon))
            .sum::<f64>()
            / 3.0;
    }
    let mean = total / image.len().max(1) as f64;
    mean.is_finite().then(|| mean.sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pt(t: f64, e: f64) -> CurvePoint {
        CurvePoint { cpu_seconds: t, rel_rmse: e }
    }

    /// On a curve at the Monte Carlo rate the interpolation and the extrapolation agree
    /// with it exactly.
    #[test]
    fn targets_on_a_monte_carlo_curve() {
        // e = 0.1 · t^(−1/2): e = 0.05 at t = 4, 0.02 at 25, 0.01 at 100
        let curve: Vec<CurvePoint> =
            [1.0, 2.0, 8.0, 16.0].iter().map(|&t| pt(t, 0.1 / f64::sqrt(t))).collect();
        let got = time_to_targets(&curve);
        assert!((got[0].cpu_seconds.unwrap() - 4.0).abs() < 1e-9 && !got[0].extrapolated);
        assert!((got[1].cpu_seconds.unwrap() - 25.0).abs() < 1e-9 && got[1].extrapolated);
        assert!((got[2].cpu_seconds.unwrap() - 100.0).abs() < 1e-9 && got[2].extrapolated);
        // Before the first point: backwards at the same rate
        let early = time_to_targets(&[pt(10.0, 0.01)]);
        assert!((early[0].cpu_seconds.unwrap() - 0.4).abs() < 1e-12 && early[0].extrapolated);
        assert_eq!(time_to_targets(&[])[0].cpu_seconds, None);
    }

    /// The error at a time: exact at the points, on the Monte Carlo line between and
    /// beyond them, marked where extrapolated.
    #[test]
    fn error_at_a_time_on_a_monte_carlo_curve() {
        let curve: Vec<CurvePoint> =
            [16.0, 1.0, 4.0].iter().map(|&t| pt(t, 0.1 / f64::sqrt(t))).collect();
        for (t, extrapolated) in
            [(1.0, false), (2.0, false), (16.0, false), (0.25, true), (64.0, true)]
        {
            let e = error_at(&curve, t).unwrap();
            assert!((e.rel_rmse - 0.1 / f64::sqrt(t)).abs() < 1e-12, "{t}: {e:?}");
            assert_eq!(e.extrapolated, extrapolated, "{t}");
        }
        assert_eq!(error_at(&[], 1.0), None);
    }
}
