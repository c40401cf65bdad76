//! What a deferred path reads instead of the field: the values its null collisions
//! asked for ([`Request`]s), answered in file order by the fill and kept by request key
//! ([`Answers`]), and the [`BufferedPoints`] view through which a rerun of the path reads
//! them. A value that is not there reads as 0 and is noted as missing; the rerun's result
//! is then void and the path is asked again (`integrator::deferred`).

use std::cell::{Cell, RefCell};

use glam::DVec3;

use crate::medium::null_tracking::{PointField, PointSample};
use plume_core::sampling::mix64;

/// What a walk asks of the field at a point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ask {
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
pub struct Request {
    /// World point.
    pub p: DVec3,
    /// What is asked there.
    pub ask: Ask,
    /// The number a picked lookup draws (0 for the others).
    pub u: f64,
}

impl Request {
    /// The exact bits of what the request asks.
    pub(super) fn bits(&self) -> ([u64; 4], Ask) {
        ([self.p.x, self.p.y, self.p.z, self.u].map(f64::to_bits), self.ask)
    }

    /// The request's key: 128 bits of hash over the exact bits of what it asks, from two
    /// independent multiply–rotate lanes, each finished by [`mix64`] (a path holds a few
    /// hundred keys: two of them agree with probability about 2⁻¹²⁰).
    pub(super) fn key(&self) -> u128 {
        let (bits, _) = self.bits();
        let lane = |seed: u64, k: u64| {
            mix64(
                bits.iter()
                    .fold(seed ^ self.ask as u64, |h, &b| (h ^ b).wrapping_mul(k).rotate_left(29)),
            )
        };
        (u128::from(lane(0x243f_6a88_85a3_08d3, 0x9e37_79b9_7f4a_7c15)) << 64)
            | u128::from(lane(0x1319_8a2e_0370_7344, 0xc2b2_ae3d_27d4_eb4f))
    }
}

/// A request's key and the value a direct walk reads for it.
pub(super) type Answer = (u128, [f64; 3]);

/// The values a path has been served, by request key.
#[derive(Debug, Default)]
pub struct Answers {
    pub(super) entries: Vec<Answer>,
}

impl Answers {
    /// The entry for `key`: its index and value.
    pub(super) fn get(&self, key: u128) -> Option<(usize, [f64; 3])> {
        self.entries.binary_search_by_key(&key, |e| e.0).ok().map(|i| (i, self.entries[i].1))
    }

    /// Keep only the entries at `used` (indices, any order, repeats allowed).
    pub(super) fn keep(&mut self, used: &[u32]) {
        let mut kept = vec![false; self.entries.len()];
        used.iter().for_each(|&i| kept[i as usize] = true);
        let mut flags = kept.iter();
        self.entries.retain(|_| flags.next().copied().unwrap_or(false));
    }

    /// Sort the entries by key after pushing new ones (a key answered twice keeps one).
    pub(super) fn sort(&mut self) {
        self.entries.sort_unstable_by_key(|e| e.0);
        self.entries.dedup_by_key(|e| e.0);
    }
}

/// The field as a deferred path's null collisions read it: from its sample's [`Answers`].
/// A value not there reads as 0 and is noted; the walk's result is then void.
pub struct BufferedPoints<'a> {
    pub(super) answers: &'a Answers,
    pub(super) picks: bool,
    pub(super) picks_emission: bool,
    pub(super) missing: RefCell<Vec<Request>>,
    /// The answers read since the path last stood at a collision it could resume from.
    pub(super) used: RefCell<Vec<u32>>,
    pub(super) complete: Cell<bool>,
    pub(super) gave_up: Cell<bool>,
    /// The last tentative point read and the albedo factor its answer carries: a real
    /// collision asks for it next.
    pub(super) last: Cell<Option<(DVec3, f32)>>,
}

impl<'a> BufferedPoints<'a> {
    /// Whether every one of `requests` (a recorded segment's) is answered; the rest are
    /// noted as missing.
    pub fn has_all(&self, requests: &[Request]) -> bool {
        // Every request is looked up, so that all the missing ones are noted
        requests.iter().filter(|&&r| self.look_up(r).is_none()).count() == 0
    }

    /// The path needs what deferral cannot serve: it is traced directly.
    pub fn give_up(&self) {
        self.complete.set(false);
        self.gave_up.set(true);
    }

    /// A tentative point's density, keeping the albedo factor its answer carries.
    pub(super) fn tentative(&self, r: Request) -> f32 {
        let v = self.answer(r);
        self.last.set(Some((r.p, v[1] as f32)));
        v[0] as f32
    }

    /// The answer to `r`, or 0 where there is none.
    pub(super) fn answer(&self, r: Request) -> [f64; 3] {
        self.look_up(r).unwrap_or([0.0; 3])
    }

    /// The answer to `r`; a request without one is noted as missing, and the walk as
    /// incomplete.
    pub(super) fn look_up(&self, r: Request) -> Option<[f64; 3]> {
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
            Some((q, albedo))
                if q.to_array().map(f64::to_bits) == p.to_array().map(f64::to_bits) =>
            {
                albedo
            }
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
