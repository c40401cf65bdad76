//! Progressive rendering with checkpoints, the measuring loop of `plume bench compare`.
//!
//! A run renders sample ranges `[k, k + n)` with [`render_with`] (each a pure function of
//! the seed, so the image is the same as one long render up to summation order; tile by
//! tile for a brick cache larger than the memory available) and adds the films. Between
//! ranges it records [`Snapshot`]s: when the process CPU time spent by the run crosses
//! each CPU-time checkpoint (the error-vs-time curve and the equal-time point), and at
//! every power-of-two spp (the equal-spp point).
//!
//! Budgets are **CPU seconds** (user + system, `getrusage`), not wall seconds: on a
//! machine shared with other work, CPU time is what a method cost. Range sizes are chosen
//! from the measured cost per spp so that a checkpoint is overshot by at most about one
//! 1-spp pass; the snapshot records the CPU time actually spent.

use std::time::Instant;

use serde::Serialize;

use super::metrics::Errors;
use plume_engine::film::Film;
use plume_engine::integrator::{Counters, Integrator, Scene};
use plume_engine::render::{
    read_ahead_window, render_with, RenderControl, RenderSettings, SampleBudget, SampleOrder,
};
use plume_engine::stats::cpu_seconds;
use plume_volume::Field;

/// The state of a run at one checkpoint.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Snapshot {
    /// CPU seconds spent by the run so far.
    pub cpu_seconds: f64,
    /// Wall seconds spent by the run so far.
    pub wall_seconds: f64,
    /// Samples per pixel so far.
    pub spp: u64,
    /// Errors against the reference (all 0 when there is none).
    pub errors: Errors,
}

/// What a progressive run produced.
#[derive(Clone, Debug)]
pub struct RunResult {
    /// One snapshot per CPU-time checkpoint, in order.
    pub time_points: Vec<Snapshot>,
    /// Snapshots at every power-of-two spp and at the minimum spp.
    pub spp_points: Vec<Snapshot>,
    /// Final per-pixel averages, row-major RGBA.
    pub image: Vec<[f32; 4]>,
    /// Final per-pixel sums, row-major RGBA.
    pub sums: Vec<[f64; 4]>,
    /// Samples per pixel at the end.
    pub spp: u64,
    /// CPU seconds at the end.
    pub cpu_seconds: f64,
    /// Counters over the whole run.
    pub counters: Counters,
}

/// How long a run goes.
#[derive(Clone, Debug)]
pub struct RunPlan {
    /// Ascending CPU-time checkpoints, seconds; the run lasts at least until the last.
    pub cpu_checkpoints: Vec<f64>,
    /// The run lasts at least until this many spp.
    pub min_spp: u64,
    /// Seed of the sample streams.
    pub seed: u64,
    /// Which numbers drive the samples.
    pub sampler: plume_core::sampling::SamplerKind,
    /// Worker threads (0 = all cores).
    pub threads: usize,
}

/// Value of one unit of the film's fixed-point sums, `2^-F`.
const FIXED_POINT_UNIT: f64 = 1.0 / (1u128 << plume_engine::film::FIXED_POINT_BITS) as f64;

/// Add a film's sums into row-major sums.
pub fn accumulate(sums: &mut [[f64; 4]], film: &Film) {
    for t in &film.tiles {
        for ty in 0..t.height {
            for tx in 0..t.width {
                let d = &mut sums[((t.y0 + ty) * film.width + t.x0 + tx) as usize];
                // The film's exact fixed-point sums, in radiance units
                for (a, v) in d.iter_mut().zip(t.sums[(ty * t.width + tx) as usize]) {
                    *a += v as f64 * FIXED_POINT_UNIT;
                }
            }
        }
    }
}

/// Row-major sums divided by `spp`, as `f32`.
#[must_use]
pub fn average(sums: &[[f64; 4]], spp: u64) -> Vec<[f32; 4]> {
    let inv = if spp > 0 { 1.0 / spp as f64 } else { 0.0 };
    sums.iter().map(|s| s.map(|v| (v * inv) as f32)).collect()
}

/// Render `scene` progressively by `plan`, measuring errors against `reference` (if any)
/// with relMSE `epsilon`.
#[must_use]
pub fn run<F: Field>(
    scene: &Scene<F>,
    integrator: &Integrator,
    plan: &RunPlan,
    reference: Option<&[[f32; 4]]>,
    epsilon: f64,
) -> RunResult {
    let (w, h) = (scene.camera.width, scene.camera.height);
    let mut sums = vec![[0.0f64; 4]; (w * h) as usize];
    let mut counters = Counters::default();
    let mut spp = 0u64;
    let mut time_points = Vec::new();
    let mut spp_points: Vec<Snapshot> = Vec::new();
    let mut cpu_per_spp: Option<f64> = None;
    let cpu0 = cpu_seconds();
    let wall0 = Instant::now();
    let snapshot = |sums: &[[f64; 4]], spp: u64, cpu: f64, wall: f64| {
        let errors = match reference {
            Some(r) => Errors::of(&average(sums, spp), r, epsilon),
            None => Errors { rmse: 0.0, relmse: 0.0, bias: 0.0 },
        };
        Snapshot { cpu_seconds: cpu, wall_seconds: wall, spp, errors }
    };
    let mut cpu = 0.0;
    // A brick cache larger than the memory available is rendered tile by tile within each
    // pass, as `plume render --sample-order auto` does: camera rays and scattered segments
    // read ahead, within the same read-ahead window. The image is the same in either order.
    let memory = plume_volume::out_of_core::memory::MemoryLimits::read();
    let available = memory.available().map_or(u64::MAX, |a| a.bytes);
    let read_ahead_window = read_ahead_window(memory.default_budget());
    let order = if scene.field.is_mapped() && scene.field.data_bytes() as u64 > available {
        SampleOrder::TileMajor
    } else {
        SampleOrder::Progressive
    };
    loop {
        let next_time = plan.cpu_checkpoints.get(time_points.len()).copied();
        if next_time.is_none() && spp >= plan.min_spp {
            break;
        }
        // Next spp checkpoint: the next power of two, or the minimum spp if nearer
        let mut next_spp = (spp + 1).next_power_of_two();
        if spp < plan.min_spp {
            next_spp = next_spp.min(plan.min_spp);
        }
        let n_spp = next_spp - spp;
        let n_time = match (next_time, cpu_per_spp) {
            (Some(target), Some(rate)) if rate > 0.0 => {
                ((0.8 * (target - cpu) / rate).floor() as u64).max(1)
            }
            (Some(_), _) => 1,
            (None, _) => u64::MAX,
        };
        let n = n_spp.min(n_time);
        let settings = RenderSettings {
            budget: SampleBudget::Spp(u32::try_from(n).unwrap_or(u32::MAX)),
            seed: plan.seed,
            sampler: plan.sampler,
            threads: plan.threads,
            first_sample: spp,
            adaptive: None,
            integrator: *integrator,
        };
        let c0 = cpu_seconds();
        let r = render_with(
            scene,
            &settings,
            RenderControl { order, read_ahead_window, ..RenderControl::default() },
            &|_, _| {},
        );
        let pass_cpu = cpu_seconds() - c0;
        accumulate(&mut sums, &r.film);
        counters.merge(&r.counters);
        spp += r.spp;
        cpu_per_spp = Some(pass_cpu / r.spp.max(1) as f64);
        cpu = cpu_seconds() - cpu0;
        let wall = wall0.elapsed().as_secs_f64();
        if spp.is_power_of_two() || spp == plan.min_spp {
            spp_points.push(snapshot(&sums, spp, cpu, wall));
        }
        while plan.cpu_checkpoints.get(time_points.len()).is_some_and(|&t| cpu >= t) {
            let s = spp_points
                .last()
                .filter(|s| s.spp == spp)
                .copied()
                .unwrap_or_else(|| snapshot(&sums, spp, cpu, wall));
            time_points.push(s);
        }
    }
    RunResult {
        time_points,
        spp_points,
        image: average(&sums, spp),
        sums,
        spp,
        cpu_seconds: cpu,
        counters,
    }
}
