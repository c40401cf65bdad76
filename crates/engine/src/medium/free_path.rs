//! Free paths: where a free path ends ([`DistanceSample`]), what tracking a segment
//! returns ([`TrackResult`]), the exponential's inversion `E = −ln(1 − u)`, and the
//! collision a given optical depth into a piece lands on ([`analog_collision`]), shared by
//! regular, forced and null-collision tracking.

use plume_volume::field::{ClassWeights, Piece};

use super::coefficients::Medium;

/// Where the free path ended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DistanceSample {
    /// A real collision at distance `t`, inside a segment with these values (use them,
    /// not a lookup at `x(t)`, which can round into a `μ = 0` neighbour: METHOD.md §10.3).
    Collided {
        /// Distance along the ray.
        t: f64,
        /// Density of the segment that holds the collision (NaN from null-collision
        /// tracking under every estimator but point, which alone scores with it:
        /// `medium::null_tracking`).
        density: f32,
        /// Source of that segment (NaN where the density is).
        source: f32,
        /// Albedo factor of that segment.
        albedo: f32,
        /// Where several volumes overlap, the collision's share of each scattering class
        /// (`volume::overlap`); `None` in one volume.
        classes: Option<ClassWeights>,
    },
    /// No collision before `t_max` (or the field's end).
    Escaped,
}

/// Outcome of tracking a segment (`medium::tracking::track`).
#[derive(Clone, Copy, Debug)]
pub struct TrackResult {
    /// Collision or escape.
    pub event: DistanceSample,
    /// The estimator's value F, an unbiased estimate of `∫₀^d τ L_e ds`.
    pub emission: [f64; 3],
    /// An unbiased estimate of `τ(d)` (0/1 for point, line and blend; the exact value,
    /// roulette-weighted, for ray-march).
    pub transmittance: f64,
    /// Optical depth from the origin to the collision (`E`, exactly, for a sampled
    /// collision), or to the end of the range on escape.
    pub optical_depth: f64,
    /// Segments visited.
    pub segments: u32,
    /// Voxel steps of the traversal (see `SegmentIter::voxel_steps`).
    pub voxel_steps: u64,
    /// Tentative points of null-collision tracking (each reads the field once); 0 for
    /// regular tracking.
    pub tentative_points: u64,
    /// The collision's weight: 1 for an analog free path, `W/q` for a forced one
    /// (`medium::forced`).
    pub collision_weight: f64,
    /// Per-channel factors of a chromatic medium's hero-channel walk; all 1 when grey.
    pub channels: Channels,
}

/// What a chromatic medium's hero-channel walk weighs each channel by
/// (`medium::extinction`); [`Channels::GREY`] (all 1) in a grey medium.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Channels {
    /// Multiplies channel `c`'s throughput at the collision, with `collision_weight` and
    /// the albedo: `e^{−k_c OD}/k̄(OD)`.
    pub collision: [f64; 3],
    /// Channel `c`'s transmittance estimate is `transmittance` times this: `τ_c/τ̄` at the
    /// end of the range.
    pub transmittance: [f64; 3],
}

impl Channels {
    /// A grey medium's: every factor 1.
    pub const GREY: Channels = Channels { collision: [1.0; 3], transmittance: [1.0; 3] };
}

impl TrackResult {
    /// A segment that was not walked: no collision, no emission, nothing crossed.
    #[must_use]
    pub fn nothing() -> TrackResult {
        TrackResult {
            event: DistanceSample::Escaped,
            emission: [0.0; 3],
            transmittance: 1.0,
            optical_depth: 0.0,
            segments: 0,
            voxel_steps: 0,
            tentative_points: 0,
            collision_weight: 1.0,
            channels: Channels::GREY,
        }
    }
}

/// Outcome of a shadow ray: its transmittance and what the walk cost.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadowResult {
    /// `τ` along the ray: exact, or ratio tracking's unbiased estimate.
    pub transmittance: f64,
    /// Voxel steps of the traversal (majorant stretches under ratio tracking).
    pub voxel_steps: u64,
    /// Tentative points of ratio tracking; 0 for an exact walk.
    pub tentative_points: u64,
    /// Channel `c`'s transmittance is `transmittance` times this in a chromatic medium
    /// (`transmittance` is then the channels' mean); all 1 when grey.
    pub channels: [f64; 3],
}

/// Transmittance below which the ray-march estimator plays Russian roulette.
pub const RAY_MARCH_ROULETTE_THRESHOLD: f64 = 1e-2;

/// `φ(x) = (1 − e^{−x})/x` with `φ(0) = 1`, accurate for small `x`.
#[inline]
#[must_use]
pub fn phi(x: f64) -> f64 {
    if x < 1e-4 {
        1.0 - x * (0.5 - x / 6.0)
    } else {
        -(-x).exp_m1() / x
    }
}

/// `E = −ln(1 − u)` for `u ∈ [0, 1)`, without cancellation near 0.
#[inline]
#[must_use]
pub fn sample_exponential(u: f64) -> f64 {
    -(-u).ln_1p()
}

/// The collision `od_left` of optical depth into `piece` (`od_left` below the piece's
/// own): in closed form on a constant piece, from the quartic on a polynomial one. The
/// analog collision, and where a forced one falls (`medium::forced`).
#[inline]
pub fn analog_collision<P: Piece>(piece: &P, medium: &Medium, od_left: f64) -> DistanceSample {
    collision_at(piece, medium, od_left).1
}

/// [`analog_collision`] and its distance `u` into the piece (before `t` is clamped to the
/// piece), for a walk that also reads the piece up to it (`medium::chromatic`).
#[inline]
pub fn collision_at<P: Piece>(piece: &P, medium: &Medium, od_left: f64) -> (f64, DistanceSample) {
    match piece.constant() {
        Some(seg) => {
            let u = od_left / medium.mu_t(seg.density);
            let t = (seg.t0 + u).clamp(seg.t0, seg.t1);
            let event = DistanceSample::Collided {
                t,
                density: seg.density,
                source: seg.source,
                albedo: seg.albedo,
                classes: None,
            };
            (u, event)
        }
        None => {
            let u = piece.free_path(medium.sigma_t, od_left);
            let t = (piece.t0() + u).clamp(piece.t0(), piece.t1());
            let event = DistanceSample::Collided {
                t,
                density: piece.density_at(u),
                source: piece.source_at(u),
                albedo: piece.albedo_at(u),
                classes: piece.class_weights(u),
            };
            (u, event)
        }
    }
}
