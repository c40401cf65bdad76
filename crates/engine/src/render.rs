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
use crate::integrator::{AovLayout, Counters, Scene};
use plume_scene::DeferPaths;
use plume_volume::field::Field;

/// What a render tells the application while it runs: the render loop never prints, so
/// a progress bar or a farm's progress lines are the application's, fed from here.
///
/// A closure `|done, total| …` is an observer (`&|_, _| {}` observes nothing).
pub trait RenderObserver: Sync {
    /// A pass ended: `done` samples per pixel rendered by this call so far, of `total`
    /// (0 for a time budget, whose total is not known). Called on the thread that called
    /// [`render_with`], between passes.
    fn pass_done(&self, done: u64, total: u64);
}

impl<T: Fn(u64, u64) + Sync> RenderObserver for T {
    fn pass_done(&self, done: u64, total: u64) {
        self(done, total);
    }
}

/// Render the whole image of `scene`, telling `observer` after every pass.
///
/// # Panics
/// If the rayon pool cannot be built (out of threads).
pub fn render<F: Field>(
    scene: &Scene<F>,
    settings: &RenderSettings,
    observer: &dyn RenderObserver,
) -> RenderResult {
    render_with(scene, settings, RenderControl::default(), observer)
}

/// Render the pixels and samples described by `settings` and `control`: samples
/// `first_sample..` of the pixels of `control.crop`, added to `control.film` if given.
/// `RenderResult::spp` counts the samples added by this call.
///
/// # Panics
/// If the rayon pool cannot be built, or `control.film` does not match the crop.
pub fn render_with<F: Field>(
    scene: &Scene<F>,
    settings: &RenderSettings,
    mut control: RenderControl<'_>,
    observer: &dyn RenderObserver,
) -> RenderResult {
    // Out of core, a worker waiting on a page fault leaves its core idle: by default one
    // worker more than cores keeps them busy. Scattered segments read ahead of themselves
    // (`integrator::tracker`) but still wait for their first pages: three workers per
    // core; without scattering more workers only widen the working set
    // (docs/BENCHMARKS.md, "Out of core with scattering: the solar flare")
    let out_of_core = control.order == SampleOrder::TileMajor && scene.field.is_mapped();
    let threads = worker_threads(scene, settings, out_of_core);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("invariant: a rayon pool can be built");
    let resumed = control.film.take();
    let mut film = start_film(scene, &control, resumed);
    let mut counters = Counters::default();
    // The first non-finite sample in (row, column, sample) order: each tile reports its
    // first in that order, so the minimum over tiles and passes does not depend on them
    let mut first_nonfinite: Option<SampleId> = None;
    let mut pacing = Pacing::start(settings.budget);
    // Each tile's wall seconds in the last pass: the next pass takes the costliest first
    let mut tile_seconds = vec![0.0f64; film.tiles.len()];
    let mut busy_seconds = 0.0;
    // Splitting by brightness: the pilot renders the whole frame, whatever this call renders
    let split_map = pool.install(|| crate::pilot::split_map(scene, settings));
    let split_map = split_map.as_ref();
    // Scattered paths in rounds, reading the file in order (`integrator::deferred`)
    // (not with adaptive sampling, whose checkpoints need each pixel's samples in its sums)
    let defer = control.order == SampleOrder::TileMajor
        && control.aovs.is_none()
        && settings.adaptive.is_none()
        && settings.integrator.defers(scene)
        && match control.defer_paths {
            // One path per camera collision: with more, the paths' lookups outgrow what a
            // few fills serve (docs/BENCHMARKS.md, "Out of core with scattering: the solar flare")
            DeferPaths::Auto => {
                out_of_core && settings.integrator.split == 1 && split_map.is_none()
            }
            DeferPaths::Always => true,
            DeferPaths::Never => false,
        };
    let tile_major =
        control.order == SampleOrder::TileMajor && matches!(settings.budget, SampleBudget::Spp(_));
    let stopped = loop {
        if control.stop.is_some_and(|stop| stop()) && pacing.remaining() != 0 {
            break StopReason::Interrupted;
        }
        let pass = match pacing.next_pass(tile_major, control.deadline) {
            Ok(pass) => pass,
            Err(reason) => break reason,
        };
        let first = settings.first_sample + pacing.done;
        let range = first..first + pass;
        let pass_start = Instant::now();
        let pass_cpu_start = crate::stats::cpu_seconds();
        let tile_counters: Vec<Counters> = if tile_major {
            let abandon = || {
                control.stop.is_some_and(|stop| stop())
                    || control.deadline.is_some_and(|d| Instant::now() >= d)
            };
            let pass = TileMajorPass {
                samples: &range,
                read_ahead_window: control.read_ahead_window,
                abandon: &abandon,
                defer,
            };
            match tile_major::tile_major_pass(
                scene,
                TileJob { settings, split_map },
                &pool,
                &mut film,
                &pass,
                &mut tile_seconds,
            ) {
                Some(c) => c,
                None if control.deadline.is_some_and(|d| Instant::now() >= d) => {
                    break StopReason::TimeLimit
                }
                None => break StopReason::Interrupted,
            }
        } else {
            progressive_pass(
                scene,
                TileJob { settings, split_map },
                &pool,
                &mut film,
                &range,
                &mut tile_seconds,
            )
        };
        busy_seconds += tile_seconds.iter().sum::<f64>();
        if settings.adaptive.is_some() && tile_counters.iter().all(|c| c.samples == 0) {
            // Every pixel has converged: no more samples would be taken up to the cap
            pacing.converged();
            break StopReason::Finished;
        }
        for c in &tile_counters {
            counters.merge(c);
            if let Some(id) = c.first_nonfinite {
                id.keep_earliest(&mut first_nonfinite);
            }
        }
        pacing.pass_done(pass, pass_start, pass_cpu_start);
        observer.pass_done(pacing.done, pacing.total);
    };
    counters.first_nonfinite = first_nonfinite;
    RenderResult {
        film,
        spp: pacing.done,
        counters,
        render_seconds: pacing.start.elapsed().as_secs_f64(),
        busy_seconds,
        stopped,
    }
}

/// Rayon workers: as asked, or by default one more than cores out of core, where a
/// worker waiting on a page fault leaves its core idle, and three per core when paths
/// scatter out of core, since scattered segments still wait for their first pages
/// (docs/BENCHMARKS.md, "Out of core with scattering: the solar flare"). Without scattering, more workers only widen the
/// working set.
fn worker_threads<F: Field>(
    scene: &Scene<F>,
    settings: &RenderSettings,
    out_of_core: bool,
) -> usize {
    let cores = std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get);
    let scatters = settings.integrator.max_depth > 0 && scene.medium.albedo.max_component() > 0.0;
    match settings.threads {
        0 if out_of_core && scatters => 3 * cores,
        0 if out_of_core => cores + 1,
        n => n,
    }
}

/// The film the render adds to: `resumed` (`control.film`, a resumed render) or a new one over the
/// crop, with the AOV channels and half sums asked for.
fn start_film<F: Field>(
    scene: &Scene<F>,
    control: &RenderControl<'_>,
    resumed: Option<Film>,
) -> Film {
    let (width, height) = (scene.camera.width, scene.camera.height);
    let crop = control.crop.unwrap_or(Crop::full(width, height));
    let aov_channels = control.aovs.as_ref().map_or(0, AovLayout::channels);
    let mut film = resumed.unwrap_or_else(|| Film::with_aovs(width, height, crop, aov_channels));
    assert_eq!(
        film.aov_channels(),
        aov_channels,
        "invariant: resumed film has the AOV channels asked for"
    );
    let block = control.half_block.unwrap_or_else(|| crate::denoise::half_block(None));
    film.set_half(
        control
            .aovs
            .as_ref()
            .and_then(|l| Some(HalfSums { at: l.half_at()?, block, filtered: l.halves? })),
    );
    assert!(
        film.crop == crop && film.width == width && film.height == height,
        "invariant: resumed film matches the crop"
    );
    film
}

/// How many samples the next pass takes: about [`PASS_SECONDS`] by the measured time
/// per spp, growing at most 4× a pass, and within the sample, time and CPU budgets and
/// the deadline.
struct Pacing {
    budget: SampleBudget,
    /// Samples per pixel asked for (0 under a time budget).
    total: u64,
    /// Samples per pixel rendered so far.
    done: u64,
    start: Instant,
    cpu_start: f64,
    seconds_per_spp: Option<f64>,
    cpu_per_spp: Option<f64>,
    last_pass: u64,
}

impl Pacing {
    fn start(budget: SampleBudget) -> Pacing {
        let total = match budget {
            SampleBudget::Spp(n) => u64::from(n),
            SampleBudget::Time(_) | SampleBudget::CpuTime(_) => 0,
        };
        let (start, cpu_start) = (Instant::now(), crate::stats::cpu_seconds());
        Pacing {
            budget,
            total,
            done: 0,
            start,
            cpu_start,
            seconds_per_spp: None,
            cpu_per_spp: None,
            last_pass: 0,
        }
    }

    /// Samples per pixel left under a sample budget (`u64::MAX` under a time budget).
    fn remaining(&self) -> u64 {
        match self.budget {
            SampleBudget::Spp(_) => self.total - self.done,
            SampleBudget::Time(_) | SampleBudget::CpuTime(_) => u64::MAX,
        }
    }

    /// The next pass's samples per pixel, or why the render ends; a tile-major pass
    /// takes every sample left.
    fn next_pass(&self, tile_major: bool, deadline: Option<Instant>) -> Result<u64, StopReason> {
        let remaining = self.remaining();
        if remaining == 0 {
            return Err(StopReason::Finished);
        }
        // Size the pass from the measured time per spp: ≈ PASS_SECONDS, growing at most 4×
        let mut pass = match self.seconds_per_spp {
            None => 1,
            Some(t) => ((PASS_SECONDS / t.max(1e-9)) as u64)
                .clamp(1, self.last_pass.saturating_mul(4).max(1)),
        };
        if tile_major {
            pass = remaining;
        }
        pass = pass.min(remaining);
        if let (Some(t), true) = (self.seconds_per_spp, self.done > 0) {
            // Budget and deadline: only passes predicted to end in time
            if let SampleBudget::Time(limit) = self.budget {
                let left = limit - self.start.elapsed().as_secs_f64();
                if left < t {
                    return Err(StopReason::Finished);
                }
                pass = pass.min((left / t) as u64).max(1);
            }
            if let (SampleBudget::CpuTime(limit), Some(c)) = (self.budget, self.cpu_per_spp) {
                let left = limit - (crate::stats::cpu_seconds() - self.cpu_start);
                if left < c {
                    return Err(StopReason::Finished);
                }
                pass = pass.min((left / c) as u64).max(1);
            }
            if let Some(deadline) = deadline {
                let left = deadline.saturating_duration_since(Instant::now()).as_secs_f64();
                if left < t {
                    return Err(StopReason::TimeLimit);
                }
                pass = pass.min((left / t) as u64).max(1);
            }
        }
        Ok(pass)
    }

    /// Every pixel converged (adaptive sampling): under a sample budget the frame holds
    /// all it will ever take, so it counts as rendered to the cap.
    fn converged(&mut self) {
        if let SampleBudget::Spp(_) = self.budget {
            self.done = self.total;
        }
    }

    /// A pass of `pass` samples per pixel, started at `pass_start` and at CPU time
    /// `pass_cpu_start`, is done.
    fn pass_done(&mut self, pass: u64, pass_start: Instant, pass_cpu_start: f64) {
        let elapsed = pass_start.elapsed().as_secs_f64();
        self.seconds_per_spp = Some(elapsed / pass as f64);
        self.cpu_per_spp = Some((crate::stats::cpu_seconds() - pass_cpu_start) / pass as f64);
        self.last_pass = pass;
        self.done += pass;
    }
}

/// One progressive pass of `samples` over every tile of `film`; the tiles' counters in
/// tile order.
///
/// Workers take tiles one at a time from a shared list, the costliest of the last pass
/// first (`tile_seconds`, updated here): the longest-processing-time-first rule, so the
/// pass ends on cheap tiles and no worker waits long for the last one. Rayon's
/// `par_iter_mut` would split the tiles into runs (with 2 workers, about 4 runs of 16 of
/// a 128² image's 64 tiles) that cannot be split once started, so a run holding the
/// fireball would keep the other worker idle. The order changes no pixel: each tile's
/// sums are its own exact integers.
fn progressive_pass<F: Field>(
    scene: &Scene<F>,
    job: TileJob<'_>,
    pool: &rayon::ThreadPool,
    film: &mut Film,
    samples: &std::ops::Range<u64>,
    tile_seconds: &mut [f64],
) -> Vec<Counters> {
    let mut order: Vec<usize> = (0..film.tiles.len()).collect();
    order.sort_by(|&a, &b| tile_seconds[b].total_cmp(&tile_seconds[a]));
    let tiles: Vec<Mutex<&mut Tile>> = film.tiles.iter_mut().map(Mutex::new).collect();
    let results: Vec<Mutex<(Counters, f64)>> =
        tiles.iter().map(|_| Mutex::new((Counters::default(), 0.0))).collect();
    let next = AtomicUsize::new(0);
    pool.broadcast(|_| loop {
        let Some(&i) = order.get(next.fetch_add(1, Ordering::Relaxed)) else { return };
        let start = Instant::now();
        let mut tile = tiles[i].lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        let c = render_tile(scene, job, samples.clone(), &mut tile, None);
        *results[i].lock().unwrap_or_else(std::sync::PoisonError::into_inner) =
            (c, start.elapsed().as_secs_f64());
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

pub mod settings;
pub mod tile;
mod tile_major;

pub use settings::{
    read_ahead_window, RenderControl, RenderResult, RenderSettings, SampleBudget, SampleOrder,
    StopReason, PASS_SECONDS,
};
pub use tile::{pixel_sample, PixelSample};
use tile::{render_tile, TileJob};
use tile_major::TileMajorPass;

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
