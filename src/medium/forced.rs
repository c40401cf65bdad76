//! Forced collisions on the expected-value walk (ray-march): every ray that meets the
//! medium may scatter, not only the few whose free path ends in it.
//!
//! **Why.** In thin media most camera rays cross without colliding (2–7 % of them collide
//! on the Mantaflow explosions at their own density). With an analog free path the
//! scattered light of a pixel then rests on whether a handful of its samples collide: at
//! one or two samples per pixel that Bernoulli trial is most of the image's error, and
//! splitting a collision into several paths does not touch it.
//!
//! **The estimator.** An analog walk collides with probability `P = 1 − τ(d)`, at a point
//! of density `μ_t(t) τ(t)` on `[0, d]`. The ray-march walk visits every piece `i` of the
//! ray anyway (until its roulette ends it) and knows each piece's *collision mass*
//! `m_i = τ̂(a_i) (1 − e^{−x_i})`, `x_i` its optical depth and `τ̂` the walk's
//! roulette-weighted transmittance, so that `W = Σ m_i` is an unbiased estimate of `P`.
//! The forced walk then collides with probability `q = min(1, K W)` ([`BOOST`] `K`), at a
//! point of density `μ_t τ̂ / W` (the analog law, conditioned on a collision), and weights
//! it `W / q`:
//!
//! `E[(W/q) g(t) · 1{collide}] = Σ_i m_i E_i[g] = ∫₀^d μ_t τ g dt`,
//!
//! the analog expectation of any `g` of the collision, so everything that follows a
//! collision stays unbiased. `K = 1` draws as many collisions as the analog walk; a large
//! `K` collides wherever `W > 1/K`, while rays that barely touch the medium keep
//! colliding rarely (a path costs the same whatever its weight). Roulette at the path's
//! first vertex compares `β` with the path's start, so a collision weighted well below 1
//! is played for there, after its first light sample.
//!
//! **One number, inverted.** `u < q` collides; then `u W / q` is located on the running
//! sum of the masses, and its place within piece `i` gives the optical depth
//! `y = −ln(1 − v (1 − e^{−x_i}))` into the piece, solved for the distance by the piece's
//! own free-path rule. This map is monotone in `u`, so Sobol points stratify the collision
//! as they stratify an analog free path. (A streaming reservoir choice, with no pieces
//! kept, measured 1.4× the error at 64 spp: its rescaled number is not stratified.)

use crate::medium::tracking::DistanceSample;
use crate::medium::Medium;
use crate::volume::field::Piece;

/// `K`: a forced walk collides with probability `min(1, K W)`. Measured on the three
/// Mantaflow explosions at albedo 0.8 (docs/BENCHMARKS.md, "Forced collisions"): 4 and 16
/// gave the same error at every budget, 4 a few per cent less CPU.
pub const BOOST: f64 = 4.0;

/// How a walk draws its collision.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Collision {
    /// None is needed (no scattering, no depth layer): ray-march does not locate one.
    Skip,
    /// The analog free path: `E = −ln(1 − u)`, a collision where the optical depth
    /// reaches `E`, weight 1.
    Analog,
    /// Forced (module docs). Only the expected-value walk (ray-march, regular tracking)
    /// forces; estimators whose emission depends on the free path (point, line, blend),
    /// and null collisions, draw it as [`Collision::Analog`].
    Forced,
}

impl Collision {
    /// Whether the walk must locate a collision.
    #[inline]
    #[must_use]
    pub fn needed(self) -> bool {
        self != Collision::Skip
    }
}

/// The pieces of a forced walk with positive collision mass, and the running sum of their
/// masses.
pub(crate) struct ForcedCollision<P> {
    /// Each piece, its optical depth, the optical depth at its start, and the running mass
    /// through it.
    pieces: Vec<(P, f64, f64, f64)>,
    total: f64,
}

/// A collision the forced walk drew.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Forced {
    pub event: DistanceSample,
    /// Optical depth from the ray's origin to the collision.
    pub optical_depth: f64,
    /// `W / q`.
    pub weight: f64,
}

impl<P: Piece> ForcedCollision<P> {
    pub(crate) fn new() -> Self {
        ForcedCollision { pieces: Vec::with_capacity(32), total: 0.0 }
    }

    /// A piece of optical depth `x`, starting at optical depth `od` with roulette-weighted
    /// transmittance `tau`.
    #[inline]
    pub(crate) fn push(&mut self, piece: &P, x: f64, od: f64, tau: f64) {
        let mass = tau * -(-x).exp_m1();
        if mass > 0.0 {
            self.total += mass;
            self.pieces.push((*piece, x, od, self.total));
        }
    }

    /// The collision for the walk's number `u ∈ [0, 1)`, if it collides.
    pub(crate) fn draw(&self, medium: &Medium, u: f64) -> Option<Forced> {
        let q = (BOOST * self.total).min(1.0);
        // Written so that a NaN number collides nowhere
        if self.pieces.is_empty() || u.partial_cmp(&q) != Some(std::cmp::Ordering::Less) {
            return None;
        }
        let target = u / q * self.total;
        let k = self.pieces.partition_point(|p| p.3 <= target).min(self.pieces.len() - 1);
        let (piece, x, od, through) = self.pieces[k];
        let before = if k == 0 { 0.0 } else { self.pieces[k - 1].3 };
        // Uniform in [0, 1) within the piece's mass (rounding can put target a hair outside)
        let v = ((target - before) / (through - before)).clamp(0.0, 1.0 - f64::EPSILON / 2.0);
        let y = -(v * (-x).exp_m1()).ln_1p();
        let event = match piece.constant() {
            Some(seg) => {
                let t = (seg.t0 + y / medium.mu_t(seg.density)).clamp(seg.t0, seg.t1);
                DistanceSample::Collided { t, density: seg.density, source: seg.source, albedo: seg.albedo }
            }
            None => {
                let s = piece.free_path(medium.sigma_t, y);
                let t = (piece.t0() + s).clamp(piece.t0(), piece.t1());
                DistanceSample::Collided { t, density: piece.density_at(s), source: piece.source_at(s), albedo: piece.albedo_at(s) }
            }
        };
        Some(Forced { event, optical_depth: od + y, weight: self.total / q })
    }
}
