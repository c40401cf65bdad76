//! The render loop: passes of samples over tiles on a rayon pool.
//!
//! Pixel sample `s` of pixel `(x, y)` uses `Sampler::with_kind(kind, seed, y·width + x, s)`,
//! so every sample is a pure function of its key, whatever crop or sample range is rendered.
//! Tiles are rendered in parallel; each pixel's samples are added as exact fixed-point
//! integers (`film.rs`), and counters are integers merged in tile order: the same seed
//! gives the same bytes for any thread count, any pass size, any split into crops and
//! sample ranges, and across an interruption and resume.
//!
//! Passes are sized from measured time (about [`PASS_SECONDS`] each) so that a stop
//! request (`SIGTERM`), a `--time-limit` or a `--time` budget is honoured between passes
//! without overshooting by much; since sums are exact, pass sizes never change the image.
//!
//! A volume larger than memory changes the trade ([`SampleOrder`]): every progressive
//! pass sends rays through all of it, so the page cache cycles and each pass rereads
//! the file. [`SampleOrder::TileMajor`] renders each tile's samples together, tiles in
//! raster order, and prefetches the camera rays' bricks of the tiles just ahead
//! (`Field::prefetch`), so each brick is read from disk about once. Same bytes either way.

pub use plume_scene::SampleId;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use crate::film::{Crop, Film, HalfSums, Tile};
use crate::integrator::deferred::PendingSample;
use crate::integrator::split_map::pixel_integrator;
use crate::integrator::{AovLayout, AovSample, Aovs, Counters, Integrator, NoAovs, NoTrace, Scene, SplitMap};
use plume_core::sampling::{Dim, Sampler, SamplerKind};
use plume_scene::DeferPaths;
use plume_volume::field::Field;

/// How many samples to take.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SampleBudget {
    /// Exactly this many samples per pixel.
    Spp(u32),
    /// Whole 1-spp passes until this many seconds are spent (at least one pass).
    Time(f64),
    /// Passes until the process has used this many CPU seconds more (at least one pass):
    /// equal-CPU-time comparisons on a shared machine.
    CpuTime(f64),
}

/// Settings of one render, validated once.
#[derive(Clone, Copy, Debug)]
pub struct RenderSettings {
    /// Sample budget.
    pub budget: SampleBudget,
    /// Seed of every sample stream.
    pub seed: u64,
    /// Which numbers the samplers give (`--sampler`).
    pub sampler: SamplerKind,
    /// Worker threads (0 = all cores; in tile-major order from a mapped volume, where
    /// workers wait on page faults, one more, or three per core when paths scatter).
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
    /// Wall seconds the workers spent rendering tiles, summed over workers: divided by
    /// `render_seconds`, how many workers had work on average (what pass ends and set-up
    /// between passes cost; wall time, so other load on the machine does not hide it).
    pub busy_seconds: f64,
    /// Why the loop ended.
    pub stopped: StopReason,
}

/// Why a render loop ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StopReason {
    /// The sample budget was spent.
    Finished,
    /// A stop was requested (a signal); the last pass was completed.
    Interrupted,
    /// The deadline came before the budget was spent.
    TimeLimit,
}

/// The order in which a render visits its samples. The image is the same either way.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SampleOrder {
    /// Passes over the whole image of a few samples per pixel each (about
    /// [`PASS_SECONDS`]): progress, stop requests and time budgets act between passes.
    #[default]
    Progressive,
    /// For a fixed sample count (with a time budget the render stays progressive): one
    /// pass taking every sample of a tile before the next, tiles in raster order, the
    /// tiles just ahead of the workers prefetched. For volumes larger than memory. A stop
    /// request or the deadline abandons the pass between tiles and keeps nothing of it.
    ///
    /// **Read-ahead window.** A tile's camera rays can cross hundreds of MB of bricks
    /// (up to 340 MB for one 16×16 tile of the 2048³ flare), so a fixed number of tiles
    /// ahead can ask for more than the memory holds: pages read ahead then push out the
    /// pages of the tiles being rendered, and both are read again. The prefetch thread
    /// therefore also waits while the bytes it asked for, for tiles not yet finished
    /// (being rendered or waiting), exceed [`RenderControl::read_ahead_window`]; a tile
    /// already taken by a worker is always asked for. In a 1.5 GiB cgroup with the flare
    /// this took an emission–absorption render from 40–180 k page faults to 16–17 k, and
    /// one with scattering from 0.71 M to 0.44 M (docs/BENCHMARKS.md, issue #17).
    TileMajor,
}

/// The [`RenderControl::read_ahead_window`] for a memory budget: half of it, i.e. a
/// quarter of the memory limit when the budget is the default, leaving the rest to the
/// tiles' scattered rays and to the volume's index.
#[must_use]
pub fn read_ahead_window(memory_budget: u64) -> Option<u64> {
    Some(memory_budget / 2)
}

/// Wall seconds a pass aims at: the longest wait between a stop request and the image.
pub const PASS_SECONDS: f64 = 1.0;

/// What `render_with` renders besides the settings: which pixels, from which sums, and
/// when to stop early.
#[derive(Default)]
pub struct RenderControl<'a> {
    /// Pixels to render (default: the whole image).
    pub crop: Option<Crop>,
    /// Sums to continue from (a resumed render), with the same crop; samples are added
    /// from `settings.first_sample` on.
    pub film: Option<Film>,
    /// Checked between passes; `true` ends the render after the current pass.
    pub stop: Option<&'a (dyn Fn() -> bool + Sync)>,
    /// No pass is started that is predicted to end after this instant (at least one pass
    /// is always rendered, except in tile-major order, which abandons it at the deadline).
    pub deadline: Option<Instant>,
    /// Sample order.
    pub order: SampleOrder,
    /// Record AOV layers with this layout (`integrator::aov`); `None`: the beauty only.
    pub aovs: Option<AovLayout>,
    /// In tile-major order, the most bytes asked to be read ahead for tiles that are not
    /// finished yet (see [`SampleOrder::TileMajor`]); `None`: no bound but the number of
    /// tiles ahead. Never changes a result.
    pub read_ahead_window: Option<u64>,
    /// Whether scattered paths are traced in rounds (`integrator::deferred`). Never
    /// changes a result.
    pub defer_paths: DeferPaths,
    /// With half sums in `aovs` (`--denoise`): the half block ([`crate::denoise::half_of`];
    /// `None`: [`crate::denoise::half_block`]`(None)`).
    pub half_block: Option<u64>,
}

/// One pixel sample as the render loop starts it: what [`pixel_sample`] returns.
#[derive(Clone, Debug)]
#[must_use]
pub struct PixelSample {
    /// The camera ray through the jittered point of the pixel (world space).
    pub ray: plume_volume::field::Ray,
    /// The sample's sampler, at the camera segment after the pixel jitter was drawn.
    pub sampler: Sampler,
    /// The sample's shutter time (seconds), when the scene moves.
    pub time: Option<f64>,
}

/// The camera ray and sampler state of one pixel sample, as the render loop makes them
/// (used by `--debug-pixel` to replay a sample exactly).
pub fn pixel_sample<F: Field>(scene: &Scene<F>, kind: SamplerKind, seed: u64, x: u32, y: u32, s: u64) -> PixelSample {
    let pixel = u64::from(y) * u64::from(scene.camera.width) + u64::from(x);
    let mut sampler = Sampler::with_kind(kind, seed, pixel, s);
    sampler.start_vertex(0);
    let [jx, jy] = sampler.get_2d(Dim::Direction);
    // With motion, the sample's shutter time places the camera (and the volume, in `li`)
    let shutter = scene.motion.as_ref().map(|m| m.shutter).or(scene.camera.motion.map(|m| m.shutter()));
    let time = shutter.map(|[open, close]| open + sampler.get_1d(Dim::Time) * (close - open));
    let camera = time.map_or(scene.camera, |t| scene.camera.at_time(t));
    PixelSample { ray: camera.ray(f64::from(x) + jx, f64::from(y) + jy), sampler, time }
}

/// Where a tile's samples whose scattered paths are deferred go (`integrator::deferred`):
/// the tile's number in the film, and the list.
type Deferring<'p> = Option<(usize, &'p mut Vec<PendingSample>)>;

fn render_tile<F: Field>(
    scene: &Scene<F>,
    (settings, split_map): (&RenderSettings, Option<&SplitMap>),
    samples: std::ops::Range<u64>,
    tile: &mut Tile,
    defer: Deferring<'_>,
) -> Counters {
    if tile.aov_channels == 0 {
        render_tile_with(scene, (settings, split_map), samples, tile, &mut NoAovs, defer)
    } else {
        let mut aovs = AovSample::new(tile.aov_channels, tile.half.map(|h| (h.at, h.filtered)));
        render_tile_with(scene, (settings, split_map), samples, tile, &mut aovs, None)
    }
}

fn render_tile_with<F: Field, A: Aovs>(
    scene: &Scene<F>,
    (settings, split_map): (&RenderSettings, Option<&SplitMap>),
    samples: std::ops::Range<u64>,
    tile: &mut Tile,
    aovs: &mut A,
    mut defer: Deferring<'_>,
) -> Counters {
    let mut counters = Counters::default();
    for ty in 0..tile.height {
        for tx in 0..tile.width {
            let (x, y) = (tile.x0 + tx, tile.y0 + ty);
            let index = (ty * tile.width + tx) as usize;
            let integrator = pixel_integrator(&settings.integrator, split_map, x, y);
            for s in samples.clone() {
                let PixelSample { ray, mut sampler, time } = pixel_sample(scene, settings.sampler, settings.seed, x, y, s);
                aovs.begin();
                let l = if let Some((tile_index, pending)) = defer.as_mut() {
                    let mut paths = Vec::new();
                    let l = integrator.li_deferring(scene, &ray, &mut sampler, (time, &mut counters), &mut paths);
                    if !paths.is_empty() {
                        // Added to the film when its paths are done
                        counters.samples += 1;
                        pending.push(PendingSample::new(*tile_index, index, SampleId { x, y, sample: s }, integrator, l, paths));
                        continue;
                    }
                    l
                } else {
                    integrator.li_aovs(scene, &ray, &mut sampler, (time, &mut counters), &mut NoTrace, aovs)
                };
                if tile.half.is_some_and(|h| A::ON && crate::denoise::half_of(s, h.block)) {
                    aovs.half(l);
                }
                counters.samples += 1;
                if l.iter().all(|v| v.is_finite()) && (!A::ON || aovs.values().iter().all(|v| v.is_finite())) {
                    tile.add_sample(index, l);
                    if A::ON {
                        tile.add_aov(index, aovs.values());
                    }
                } else {
                    // Drop and count non-finite samples; report the first for replay
                    counters.nonfinite_samples += 1;
                    counters.first_nonfinite.get_or_insert(SampleId { x, y, sample: s });
                }
            }
        }
    }
    counters
}

/// Render the whole image of `scene`. `on_pass(done_spp, total_spp_or_0)` is called after
/// every pass.
///
/// # Panics
/// If the rayon pool cannot be built (out of threads).
pub fn render<F: Field>(scene: &Scene<F>, settings: &RenderSettings, on_pass: &(dyn Fn(u64, u64) + Sync)) -> RenderResult {
    render_with(scene, settings, RenderControl::default(), on_pass)
}

/// Render the pixels and samples described by `settings` and `control`: samples
/// `first_sample..` of the pixels of `control.crop`, added to `control.film` if given.
/// `RenderResult::spp` counts the samples added by this call.
///
/// # Panics
/// If the rayon pool cannot be built, or `control.film` does not match the crop.
pub fn render_with<F: Field>(scene: &Scene<F>, settings: &RenderSettings, control: RenderControl<'_>, on_pass: &(dyn Fn(u64, u64) + Sync)) -> RenderResult {
    // Out of core, a worker waiting on a page fault leaves its core idle: by default one
    // worker more than cores keeps them busy (measured: +8 % on the 33 GB flare, 2 cores).
    // Scattered segments read ahead of themselves (`integrator::tracker`) but still wait
    // for their first pages: three workers per core (2048³ flare in a 1.5 GiB cgroup,
    // albedo 0.5: 61.2 s with 3 workers, 50.9 s with 6, 48.6 s with 12; without
    // scattering more workers widen the working set: 18.0 s with 3, 20.3 s with 8)
    let out_of_core = control.order == SampleOrder::TileMajor && scene.field.is_mapped();
    let cores = std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get);
    let scatters = settings.integrator.max_depth > 0 && scene.medium.albedo > 0.0;
    let threads = match settings.threads {
        0 if out_of_core && scatters => 3 * cores,
        0 if out_of_core => cores + 1,
        n => n,
    };
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("invariant: a rayon pool can be built");
    let (width, height) = (scene.camera.width, scene.camera.height);
    let crop = control.crop.unwrap_or(Crop::full(width, height));
    let aov_channels = control.aovs.as_ref().map_or(0, AovLayout::channels);
    let mut film = control.film.unwrap_or_else(|| Film::with_aovs(width, height, crop, aov_channels));
    assert_eq!(film.aov_channels(), aov_channels, "invariant: resumed film has the AOV channels asked for");
    let block = control.half_block.unwrap_or_else(|| crate::denoise::half_block(None));
    film.set_half(control.aovs.as_ref().and_then(|l| Some(HalfSums { at: l.half_at()?, block, filtered: l.halves? })));
    assert!(film.crop == crop && film.width == width && film.height == height, "invariant: resumed film matches the crop");
    let mut counters = Counters::default();
    // The first non-finite sample in (row, column, sample) order: each tile reports its
    // first in that order, so the minimum over tiles and passes does not depend on them
    let mut first_nonfinite: Option<SampleId> = None;
    let start = Instant::now();
    let mut done: u64 = 0;
    let total = match settings.budget {
        SampleBudget::Spp(n) => u64::from(n),
        SampleBudget::Time(_) | SampleBudget::CpuTime(_) => 0,
    };
    let cpu_start = crate::stats::cpu_seconds();
    let mut cpu_per_spp: Option<f64> = None;
    let mut seconds_per_spp: Option<f64> = None;
    let mut last_pass: u64 = 0;
    // Each tile's wall seconds in the last pass: the next pass takes the costliest first
    let mut tile_seconds = vec![0.0f64; film.tiles.len()];
    let mut busy_seconds = 0.0;
    // Splitting by brightness: the pilot renders the whole frame, whatever this call renders
    let split_map = pool.install(|| crate::pilot::split_map(scene, settings));
    let split_map = split_map.as_ref();
    // Scattered paths in rounds, reading the file in order (`integrator::deferred`)
    let defer = control.order == SampleOrder::TileMajor
        && control.aovs.is_none()
        && settings.integrator.defers(scene)
        && match control.defer_paths {
            // One path per camera collision: with more, the paths' lookups outgrow what a
            // few fills serve (the 2048³ flare in a 1.5 GiB cgroup, 16 spp: `--split 1`
            // 67–85 s deferred against 126–131 s direct; `--split 8` about 35 fills of 4 M
            // lookups, slower than its 195–217 s direct; docs/BENCHMARKS.md)
            DeferPaths::Auto => out_of_core && settings.integrator.split == 1 && split_map.is_none(),
            DeferPaths::Always => true,
            DeferPaths::Never => false,
        };
    let stopped = loop {
        let remaining = match settings.budget {
            SampleBudget::Spp(_) => total - done,
            SampleBudget::Time(_) | SampleBudget::CpuTime(_) => u64::MAX,
        };
        if remaining == 0 {
            break StopReason::Finished;
        }
        if control.stop.is_some_and(|stop| stop()) {
            break StopReason::Interrupted;
        }
        // Size the pass from the measured time per spp: ≈ PASS_SECONDS, growing at most 4×
        let mut pass = match seconds_per_spp {
            None => 1,
            Some(t) => ((PASS_SECONDS / t.max(1e-9)) as u64).clamp(1, last_pass.saturating_mul(4).max(1)),
        };
        let tile_major = control.order == SampleOrder::TileMajor && matches!(settings.budget, SampleBudget::Spp(_));
        if tile_major {
            pass = remaining;
        }
        pass = pass.min(remaining);
        if let (Some(t), true) = (seconds_per_spp, done > 0) {
            // Budget and deadline: only passes predicted to end in time
            if let SampleBudget::Time(limit) = settings.budget {
                let left = limit - start.elapsed().as_secs_f64();
                if left < t {
                    break StopReason::Finished;
                }
                pass = pass.min((left / t) as u64).max(1);
            }
            if let (SampleBudget::CpuTime(limit), Some(c)) = (settings.budget, cpu_per_spp) {
                let left = limit - (crate::stats::cpu_seconds() - cpu_start);
                if left < c {
                    break StopReason::Finished;
                }
                pass = pass.min((left / c) as u64).max(1);
            }
            if let Some(deadline) = control.deadline {
                let left = deadline.saturating_duration_since(Instant::now()).as_secs_f64();
                if left < t {
                    break StopReason::TimeLimit;
                }
                pass = pass.min((left / t) as u64).max(1);
            }
        }
        let first = settings.first_sample + done;
        let range = first..first + pass;
        let pass_start = Instant::now();
        let pass_cpu_start = crate::stats::cpu_seconds();
        let tile_counters: Vec<Counters> = if tile_major {
            let abandon = || control.stop.is_some_and(|stop| stop()) || control.deadline.is_some_and(|d| Instant::now() >= d);
            match tile_major::tile_major_pass(
                scene,
                (settings, split_map),
                &pool,
                &mut film,
                (&range, control.read_ahead_window),
                &abandon,
                &mut tile_seconds,
                defer,
            ) {
                Some(c) => c,
                None if control.deadline.is_some_and(|d| Instant::now() >= d) => break StopReason::TimeLimit,
                None => break StopReason::Interrupted,
            }
        } else {
            progressive_pass(scene, (settings, split_map), &pool, &mut film, &range, &mut tile_seconds)
        };
        busy_seconds += tile_seconds.iter().sum::<f64>();
        for c in &tile_counters {
            counters.merge(c);
            if let Some(id) = c.first_nonfinite {
                id.keep_earliest(&mut first_nonfinite);
            }
        }
        let elapsed = pass_start.elapsed().as_secs_f64();
        seconds_per_spp = Some(elapsed / pass as f64);
        cpu_per_spp = Some((crate::stats::cpu_seconds() - pass_cpu_start) / pass as f64);
        last_pass = pass;
        done += pass;
        on_pass(done, total);
    };
    counters.first_nonfinite = first_nonfinite;
    RenderResult { film, spp: done, counters, render_seconds: start.elapsed().as_secs_f64(), busy_seconds, stopped }
}

/// One progressive pass of `samples` over every tile of `film`; the tiles' counters in
/// tile order.
///
/// Workers take tiles one at a time from a shared list, the costliest of the last pass
/// first (`tile_seconds`, updated here): the longest-processing-time-first rule, so the
/// pass ends on cheap tiles and no worker waits long for the last one. Before, rayon's
/// `par_iter_mut` split the tiles into runs (with 2 workers, about 4 runs of 16 of a
/// 128² image's 64 tiles) that cannot be split once started, so a run holding the
/// fireball kept the other worker idle: 1.66 of 2 cores busy (issue #16). The order
/// changes no pixel: each tile's sums are its own exact integers.
fn progressive_pass<F: Field>(
    scene: &Scene<F>,
    settings: (&RenderSettings, Option<&SplitMap>),
    pool: &rayon::ThreadPool,
    film: &mut Film,
    samples: &std::ops::Range<u64>,
    tile_seconds: &mut [f64],
) -> Vec<Counters> {
    let mut order: Vec<usize> = (0..film.tiles.len()).collect();
    order.sort_by(|&a, &b| tile_seconds[b].total_cmp(&tile_seconds[a]));
    let tiles: Vec<Mutex<&mut Tile>> = film.tiles.iter_mut().map(Mutex::new).collect();
    let results: Vec<Mutex<(Counters, f64)>> = tiles.iter().map(|_| Mutex::new((Counters::default(), 0.0))).collect();
    let next = AtomicUsize::new(0);
    pool.broadcast(|_| loop {
        let Some(&i) = order.get(next.fetch_add(1, Ordering::Relaxed)) else { return };
        let start = Instant::now();
        let mut tile = tiles[i].lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        let c = render_tile(scene, settings, samples.clone(), &mut tile, None);
        *results[i].lock().unwrap_or_else(std::sync::PoisonError::into_inner) = (c, start.elapsed().as_secs_f64());
    });
    results
        .into_iter()
        .zip(tile_seconds.iter_mut())
        .map(|(r, t)| {
            let (c, seconds) = r.into_inner().unwrap_or_else(std::sync::PoisonError::into_inner);
            *t = seconds;
            c
        })
        .collect()
}

mod tile_major;

#[cfg(test)]
mod tests {
    use super::SampleId;

    /// `--debug-pixel` takes what warnings print; the stats JSON names the fields.
    #[test]
    fn sample_id_displays_as_debug_pixel_and_serializes_by_name() {
        let id = SampleId { x: 10, y: 7, sample: 3 };
        assert_eq!(id.to_string(), "10,7,3");
        assert_eq!(serde_json::to_string(&id).unwrap(), r#"{"x":10,"y":7,"sample":3}"#);
    }
}
