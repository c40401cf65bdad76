//! Scattered paths of an out-of-core render, traced in rounds: record, fill, rerun
//! (docs/BENCHMARKS.md, "Out of core with scattering: the solar flare").
//!
//! **Why.** A volume larger than memory is paged from its cache file. The camera pass
//! reads it tile by tile, in order; a scattered path instead looks the volume up at
//! about a hundred points spread over it, each a page read at random, which costs the
//! kernel an order of magnitude more than a page read in file order.
//!
//! **How.** Four facts make the paths replayable without a resumable tracker:
//! - a null-tracked segment's lookups are known before it runs: a walk through a field
//!   that records instead of reading ([`Recorder`](super::tracker)) draws the same numbers
//!   and asks at every point the real walk will ask at (a superset: it never collides);
//! - a scattered path is a pure function of its first vertex and its sampler
//!   ([`Integrator::li_deferring`] hands both out instead of tracing the path);
//! - so it can be run again, and takes the same way for as long as its lookups return the
//!   same values;
//! - the film sums samples as exact fixed-point integers, in any order.
//!
//! Each round reruns every unfinished path against the values gathered for it
//! ([`Answers`], served by [`BufferedPoints`]), from its first vertex or, for a sample's
//! first unfinished path, from the last collision an earlier run reached with every value
//! it asked for ([`Bounces`]: there the vertex, the sampler, the sample's radiance and the
//! counters are kept, and the values read before it are dropped, so a path's values do
//! not pile up from round to round). The first segment whose values are not all there is
//! recorded, not walked; the sampler moves on as the recording drew, so a light (FNEE)
//! segment's miss still lets the path's next segment be recorded in the same round, as if
//! the light segment had no real collision (which a rerun checks). A round reruns samples
//! in order until what they recorded reaches the memory given (`BYTES_PER_LOOKUP` each;
//! `render` gives three quarters of the memory budget). Then every recorded lookup is
//! answered in the order of the cache file (buckets of its value blocks,
//! [`Volume::value_blocks_at`](plume_volume::Volume::value_blocks_at)), each bucket's
//! pages asked for 64 MiB ahead, by the same code a direct walk reads with: a value
//! served later is the value a direct walk would read, bit for bit. A sample's paths are
//! committed in order, each onto the radiance its predecessors left, so the sample
//! reaches the film with the sums a direct render makes: **images and counters are the
//! direct render's**, bit for bit, for any thread count and split.
//!
//! **Cost** (docs/BENCHMARKS.md, "Out of core with scattering: the solar flare"). A fill's time grows with its lookups,
//! and each fill brings most of the file's pages in again. With one path per camera
//! collision a few fills serve a render in a tight memory limit, faster than tracing it
//! directly. Split paths multiply the lookups past what a few fills serve (`--split 8`
//! needs several times as many fills, slower than direct), so `--defer-paths auto` defers
//! one path per camera collision only (`render`), and the rounds are given up when the
//! first one's lookups extrapolate to more than [`MAX_PASSES`] fills.
//!
//! After [`MAX_ROUNDS`] rounds, or once few samples remain, the rest are traced directly.
//! Paths whose scene needs exact walks after scattering (classic NEE, external lights),
//! motion blur, or the point estimator are never deferred ([`Integrator::defers`]).

use std::cell::{Cell, RefCell};

use rayon::prelude::*;

use super::aov::NoAovs;
use super::buffered::{Answer, Answers, Ask, BufferedPoints, Request};
use super::counters::Counters;
use super::path::{Bounces, PathState, Vertex};
use super::scene::Scene;
use super::trace::NoTrace;
use super::tracker::{PointLookup, Points};
use super::volpath::Integrator;
use crate::film::Film;
use crate::medium::null_tracking::PointField;
use plume_core::sampling::Sampler;
use plume_scene::SampleId;
use plume_volume::field::Field;

/// Rounds of record, fill and rerun before the samples left are traced directly.
pub const MAX_ROUNDS: usize = 256;

/// Samples left below which the rest are traced directly: a pass over the file costs
/// more than their random reads.
const FEW_SAMPLES: usize = 64;

impl Request {
    /// The value a direct walk reads: an `L_e`; an albedo factor in the first slot; or
    /// a tentative point's density in the first and, since the walk may collide there and
    /// then ask for it, the albedo factor in the second.
    fn answer<F: Field>(&self, points: &Points<'_, F>) -> [f64; 3] {
        let first = |v: f32| [f64::from(v), 0.0, 0.0];
        let density = |v: f32| [f64::from(v), f64::from(points.albedo(self.p)), 0.0];
        match self.ask {
            Ask::Density => density(points.density(self.p)),
            Ask::DensityPicked => density(points.density_picked(self.p, self.u)),
            Ask::Albedo => first(points.albedo(self.p)),
            Ask::Emission => points.emission_for_fill(self.p),
            Ask::EmissionPicked => points.emission_picked(self.p, self.u),
        }
    }
}

impl<'a> BufferedPoints<'a> {
    /// Values from `answers`, picked as a direct walk through `points` picks.
    fn mirroring<F: Field>(answers: &'a Answers, points: &Points<'_, F>) -> Self {
        BufferedPoints {
            answers,
            picks: points.picks(),
            picks_emission: points.picks_emission(),
            missing: RefCell::default(),
            used: RefCell::default(),
            complete: Cell::new(true),
            gave_up: Cell::new(false),
            last: Cell::new(None),
        }
    }
}

/// A deferred path: the vertex and sampler it runs from (its first, or the last
/// collision an earlier run reached with every value), the values gathered for it since,
/// and what its last run missed.
struct PendingPath {
    vertex: Vertex,
    sampler: Sampler,
    /// From a later collision: the sample's radiance and the path's counters there.
    partial: Option<([f64; 3], Counters)>,
    answers: Answers,
    missing: Vec<Request>,
}

/// Where a deferred path last stood at a collision with every value it had asked for:
/// what its next run resumes from ([`Bounces`]).
struct Resume<'p> {
    points: &'p BufferedPoints<'p>,
    /// Only the first path not committed resumes (the radiance is the sample's, in order).
    enabled: bool,
    last: Option<(Vertex, Sampler, [f64; 3], Counters)>,
}

impl Bounces for Resume<'_> {
    fn at(&mut self, vertex: Vertex, sampler: &Sampler, l: &[f64; 3], c: &Counters) {
        if self.enabled && self.points.complete.get() {
            self.last = Some((vertex, sampler.clone(), *l, *c));
            // What was read before this collision is not read again from it
            self.points.used.borrow_mut().clear();
        }
    }
}

/// A pixel sample whose camera segment is done and whose scattered paths are not.
pub(crate) struct PendingSample {
    /// The film tile and the pixel's index in it.
    tile: usize,
    index: usize,
    /// The sample, for the report of a non-finite one.
    id: SampleId,
    /// The pixel's integrator (its split may be the pixel's own).
    integrator: Integrator,
    /// Radiance of the camera segment and of the paths committed so far, and alpha.
    l: [f64; 3],
    alpha: f64,
    /// The paths in the order a direct render traces them; `next` is the first not
    /// committed.
    paths: Vec<PendingPath>,
    next: usize,
    /// Whether values came for the paths since they last ran.
    stale: bool,
    /// Whether the paths need what deferral cannot serve.
    direct: bool,
}

impl PendingSample {
    /// A sample whose camera segment gave `l` (radiance and alpha) and left `paths`.
    pub(crate) fn new(
        tile: usize,
        index: usize,
        id: SampleId,
        integrator: Integrator,
        l: [f64; 4],
        paths: Vec<(Vertex, Sampler)>,
    ) -> Self {
        let paths = paths
            .into_iter()
            .map(|(vertex, sampler)| PendingPath {
                vertex,
                sampler,
                partial: None,
                answers: Answers::default(),
                missing: Vec::new(),
            })
            .collect();
        PendingSample {
            tile,
            index,
            id,
            integrator,
            l: [l[0], l[1], l[2]],
            alpha: l[3],
            paths,
            next: 0,
            stale: true,
            direct: false,
        }
    }

    fn done(&self) -> bool {
        self.next == self.paths.len()
    }

    /// Lookups the paths wait for.
    fn missing(&self) -> usize {
        self.paths[self.next..].iter().map(|p| p.missing.len()).sum()
    }

    /// Rerun the paths not committed, committing those that got every value, in order
    /// (a committed path's values are dropped); the others note what they miss. The
    /// committed paths' counters.
    fn rerun<F: Field>(&mut self, scene: &Scene<F>, lookup: PointLookup) -> Counters {
        let mut counters = Counters::default();
        if self.direct || !self.stale {
            return counters;
        }
        self.stale = false;
        let points = Points::new(&scene.field, &scene.medium, None, lookup);
        let mut in_order = true;
        for k in self.next..self.paths.len() {
            let path = &mut self.paths[k];
            let buffered = BufferedPoints::mirroring(&path.answers, &points);
            let mut sampler = path.sampler.clone();
            // Only the first path not committed can have run from a later collision
            let (mut l, mut c) = path.partial.unwrap_or((self.l, Counters::default()));
            let mut resume = Resume { points: &buffered, enabled: in_order, last: None };
            self.integrator.deferred_path(
                scene,
                &buffered,
                path.vertex,
                PathState {
                    sampler: &mut sampler,
                    counters: &mut c,
                    trace: &mut NoTrace,
                    aovs: &mut NoAovs,
                },
                &mut resume,
                &mut l,
            );
            let resume = resume.last;
            if buffered.gave_up.get() {
                // Traced directly at the end: nothing of it is asked for or kept
                self.direct = true;
                for path in &mut self.paths {
                    (path.answers, path.missing) = (Answers::default(), Vec::new());
                }
                return counters;
            }
            if buffered.complete.get() && in_order {
                self.l = l;
                self.next = k + 1;
                counters.merge(&c);
                path.answers = Answers::default();
                path.missing = Vec::new();
            } else {
                let (used, mut missing) =
                    (buffered.used.into_inner(), buffered.missing.into_inner());
                if let Some((vertex, sampler, l, c)) = resume {
                    // The next run starts at the last collision this one walked to, with
                    // the values read after it
                    (path.vertex, path.sampler, path.partial) = (vertex, sampler, Some((l, c)));
                    path.answers.keep(&used);
                }
                // A path after an unfinished one runs only to record what it will need
                in_order = false;
                // One key per request (a key is ten multiplications), equal keys equal bits
                missing.sort_by_cached_key(Request::key);
                missing.dedup_by(|a, b| a.bits() == b.bits());
                path.missing = missing;
            }
        }
        counters
    }

    /// Trace the paths not committed directly, reading the volume.
    fn trace_direct<F: Field>(&mut self, scene: &Scene<F>) -> Counters {
        let mut counters = Counters::default();
        for path in &self.paths[self.next..] {
            let mut sampler = path.sampler.clone();
            if let Some((l, c)) = path.partial {
                // Resumed where the rounds left it (only the first path not committed)
                self.l = l;
                counters.merge(&c);
            }
            self.integrator.direct_path(
                scene,
                path.vertex,
                PathState {
                    sampler: &mut sampler,
                    counters: &mut counters,
                    trace: &mut NoTrace,
                    aovs: &mut NoAovs,
                },
                &mut self.l,
            );
        }
        self.next = self.paths.len();
        counters
    }

    /// Add the finished sample to `film` (a non-finite one is dropped and counted).
    fn add_to(&self, film: &mut Film, counters: &mut Counters) {
        let l = [self.l[0], self.l[1], self.l[2], self.alpha];
        if l.iter().all(|v| v.is_finite()) {
            film.tiles[self.tile].add_sample(self.index, self.id.sample, l);
        } else {
            film.tiles[self.tile].add_dropped(self.index, self.id.sample);
            counters.nonfinite_samples += 1;
            self.id.keep_earliest(&mut counters.first_nonfinite);
        }
    }
}

/// Bytes a lookup holds at most, from its recording until its path is committed or
/// resumes past it: the request (40), its place in the file order (12 + 12), its key and
/// value in the fill (40) and in its path's answers (48).
const BYTES_PER_LOOKUP: u64 = 152;

/// The rounds are given up, and every path traced directly, when the first round's
/// lookups, extrapolated to all samples, would take more fills than this. Each fill
/// brings most of the file's pages in again: in a tight memory limit `--split 1` takes a
/// few fills and renders faster than directly, while `--split 8` would need several times
/// this many, slower than directly (docs/BENCHMARKS.md, "Out of core with scattering: the solar flare").
const MAX_PASSES: usize = 8;

/// Samples rerun together, between checks of how many lookups they recorded.
const RERUN_BATCH: usize = 2048;

/// Trace the paths of `pending` in rounds (module docs) and add each sample to `film`
/// when its paths are done. A round reruns the samples in order until they have recorded
/// `memory / BYTES_PER_LOOKUP` lookups (`None`: all samples), then answers those. Returns
/// the paths' counters, with what the rounds did, or `None` as soon as `abandon` says so
/// between rounds (the caller then restores the film: a stop or a deadline abandons a
/// tile-major pass, rounds included).
pub(crate) fn finish<F: Field>(
    scene: &Scene<F>,
    pool: &rayon::ThreadPool,
    memory: Option<u64>,
    film: &mut Film,
    mut pending: Vec<PendingSample>,
    lookup: PointLookup,
    abandon: &(dyn Fn() -> bool + Sync),
) -> Option<Counters> {
    let mut counters = Counters { deferred_samples: pending.len() as u64, ..Counters::default() };
    let most = memory.map_or(usize::MAX, |m| {
        usize::try_from(m / BYTES_PER_LOOKUP).unwrap_or(usize::MAX).max(1 << 16)
    });
    let mut buffers = fill::FillBuffers::default();
    for round in 0..MAX_ROUNDS {
        if abandon() {
            return None;
        }
        // Rerun the samples in order while what they record fits
        let mut recorded = 0;
        let mut start = 0;
        while start < pending.len() && recorded < most {
            let end = (start + RERUN_BATCH).min(pending.len());
            let batch: Vec<(Counters, usize)> = pool.install(|| {
                pending[start..end]
                    .par_iter_mut()
                    .map(|s| {
                        let c = s.rerun(scene, lookup);
                        (c, s.missing())
                    })
                    .collect()
            });
            for (c, n) in &batch {
                counters.merge(c);
                recorded += n;
            }
            start = end;
        }
        counters.deferred_rounds += 1;
        if round == 0
            && start > 0
            && recorded.saturating_mul(pending.len()) / start > MAX_PASSES.saturating_mul(most)
        {
            // The first segments alone would take more fills than random reads cost:
            // every path is traced directly
            break;
        }
        let before = pending.len();
        pending.retain(|s| {
            if s.done() {
                s.add_to(film, &mut counters);
            }
            !s.done()
        });
        if pending.len() <= FEW_SAMPLES || (recorded == 0 && pending.len() == before) {
            break;
        }
        let n = fill::fill(scene, pool, lookup, &mut pending, &mut buffers);
        counters.deferred_lookups += n;
    }
    counters.deferred_direct = pending.len() as u64;
    let direct: Vec<Counters> =
        pool.install(|| pending.par_iter_mut().map(|s| s.trace_direct(scene)).collect());
    direct.iter().for_each(|c| counters.merge(c));
    for s in &pending {
        s.add_to(film, &mut counters);
    }
    Some(counters)
}

mod fill;

#[cfg(test)]
mod tests;
