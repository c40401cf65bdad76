//! One tile-major pass ([`SampleOrder::TileMajor`](super::SampleOrder::TileMajor)): the
//! workers take tiles in raster order while a prefetch thread asks for the camera rays'
//! bricks of the tiles just ahead, within a window of tiles and bytes; scattered paths
//! may then be finished in rounds (`integrator::deferred`).

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use super::tile::{render_tile, TileJob};
use crate::film::Film;
use crate::integrator::deferred::PendingSample;
use crate::integrator::{Counters, Scene};
use plume_volume::field::{Field, RayGrid};

/// Tiles beyond those being rendered whose camera rays are prefetched.
const PREFETCH_AHEAD: usize = 4;

/// One tile-major pass: the samples each tile takes, the most bytes read ahead for
/// unfinished tiles, when to abandon the pass, and whether scattered paths are deferred
/// into rounds (`integrator::deferred`).
#[derive(Clone, Copy)]
pub(super) struct TileMajorPass<'a> {
    /// Samples of every pixel.
    pub(super) samples: &'a std::ops::Range<u64>,
    /// Bytes asked to be read ahead (`None`: bounded by the tiles ahead only).
    pub(super) read_ahead_window: Option<u64>,
    /// Checked between tiles and rounds: `true` abandons the pass.
    pub(super) abandon: &'a (dyn Fn() -> bool + Sync),
    /// Scattered paths are traced in rounds.
    pub(super) defer: bool,
}

/// How far the render threads are, as the prefetch thread reads it: tiles taken, tiles
/// finished, and the pass finished.
#[derive(Clone, Copy)]
struct TileProgress<'a> {
    taken: &'a AtomicUsize,
    done: &'a [AtomicBool],
    finished: &'a AtomicBool,
}

/// One tile-major pass of `samples` over `film` (see [`SampleOrder::TileMajor`](super::SampleOrder::TileMajor)): the
/// workers take tiles in raster order from a shared queue while a prefetch thread walks
/// the camera rays of the next tiles through `scene.field`, within `read_ahead_window`.
/// With `defer`, the samples whose paths scatter are finished after the tiles, in rounds
/// (`integrator::deferred`). Returns the tiles' counters in tile order (the deferred
/// paths' last), or `None` with `film` unchanged when `abandon` said so between tiles or
/// rounds.
pub(super) fn tile_major_pass<F: Field>(
    scene: &Scene<F>,
    job: TileJob<'_>,
    pool: &rayon::ThreadPool,
    film: &mut Film,
    pass: &TileMajorPass<'_>,
    tile_seconds: &mut [f64],
) -> Option<Vec<Counters>> {
    let TileMajorPass { samples, read_ahead_window, abandon, defer } = *pass;
    let before = film.clone();
    let rects: Vec<(u32, u32, u32, u32)> =
        film.tiles.iter().map(|t| (t.x0, t.y0, t.width, t.height)).collect();
    let taken = AtomicUsize::new(0);
    let finished = AtomicBool::new(false);
    let abandoned = AtomicBool::new(false);
    let queue = Mutex::new(film.tiles.iter_mut().enumerate());
    let results: Mutex<Vec<(usize, Counters, f64)>> = Mutex::new(Vec::with_capacity(rects.len()));
    let done: Vec<AtomicBool> = rects.iter().map(|_| AtomicBool::new(false)).collect();
    let window = ReadAheadWindow {
        ahead: pool.current_num_threads() + PREFETCH_AHEAD,
        bytes: read_ahead_window.unwrap_or(u64::MAX),
    };
    let pending: Mutex<Vec<PendingSample>> = Mutex::new(Vec::new());
    std::thread::scope(|s| {
        if scene.field.is_mapped() {
            scene.field.expect_prefetch();
            s.spawn(|| {
                prefetch_tiles(
                    scene,
                    &rects,
                    TileProgress { taken: &taken, done: &done, finished: &finished },
                    window,
                )
            });
        }
        pool.broadcast(|_| loop {
            if abandoned.load(Ordering::Relaxed) {
                return;
            }
            if abandon() {
                abandoned.store(true, Ordering::Relaxed);
                return;
            }
            let next = queue.lock().unwrap_or_else(std::sync::PoisonError::into_inner).next();
            let Some((i, tile)) = next else { return };
            taken.fetch_max(i + 1, Ordering::Relaxed);
            let start = Instant::now();
            let mut deferred = Vec::new();
            let c =
                render_tile(scene, job, samples.clone(), tile, defer.then_some((i, &mut deferred)));
            if !deferred.is_empty() {
                pending
                    .lock()
                    .unwrap_or_else(std::sync::PoisonError::into_inner)
                    .append(&mut deferred);
            }
            done[i].store(true, Ordering::Relaxed);
            results.lock().unwrap_or_else(std::sync::PoisonError::into_inner).push((
                i,
                c,
                start.elapsed().as_secs_f64(),
            ));
        });
        finished.store(true, Ordering::Relaxed);
    });
    if abandoned.load(Ordering::Relaxed) {
        *film = before;
        return None;
    }
    let mut results = results.into_inner().unwrap_or_else(std::sync::PoisonError::into_inner);
    results.sort_unstable_by_key(|&(i, ..)| i);
    let mut counters: Vec<Counters> = results
        .into_iter()
        .map(|(i, c, seconds)| {
            tile_seconds[i] = seconds;
            c
        })
        .collect();
    let pending = pending.into_inner().unwrap_or_else(std::sync::PoisonError::into_inner);
    if !pending.is_empty() {
        // The scattered paths, in rounds (the film's sums do not depend on when). Their
        // lookups may hold three quarters of the memory budget: the camera pass's
        // read-ahead window (half of it) is free by then, and a fill reads 64 MiB ahead.
        // In a tight memory limit that renders faster than half the budget
        // (docs/BENCHMARKS.md, "Out of core with scattering: the solar flare")
        let lookup = job.settings.integrator.point_lookup;
        let memory = read_ahead_window.map(|w| w.saturating_add(w / 2));
        match crate::integrator::deferred::finish(
            scene, pool, memory, film, pending, lookup, abandon,
        ) {
            Some(c) => counters.push(c),
            None => {
                *film = before;
                return None;
            }
        }
    }
    Some(counters)
}

/// How far the prefetch thread of a tile-major pass may run ahead of the workers.
#[derive(Clone, Copy, Debug)]
struct ReadAheadWindow {
    /// Tiles beyond the last one taken.
    ahead: usize,
    /// Bytes asked for, for tiles not finished.
    bytes: u64,
}

impl ReadAheadWindow {
    /// Whether tile `i` may be asked for now: `taken` tiles have been taken by workers,
    /// and `in_flight` bytes were asked for, for tiles before `i` not yet finished. A
    /// taken tile always may: a worker is reading it now.
    fn allows(self, i: usize, taken: usize, in_flight: u64) -> bool {
        i < taken || (i < taken + self.ahead && in_flight <= self.bytes)
    }
}

/// The prefetch thread of a tile-major pass: hands the rays through the pixel corners of
/// the tiles to `Field::prefetch`, as far ahead of the tiles taken (`taken`) and of those
/// finished (`done`) as `window` allows, until the pass has `finished`.
fn prefetch_tiles<F: Field>(
    scene: &Scene<F>,
    rects: &[(u32, u32, u32, u32)],
    TileProgress { taken, done, finished }: TileProgress<'_>,
    window: ReadAheadWindow,
) {
    let mut grid = RayGrid::default();
    let mut asked = vec![0u64; rects.len()];
    let mut oldest = 0; // no tile before it is unfinished
    for (i, &(x0, y0, w, h)) in rects.iter().enumerate() {
        loop {
            while oldest < i && done[oldest].load(Ordering::Relaxed) {
                oldest += 1;
            }
            let in_flight =
                (oldest..i).filter(|&j| !done[j].load(Ordering::Relaxed)).map(|j| asked[j]).sum();
            if window.allows(i, taken.load(Ordering::Relaxed), in_flight) {
                break;
            }
            if finished.load(Ordering::Relaxed) {
                return;
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        if finished.load(Ordering::Relaxed) {
            return;
        }
        grid.rays.clear();
        (grid.cells_x, grid.cells_y) = (w as usize, h as usize);
        for y in y0..=y0 + h {
            for x in x0..=x0 + w {
                grid.rays.push(scene.camera.ray(f64::from(x), f64::from(y)));
            }
        }
        asked[i] = scene.field.prefetch(&grid);
    }
}

#[cfg(test)]
mod tests {
    use super::ReadAheadWindow;

    /// The prefetch thread asks for a tile when a worker has taken it, or when it is
    /// within `ahead` tiles of the last one taken and the bytes asked for unfinished
    /// tiles are within the window; never otherwise.
    #[test]
    fn the_read_ahead_window_bounds_tiles_and_bytes() {
        let w = ReadAheadWindow { ahead: 4, bytes: 100 };
        // Taken: always, whatever is in flight
        assert!(w.allows(2, 3, 1_000));
        // Waiting, within the tiles ahead: as the bytes allow
        assert!(w.allows(3, 3, 100));
        assert!(!w.allows(3, 3, 101));
        assert!(w.allows(6, 3, 0));
        // Beyond the tiles ahead: never
        assert!(!w.allows(7, 3, 0));
        // No byte bound: the tiles ahead alone
        let tiles = ReadAheadWindow { ahead: 4, bytes: u64::MAX };
        assert!(tiles.allows(6, 3, u64::MAX - 1) && !tiles.allows(7, 3, 0));
    }
}
