//! Scattered paths of an out-of-core render, traced in rounds: record, fill, rerun
//! (issue #17; docs/BENCHMARKS.md, "Scattering in a memory limit").
//!
//! **Why.** A volume larger than memory is paged from its cache file. The camera pass
//! reads it tile by tile, in order; a scattered path instead looks the volume up at
//! about a hundred points spread over it, each a page read at random (≈ 9 µs of kernel
//! time per 4 KiB page in a cgroup, against ≈ 0.7 µs for a page read in file order).
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
//! **Cost** (docs/BENCHMARKS.md, "Deferred paths"). A fill's time grows with its lookups
//! (about 2.3 µs each in a tight cgroup, 0.8 µs in core), and each fill brings most of
//! the file's pages in again. The 2048³ flare in a 1.5 GiB cgroup, `--split 1`: 67–85 s
//! against 126–131 s direct (cached 21.4 s; the host's load varies). Split paths multiply
//! the lookups past what a few fills serve (`--split 8`: about 35 fills, slower than
//! direct), so `--defer-paths auto` defers one path per camera collision only (`render`),
//! and the rounds are given up when the first one's lookups extrapolate to more than
//! [`MAX_PASSES`] fills.
//!
//! After [`MAX_ROUNDS`] rounds, or once few samples remain, the rest are traced directly.
//! Paths whose scene needs exact walks after scattering (classic NEE, external lights),
//! motion blur, or the point estimator are never deferred ([`Integrator::defers`]).

use std::cell::{Cell, RefCell};

use glam::DVec3;
use rayon::prelude::*;

use super::tracker::{PointLookup, Points};
use super::volpath::{Bounces, Vertex};
use super::{Counters, Integrator, Scene};
use crate::film::Film;
use crate::medium::null_tracking::{PointField, PointSample};
use crate::render::SampleId;
use plume_core::sampling::{mix64, Sampler};
use plume_volume::field::Field;

/// Rounds of record, fill and rerun before the samples left are traced directly.
pub const MAX_ROUNDS: usize = 256;

/// Samples left below which the rest are traced directly: a pass over the file costs
/// more than their random reads.
const FEW_SAMPLES: usize = 64;

/// What a walk asks of the field at a point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Ask {
    /// A tentative point's density.
    Density,
    /// A tentative point's density, one voxel picked by its weight with the request's `u`.
    DensityPicked,
    /// A real collision's albedo factor.
    Albedo,
    /// An emission point's `L_e`.
    Emission,
    /// An emission point's `L_e`, one voxel picked with the request's `u`.
    EmissionPicked,
}

/// One value a walk asks for.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Request {
    /// World point.
    pub(crate) p: DVec3,
    /// What is asked there.
    pub(crate) ask: Ask,
    /// The number a picked lookup draws (0 for the others).
    pub(crate) u: f64,
}

impl Request {
    /// The exact bits of what the request asks.
    fn bits(&self) -> ([u64; 4], Ask) {
        ([self.p.x, self.p.y, self.p.z, self.u].map(f64::to_bits), self.ask)
    }

    /// The request's key: 128 bits of hash over the exact bits of what it asks, from two
    /// independent multiply–rotate lanes, each finished by [`mix64`] (a path holds a few
    /// hundred keys: two of them agree with probability about 2⁻¹²⁰).
    fn key(&self) -> u128 {
        let (bits, _) = self.bits();
        let lane = |seed: u64, k: u64| mix64(bits.iter().fold(seed ^ self.ask as u64, |h, &b| (h ^ b).wrapping_mul(k).rotate_left(29)));
        (u128::from(lane(0x243f_6a88_85a3_08d3, 0x9e37_79b9_7f4a_7c15)) << 64) | u128::from(lane(0x1319_8a2e_0370_7344, 0xc2b2_ae3d_27d4_eb4f))
    }

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

/// A request's key and the value a direct walk reads for it.
type Answer = (u128, [f64; 3]);

/// The values a path has been served, by request key.
#[derive(Debug, Default)]
pub(crate) struct Answers {
    entries: Vec<Answer>,
}

impl Answers {
    /// The entry for `key`: its index and value.
    fn get(&self, key: u128) -> Option<(usize, [f64; 3])> {
        self.entries.binary_search_by_key(&key, |e| e.0).ok().map(|i| (i, self.entries[i].1))
    }

    /// Keep only the entries at `used` (indices, any order, repeats allowed).
    fn keep(&mut self, used: &[u32]) {
        let mut kept = vec![false; self.entries.len()];
        used.iter().for_each(|&i| kept[i as usize] = true);
        let mut flags = kept.iter();
        self.entries.retain(|_| flags.next().copied().unwrap_or(false));
    }

    /// Sort the entries by key after pushing new ones (a key answered twice keeps one).
    fn sort(&mut self) {
        self.entries.sort_unstable_by_key(|e| e.0);
        self.entries.dedup_by_key(|e| e.0);
    }
}

/// The field as a deferred path's null collisions read it: from its sample's [`Answers`].
/// A value not there reads as 0 and is noted; the walk's result is then void.
pub struct BufferedPoints<'a> {
    answers: &'a Answers,
    picks: bool,
    picks_emission: bool,
    missing: RefCell<Vec<Request>>,
    /// The answers read since the path last stood at a collision it could resume from.
    used: RefCell<Vec<u32>>,
    complete: Cell<bool>,
    gave_up: Cell<bool>,
    /// The last tentative point read and the albedo factor its answer carries: a real
    /// collision asks for it next.
    last: Cell<Option<(DVec3, f32)>>,
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

    /// Whether every one of `requests` (a recorded segment's) is answered; the rest are
    /// noted as missing.
    pub(crate) fn has_all(&self, requests: &[Request]) -> bool {
        // Every request is looked up, so that all the missing ones are noted
        requests.iter().filter(|&&r| self.look_up(r).is_none()).count() == 0
    }

    /// The path needs what deferral cannot serve: it is traced directly.
    pub(crate) fn give_up(&self) {
        self.complete.set(false);
        self.gave_up.set(true);
    }

    /// A tentative point's density, keeping the albedo factor its answer carries.
    fn tentative(&self, r: Request) -> f32 {
        let v = self.answer(r);
        self.last.set(Some((r.p, v[1] as f32)));
        v[0] as f32
    }

    /// The answer to `r`, or 0 where there is none.
    fn answer(&self, r: Request) -> [f64; 3] {
        self.look_up(r).unwrap_or([0.0; 3])
    }

    /// The answer to `r`; a request without one is noted as missing, and the walk as
    /// incomplete.
    fn look_up(&self, r: Request) -> Option<[f64; 3]> {
        match self.answers.get(r.key()) {
            Some((i, value)) => {
                self.used.borrow_mut().push(i as u32);
                Some(value)
            }
            None => {
                self.complete.set(false);
                self.missing.borrow_mut().push(r);
                None
            }
        }
    }
}

impl PointField for BufferedPoints<'_> {
    fn picks(&self) -> bool {
        self.picks
    }
    fn picks_emission(&self) -> bool {
        self.picks_emission
    }
    fn density(&self, p: DVec3) -> f32 {
        self.tentative(Request { p, ask: Ask::Density, u: 0.0 })
    }
    fn density_picked(&self, p: DVec3, u: f64) -> f32 {
        self.tentative(Request { p, ask: Ask::DensityPicked, u })
    }
    fn albedo(&self, p: DVec3) -> f32 {
        match self.last.get() {
            Some((q, albedo)) if q.to_array().map(f64::to_bits) == p.to_array().map(f64::to_bits) => albedo,
            _ => self.answer(Request { p, ask: Ask::Albedo, u: 0.0 })[0] as f32,
        }
    }
    fn emission(&self, p: DVec3) -> [f64; 3] {
        self.answer(Request { p, ask: Ask::Emission, u: 0.0 })
    }
    fn emission_picked(&self, p: DVec3, u: f64) -> [f64; 3] {
        self.answer(Request { p, ask: Ask::EmissionPicked, u })
    }
    /// A real collision's whole record: only the point estimator asks, and its paths are
    /// not deferred.
    fn sample(&self, _p: DVec3, _emission: bool) -> PointSample {
        self.give_up();
        PointSample::default()
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
    pub(crate) fn new(tile: usize, index: usize, id: SampleId, integrator: Integrator, l: [f64; 4], paths: Vec<(Vertex, Sampler)>) -> Self {
        let paths = paths
            .into_iter()
            .map(|(vertex, sampler)| PendingPath { vertex, sampler, partial: None, answers: Answers::default(), missing: Vec::new() })
            .collect();
        PendingSample { tile, index, id, integrator, l: [l[0], l[1], l[2]], alpha: l[3], paths, next: 0, stale: true, direct: false }
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
            self.integrator.deferred_path(scene, &buffered, (path.vertex, &mut sampler, &mut resume), &mut c, &mut l);
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
                let (used, mut missing) = (buffered.used.into_inner(), buffered.missing.into_inner());
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
            self.integrator.direct_path(scene, (path.vertex, &mut sampler), &mut counters, &mut self.l);
        }
        self.next = self.paths.len();
        counters
    }

    /// Add the finished sample to `film` (a non-finite one is dropped and counted).
    fn add_to(&self, film: &mut Film, counters: &mut Counters) {
        let l = [self.l[0], self.l[1], self.l[2], self.alpha];
        if l.iter().all(|v| v.is_finite()) {
            film.tiles[self.tile].add_sample(self.index, l);
        } else {
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
/// brings most of the file's pages in again; in the 2048³ flare's 1.5 GiB cgroup
/// (`docs/BENCHMARKS.md`), `--split 1` takes 9 rounds (16 M lookups, up to 4 M a fill)
/// and renders in 67–85 s instead of 126–131 s, while `--split 8` would need about 35
/// fills of 4 M lookups, slower than its 195–217 s direct.
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
    (pool, memory): (&rayon::ThreadPool, Option<u64>),
    film: &mut Film,
    mut pending: Vec<PendingSample>,
    (lookup, abandon): (PointLookup, &(dyn Fn() -> bool + Sync)),
) -> Option<Counters> {
    let mut counters = Counters { deferred_samples: pending.len() as u64, ..Counters::default() };
    let most = memory.map_or(usize::MAX, |m| usize::try_from(m / BYTES_PER_LOOKUP).unwrap_or(usize::MAX).max(1 << 16));
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
        if round == 0 && start > 0 && recorded.saturating_mul(pending.len()) / start > MAX_PASSES.saturating_mul(most) {
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
    let direct: Vec<Counters> = pool.install(|| pending.par_iter_mut().map(|s| s.trace_direct(scene)).collect());
    direct.iter().for_each(|c| counters.merge(c));
    for s in &pending {
        s.add_to(film, &mut counters);
    }
    Some(counters)
}

mod fill;

#[cfg(test)]
mod tests;
