//! Free paths through a chromatic medium by regular tracking (METHOD.md §15; the
//! channels' weights are derived in `medium::extinction`).
//!
//! The walk is a grey one, `OD = ∫ σ_t ρ`, with the hero channel's target `E/k_h`, so its
//! collision is exact as in `medium::tracking`. What each estimator collects per channel
//! `c` (`L_e^c` the emission density, `τ_c = e^{−k_c OD}`, `τ̄` their mean):
//! - **line**: `∫₀^{min(t,d)} L_e^c τ_c/τ̄ ds`, unbiased for `∫₀^d τ_c L_e^c` because
//!   `Pr{t > s} = τ̄(s)`. The ratio is exact at every point, but its integral over a piece
//!   has no closed form: each piece takes one point `s` uniform in the part of it the
//!   walk crossed (length `ℓ`) and adds `ℓ L_e^c(s) τ_c(s)/τ̄(s)`, unbiased for that part
//!   (one `ξ` per walk, as ray-march's one-point rule). Where `μ = 0` the ratio is
//!   constant over the piece and the point is exact.
//! - **point**: at a collision after optical depth `OD`,
//!   `L_e^c/μ · e^{−k_c OD}/k̄(OD)`, the grey score times the collision's weight.
//! - **blend**: line with `α = 1/(1 + κ μΔ)` per piece and point with `1 − α` at the
//!   collision's; `α` uses the reference `μ`, so it is fixed by the ray.
//! - **ray-march** (expected value): `Σ_i τ_c(a_i) L_e^c Δ_i φ(k_c x_i)` on constant pieces
//!   and the one-point rule `Δ τ_c(u) L_e^c(u)` on polynomial ones: each channel in
//!   closed form, independent of the collision. Its roulette plays on the least attenuated
//!   channel's `τ`; the hero's collision is drawn on the way.
//!
//! Forced camera collisions (`medium::forced`) are for grey media: a chromatic walk draws
//! the analog collision wherever one is asked for.

use std::ops::ControlFlow;

use super::coefficients::Medium;
use super::emission::EmissionMemo;
use super::extinction::Chromatic;
use super::forced::Collision;
use super::free_path::{
    analog_collision, collision_at, phi, sample_exponential, Channels, DistanceSample, TrackResult,
};
use super::tracking::{emission_at, march_roulette, Estimator};
use plume_core::sampling::{Dim, Sampler};
use plume_volume::field::{Field, Piece, Ray, Segment, SegmentIter};

/// A free path along `ray` over `[0, t_max]` through a chromatic medium and the emission
/// `estimator` collects on the way, per channel; `u` picks the hero channel and its free
/// path ([`Chromatic::hero`]); `sampler` gives the one-point rule's `ξ` and ray-march's
/// roulette. The result's `channels` carry the collision's and the escape's weights.
// Each argument is a distinct input of the walk (randomness stays an argument: STYLE §3)
#[allow(clippy::too_many_arguments)]
pub fn track_chromatic<F: Field>(
    field: &F,
    medium: &Medium,
    chromatic: &Chromatic,
    ray: &Ray,
    t_max: f64,
    estimator: Estimator,
    collision: Collision,
    u: f64,
    sampler: &mut Sampler,
) -> TrackResult {
    let (hero, u) = Chromatic::hero(u);
    let walk = Walk {
        field,
        medium,
        chromatic,
        ray,
        t_max,
        target: chromatic.target(hero, sample_exponential(u)),
        memo: EmissionMemo::new(&medium.emission),
    };
    match estimator {
        Estimator::RayMarch => walk.march(collision.needed(), sampler),
        _ => walk.free_path(estimator, sampler),
    }
}

/// One chromatic walk: the field, the medium, the ray and the hero's target optical depth.
struct Walk<'a, F: Field> {
    field: &'a F,
    medium: &'a Medium,
    chromatic: &'a Chromatic,
    ray: &'a Ray,
    t_max: f64,
    /// The reference optical depth at which the hero channel's free path ends.
    target: f64,
    memo: EmissionMemo<'a>,
}

/// A piece as the walk reads it: its length, optical depth and whether it emits.
#[derive(Clone, Copy)]
struct Read {
    len: f64,
    x: f64,
    emits: bool,
}

impl<F: Field> Walk<'_, F> {
    /// The reference optical depth of `piece` over `[0, u]`.
    #[inline]
    fn depth<P: Piece>(&self, piece: &P, constant: Option<Segment>, u: f64) -> f64 {
        match constant {
            Some(seg) => self.medium.mu_t(seg.density) * u,
            None => piece.optical_depth(self.medium.sigma_t, u),
        }
    }

    #[inline]
    fn read<P: Piece>(&self, piece: &P, constant: Option<Segment>) -> Read {
        let len = piece.length();
        let emits = match constant {
            Some(seg) => seg.source != 0.0,
            None => piece.may_emit(),
        };
        Read { len, x: self.depth(piece, constant, len), emits }
    }

    /// `L_e` at `u` into `piece`.
    #[inline]
    fn le_at<P: Piece>(&self, piece: &P, constant: Option<Segment>, u: f64) -> [f64; 3] {
        match constant {
            Some(seg) => self.medium.emission.le(seg.density, seg.source).to_f64(),
            None => emission_at(piece, &self.memo, u),
        }
    }

    /// Point, line or blend (the module docs).
    fn free_path(&self, estimator: Estimator, sampler: &mut Sampler) -> TrackResult {
        let (chromatic, target) = (self.chromatic, self.target);
        let mut od = 0.0f64;
        let mut f = [0.0f64; 3];
        let mut segments = 0u32;
        let mut xi: Option<f64> = None;
        // The point estimator's score at the collision, before its channels' weights
        let mut point = [0.0f64; 3];
        let mut it = self.field.segments(self.ray, 0.0, self.t_max);
        let end = it.visit(|piece| {
            segments += 1;
            let constant = piece.constant();
            let Read { len, x, emits } = self.read(piece, constant);
            // The collision, and its distance into the piece
            let hit = (od + x > target).then(|| collision_at(piece, self.medium, target - od));
            let alpha = match estimator {
                Estimator::Point => 0.0,
                Estimator::Blend { kappa } => 1.0 / (1.0 + kappa * x),
                Estimator::Line | Estimator::RayMarch => 1.0,
            };
            let crossed = hit.map_or(len, |(u, _)| u.clamp(0.0, len));
            if alpha > 0.0 && emits && crossed > 0.0 {
                // One point of the crossed part carries its ratio τ_c/τ̄
                let s = *xi.get_or_insert_with(|| sampler.get_1d(Dim::OnePoint)) * crossed;
                let le = self.le_at(piece, constant, s);
                let r = chromatic.escape_weights(od + self.depth(piece, constant, s));
                for c in 0..3 {
                    f[c] += alpha * crossed * le[c] * r[c];
                }
            }
            let Some((u, event)) = hit else {
                od += x;
                return ControlFlow::Continue(());
            };
            // The point part's `(1 − α) L_e/μ`, weighted once the collision's weights are
            if let (true, true, DistanceSample::Collided { density, .. }) =
                (alpha < 1.0, emits, event)
            {
                let mu = self.medium.mu_t(density);
                if mu > 0.0 {
                    point = self.le_at(piece, constant, u).map(|v| (1.0 - alpha) * v / mu);
                }
            }
            ControlFlow::Break(event)
        });
        let voxel_steps = it.voxel_steps();
        let (event, transmittance, optical_depth, channels) = match end {
            ControlFlow::Break(event) => {
                let collision = chromatic.collision_weights(target);
                for c in 0..3 {
                    f[c] += point[c] * collision[c];
                }
                (event, 0.0, target, Channels { collision, ..Channels::GREY })
            }
            ControlFlow::Continue(()) => {
                let escape = chromatic.escape_weights(od);
                (
                    DistanceSample::Escaped,
                    1.0,
                    od,
                    Channels { transmittance: escape, ..Channels::GREY },
                )
            }
        };
        TrackResult {
            event,
            emission: f,
            transmittance,
            optical_depth,
            segments,
            voxel_steps,
            tentative_points: 0,
            collision_weight: 1.0,
            channels,
        }
    }

    /// Ray-march, the expected value per channel (the module docs); the hero's analog
    /// collision where `need_collision`.
    fn march(&self, need_collision: bool, sampler: &mut Sampler) -> TrackResult {
        let (chromatic, target) = (self.chromatic, self.target);
        let k = chromatic.factors();
        let k_min = k[0].min(k[1]).min(k[2]);
        let mut od = 0.0f64;
        let mut weight = 1.0f64;
        let mut f = [0.0f64; 3];
        let mut segments = 0u32;
        let mut event = DistanceSample::Escaped;
        let mut marching = true;
        let mut xi: Option<f64> = None;
        let mut it = self.field.segments(self.ray, 0.0, self.t_max);
        let _ = it.visit(|piece| {
            segments += 1;
            let constant = piece.constant();
            let Read { len, x, emits } = self.read(piece, constant);
            if marching
                && march_roulette((-k_min * od).exp() * weight, &mut weight, sampler).is_none()
            {
                marching = false;
            }
            if need_collision && event == DistanceSample::Escaped && od + x > target {
                event = analog_collision(piece, self.medium, target - od);
            }
            if marching && emits {
                match constant {
                    Some(seg) => {
                        let le = self.medium.emission.le(seg.density, seg.source).to_f64();
                        for c in 0..3 {
                            f[c] += weight * (-k[c] * od).exp() * len * phi(k[c] * x) * le[c];
                        }
                    }
                    None => {
                        let u = *xi.get_or_insert_with(|| sampler.get_1d(Dim::OnePoint)) * len;
                        let od_u = od + piece.optical_depth(self.medium.sigma_t, u);
                        let le = emission_at(piece, &self.memo, u);
                        for c in 0..3 {
                            f[c] += weight * (-k[c] * od_u).exp() * len * le[c];
                        }
                    }
                }
            }
            od += x;
            if !marching && (!need_collision || event != DistanceSample::Escaped) {
                return ControlFlow::Break(());
            }
            ControlFlow::Continue(())
        });
        let (transmittance, ratios) =
            if marching { chromatic.transmittance_ratios(od, weight) } else { (0.0, [1.0; 3]) };
        let collided = matches!(event, DistanceSample::Collided { .. });
        let channels = Channels {
            collision: if collided { chromatic.collision_weights(target) } else { [1.0; 3] },
            transmittance: ratios,
        };
        TrackResult {
            event,
            emission: f,
            transmittance,
            optical_depth: if collided { target } else { od },
            segments,
            voxel_steps: it.voxel_steps(),
            tentative_points: 0,
            collision_weight: 1.0,
            channels,
        }
    }
}
