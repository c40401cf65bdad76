//! The state a path carries from vertex to vertex ([`Vertex`]: where it collided, its
//! throughput `β` and depth) and what it reports to ([`PathState`]: its sampler, the
//! counters, the `--debug-pixel` trace and the AOV sink), in the spirit of pbrt-v4's
//! integrators, which keep a path's state in one place rather than in loose arguments.

use plume_core::sampling::Sampler;
use plume_volume::field::{ClassWeights, Ray};

use super::aov::{Aovs, Component};
use super::counters::Counters;
use super::trace::Trace;

/// What one path draws from and reports to: its numbers, the counters, the trace
/// (`--debug-pixel`) and the AOV sink. The radiance it gathers is added to an `[r, g, b]`
/// the caller owns, so that the split paths of one camera sample add to one sum.
pub struct PathState<'a, T: Trace, A: Aovs> {
    /// The path's sampler (a split path's own, from `Sampler::split`).
    pub sampler: &'a mut Sampler,
    /// Counters of the tile the sample belongs to.
    pub counters: &'a mut Counters,
    /// Receives the path's events when a sample is replayed.
    pub trace: &'a mut T,
    /// Receives every contribution by its AOV component.
    pub aovs: &'a mut A,
}

impl<'a, T: Trace, A: Aovs> PathState<'a, T, A> {
    /// The same sinks with another sampler (a split path's).
    pub fn with_sampler<'b>(&'b mut self, sampler: &'b mut Sampler) -> PathState<'b, T, A> {
        PathState {
            sampler,
            counters: &mut *self.counters,
            trace: &mut *self.trace,
            aovs: &mut *self.aovs,
        }
    }
}

/// The MIS weight owed to a forward segment's emission.
#[derive(Clone, Copy, Debug)]
pub(super) enum ForwardWeight {
    /// No partner technique: full weight.
    One,
    /// Another technique carries this emission.
    Zero,
    /// FNEE partner: `w(p_phase, p_σ(ω))`, evaluated only if the segment collects emission.
    Fnee {
        /// Phase pdf of the segment's direction.
        p_phase: f64,
    },
}

/// A path's throughput per channel (the channels differ through a coloured albedo and,
/// in a chromatic medium, the hero-channel walk's weights).
pub(crate) type Beta = [f64; 3];

/// `beta` times `w`, channel by channel.
#[inline]
pub(crate) fn times(beta: Beta, w: f64) -> Beta {
    beta.map(|b| b * w)
}

/// A collision a scattered path starts from: at `incoming.at(t)`, in a segment with
/// albedo factor `albedo` (or the class shares `classes`), carrying throughput `beta` (before the albedo) of a path whose
/// nominal weight is `scale`, after `depth` earlier collisions of the path.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Vertex {
    pub(super) incoming: Ray,
    pub(super) t: f64,
    pub(super) albedo: f32,
    /// Where several volumes overlap, the collision's class shares (`overlap`), which
    /// then give its albedo and phase instead of `albedo` and the medium's.
    pub(super) classes: Option<ClassWeights>,
    pub(super) beta: Beta,
    /// 1, or `1/n` for one of `n` split paths: roulette keeps `β` near it.
    pub(super) scale: f64,
    /// Collisions of the path before this one (0 at the camera segment's).
    pub(super) depth: u32,
}

/// Told where a scattered path stands at each collision it bounces from, before the
/// bounce: the vertex, the sampler, the radiance so far and the counters. Continuing
/// from there gives the rest of the path, bit for bit (deferred paths resume from the
/// last collision whose past they could walk: `integrator::deferred`).
pub(crate) trait Bounces {
    /// The path is about to bounce at `vertex`.
    fn at(&mut self, vertex: Vertex, sampler: &Sampler, l: &[f64; 3], c: &Counters);
}

/// No one is told (every path but a deferred one's).
pub(crate) struct NoBounces;

impl Bounces for NoBounces {
    #[inline(always)]
    fn at(&mut self, _vertex: Vertex, _sampler: &Sampler, _l: &[f64; 3], _c: &Counters) {}
}

/// Add `w · e`, channel by channel, to the radiance and to its AOV component (`w` is a
/// path's throughput times the estimate's weight).
#[inline]
pub(super) fn contribute<A: Aovs>(
    l: &mut [f64; 3],
    aovs: &mut A,
    component: Component,
    w: Beta,
    e: [f64; 3],
) {
    if w != [0.0; 3] {
        for ((a, v), w) in l.iter_mut().zip(e).zip(w) {
            *a += w * v;
        }
        aovs.add(component, w, e);
    }
}
