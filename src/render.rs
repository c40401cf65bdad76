//! The render loop: passes of samples over tiles on a rayon pool.
//!
//! Pixel sample `s` of pixel `(x, y)` uses `Sampler::new(seed, y·width + x, s)`, so every
//! sample is a pure function of its key. Tiles are rendered in parallel, but each tile's
//! pixels accumulate their samples in order, and counters are merged in tile order:
//! the same seed gives the same bytes for any thread count.

use std::time::{Duration, Instant};

use rayon::prelude::*;

use crate::film::{Film, Tile};
use crate::integrator::{Counters, Integrator, NoTrace, Scene};
use crate::sampling::Sampler;
use crate::volume::field::Field;

/// How many samples to take.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SampleBudget {
    /// Exactly this many samples per pixel.
    Spp(u32),
    /// Whole 1-spp passes until this many seconds are spent (at least one pass).
    Time(f64),
    /// Whole 1-spp passes until the process has used this many CPU seconds more (at least
    /// one pass): equal-CPU-time comparisons on a shared machine.
    CpuTime(f64),
}

/// Settings of one render, validated once.
#[derive(Clone, Copy, Debug)]
pub struct RenderSettings {
    /// Sample budget.
    pub budget: SampleBudget,
    /// Seed of every sample stream.
    pub seed: u64,
    /// Worker threads (0 = all cores).
    pub threads: usize,
    /// First sample index (sample ranges; 0 normally).
    pub first_sample: u64,
    /// The integrator.
    pub integrator: Integrator,
}

/// What a render produced.
#[derive(Debug)]
pub struct RenderResult {
    /// Sums per pixel.
    pub film: Film,
    /// Samples per pixel taken.
    pub spp: u64,
    /// Counters over all tiles.
    pub counters: Counters,
    /// Wall time spent rendering, seconds.
    pub render_seconds: f64,
}

/// The camera ray and sampler state of one pixel sample, as the render loop makes them
/// (used by `--debug-pixel` to replay a sample exactly).
pub fn pixel_sample<F: Field>(scene: &Scene<F>, seed: u64, x: u32, y: u32, s: u64) -> (crate::volume::field::Ray, Sampler) {
    let pixel = u64::from(y) * u64::from(scene.camera.width) + u64::from(x);
    let mut sampler = Sampler::new(seed, pixel, s);
    let (jx, jy) = (sampler.next_f64(), sampler.next_f64());
    (scene.camera.ray(f64::from(x) + jx, f64::from(y) + jy), sampler)
}

fn render_tile<F: Field>(scene: &Scene<F>, integ: &Integrator, seed: u64, samples: std::ops::Range<u64>, tile: &mut Tile) -> Counters {
    let mut counters = Counters::default();
    for ty in 0..tile.height {
        for tx in 0..tile.width {
            let (x, y) = (tile.x0 + tx, tile.y0 + ty);
            let sum = &mut tile.sums[(ty * tile.width + tx) as usize];
            for s in samples.clone() {
                let (ray, mut sampler) = pixel_sample(scene, seed, x, y, s);
                let l = integ.li(scene, &ray, &mut sampler, &mut counters, &mut NoTrace);
                counters.samples += 1;
                if l.iter().all(|v| v.is_finite()) {
                    for (a, v) in sum.iter_mut().zip(l) {
                        *a += v;
                    }
                } else {
                    // Drop and count non-finite samples; report the first for replay
                    counters.nonfinite_samples += 1;
                    counters.first_nonfinite.get_or_insert((x, y, s));
                }
            }
        }
    }
    counters
}

/// Render `scene`. `on_pass(done_spp, total_spp_or_0)` is called after every pass.
///
/// # Panics
/// If the rayon pool cannot be built (out of threads).
pub fn render<F: Field>(scene: &Scene<F>, settings: &RenderSettings, on_pass: &(dyn Fn(u64, u64) + Sync)) -> RenderResult {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(settings.threads)
        .build()
        .expect("invariant: a rayon pool can be built");
    let mut film = Film::new(scene.camera.width, scene.camera.height);
    let mut counters = Counters::default();
    let start = Instant::now();
    let mut done: u64 = 0;
    let total = match settings.budget {
        SampleBudget::Spp(n) => u64::from(n),
        SampleBudget::Time(_) | SampleBudget::CpuTime(_) => 0,
    };
    let cpu_start = crate::stats::cpu_seconds();
    let mut last_pass_cpu = 0.0;
    let mut last_pass = Duration::ZERO;
    loop {
        let pass = match settings.budget {
            SampleBudget::Spp(_) => {
                if done >= total {
                    break;
                }
                // About 32 passes for progress reporting; sums do not depend on it.
                (total / 32).clamp(1, total - done)
            }
            SampleBudget::Time(limit) => {
                let elapsed = start.elapsed();
                if done > 0 && (elapsed + last_pass).as_secs_f64() > limit {
                    break;
                }
                1
            }
            SampleBudget::CpuTime(limit) => {
                if done > 0 && crate::stats::cpu_seconds() - cpu_start + last_pass_cpu > limit {
                    break;
                }
                1
            }
        };
        let pass_cpu_start = crate::stats::cpu_seconds();
        let first = settings.first_sample + done;
        let range = first..first + pass;
        let pass_start = Instant::now();
        let tile_counters: Vec<Counters> = pool.install(|| {
            film.tiles
                .par_iter_mut()
                .map(|tile| render_tile(scene, &settings.integrator, settings.seed, range.clone(), tile))
                .collect()
        });
        for c in &tile_counters {
            counters.merge(c);
        }
        last_pass = pass_start.elapsed();
        last_pass_cpu = crate::stats::cpu_seconds() - pass_cpu_start;
        done += pass;
        on_pass(done, total);
    }
    RenderResult { film, spp: done, counters, render_seconds: start.elapsed().as_secs_f64() }
}
