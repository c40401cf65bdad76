//! Regular tracking: exact free-path sampling through piecewise-constant segments, and
//! the emission estimators F of METHOD.md §3–4.
//!
//! Optical depth `OD(s) = ∫₀ˢ μ_t`, transmittance `τ = e^{−OD}`. A free path solves
//! `OD(t) = E` with `E = −ln(1 − u)`: walking segments in order, the collision lies in the
//! first segment `i` with `OD + μ_iΔ_i > E` (strict, so `μ = 0` never collides), at
//! `t = a_i + (E − OD)/μ_i`. This is exact (`Pr{t > s} = τ(s)`), with no majorant.
//! OD and `t` are `f64` (METHOD.md §10.2).
//!
//! Each estimator returns an unbiased estimate of `I_e = ∫₀^d τ(s) L_e(s) ds`:
//! - **point** (collision): `L_{e,c}/μ_c` at a collision, 0 on escape;
//! - **line** (track-length, the paper's): `∫₀^{min(t,d)} L_e ds`;
//! - **ray-march** (expected value): `Σ_i τ(a_i) L_{e,i} Δ_i φ(μ_iΔ_i)`,
//!   `φ(x) = (1 − e^{−x})/x`, independent of the collision, stopped by Russian roulette
//!   once `τ` is small;
//! - **blend** (our extension, METHOD.md §4): per-segment mix
//!   `α_i = 1/(1 + κ μ_i Δ_i)` of line (weight α) and point (1 − α).

pub use plume_scene::sets::Estimator;
use std::ops::ControlFlow;

use super::coefficients::Medium;
pub use super::free_path::{
    analog_collision, phi, sample_exponential, Channels, DistanceSample, ShadowResult, TrackResult,
    RAY_MARCH_ROULETTE_THRESHOLD,
};
use crate::medium::emission::{EmissionMemo, LeTask};
use crate::medium::forced::{Collision, Forced, ForcedCollision, SplitFirsts};
use plume_core::color::Rgb;
use plume_core::sampling::Sampler;
use plume_volume::field::{Field, Piece, PieceIntegrals, PointValues, Ray, Segment, SegmentIter};

mod stretch;
pub use stretch::{walk_stretch, StretchKind, StretchWalk};

#[inline]
pub(super) fn add(acc: &mut [f64; 3], le: Rgb, w: f64) {
    for (a, c) in acc.iter_mut().zip(le.0) {
        *a += f64::from(c) * w;
    }
}

/// Sample a free path along `ray` over `[0, t_max]` and estimate the emission collected.
///
/// `u` drives the free path; `sampler` supplies roulette decisions for ray-march. With
/// [`Collision::Skip`] (no scattering), ray-march does not locate the collision; with
/// [`Collision::Forced`] it forces one (`medium::forced`), and the other estimators draw
/// it as [`Collision::Analog`].
// Each argument is a distinct input of the estimator (randomness stays an argument: STYLE §3)
#[allow(clippy::too_many_arguments)]
pub fn track<F: Field>(
    field: &F,
    medium: &Medium,
    ray: &Ray,
    t_max: f64,
    estimator: Estimator,
    collision: Collision,
    u: f64,
    sampler: &mut Sampler,
) -> TrackResult {
    match estimator {
        // A forced walk is its own instance, so that walks without one run the code they ran
        // before forcing existed, with no branch or buffer of it
        Estimator::RayMarch if collision == Collision::Forced => {
            let start = MarchStart::whole(u);
            track_expected::<F, true>(field, medium, ray, start, t_max, collision, u, sampler, None)
        }
        Estimator::RayMarch => {
            let start = MarchStart::whole(u);
            track_expected::<F, false>(
                field, medium, ray, start, t_max, collision, u, sampler, None,
            )
        }
        _ => track_free_path(field, medium, ray, t_max, estimator, u),
    }
}

/// [`track`], and where it forces the collision (ray-march, [`Collision::Forced`]) the
/// first vertices of `paths` split paths appended to `firsts`, one stratum of the
/// collision law each (`medium::forced`, "Split paths start apart"); `firsts` stays as
/// it is where the walk does not force or does not collide. The result is [`track`]'s.
// Each argument is a distinct input of the walk (randomness stays an argument: STYLE §3)
#[allow(clippy::too_many_arguments)]
pub(crate) fn track_split<F: Field>(
    field: &F,
    medium: &Medium,
    ray: &Ray,
    t_max: f64,
    estimator: Estimator,
    collision: Collision,
    u: f64,
    sampler: &mut Sampler,
    split: SplitFirsts<'_>,
) -> TrackResult {
    if estimator == Estimator::RayMarch && collision == Collision::Forced {
        let start = MarchStart::whole(u);
        track_expected::<F, true>(
            field,
            medium,
            ray,
            start,
            t_max,
            collision,
            u,
            sampler,
            Some(split),
        )
    } else {
        track(field, medium, ray, t_max, estimator, collision, u, sampler)
    }
}

fn track_free_path<F: Field>(
    field: &F,
    medium: &Medium,
    ray: &Ray,
    t_max: f64,
    estimator: Estimator,
    u: f64,
) -> TrackResult {
    let e = sample_exponential(u);
    let walk = free_path_stretch(field, medium, ray, 0.0, t_max, estimator, e);
    TrackResult {
        event: walk.collision.unwrap_or(DistanceSample::Escaped),
        emission: walk.emission,
        transmittance: if walk.collision.is_some() { 0.0 } else { 1.0 },
        optical_depth: walk.optical_depth,
        segments: walk.segments,
        voxel_steps: walk.voxel_steps,
        tentative_points: 0,
        collision_weight: 1.0,
        channels: Channels::GREY,
    }
}

/// Regular tracking of `ray` over `[t0, t1]` against the exponential `e` (the free path
/// ends where the optical depth from `t0` reaches `e`), with the point, line or blend
/// estimate of the emission collected on the way. A whole free path is the stretch
/// `[0, t_max]` with `e = −ln(1 − u)`.
///
/// # Panics
/// For [`Estimator::RayMarch`] (an expected-value walk, `track_expected`).
fn free_path_stretch<F: Field>(
    field: &F,
    medium: &Medium,
    ray: &Ray,
    t0: f64,
    t1: f64,
    estimator: Estimator,
    e: f64,
) -> StretchWalk {
    let memo = EmissionMemo::new(&medium.emission);
    let mut od = 0.0f64;
    let mut f = [0.0f64; 3];
    let mut segments = 0u32;
    let mut it = field.segments(ray, t0, t1);
    let collision = it.visit(|piece| {
        segments += 1;
        let Some(seg) = piece.constant() else {
            // A polynomial piece (trilinear reconstruction, METHOD.md §12)
            return match free_path_polynomial(piece, medium, &memo, estimator, e, &mut od, &mut f) {
                Some(event) => ControlFlow::Break(event),
                None => ControlFlow::Continue(()),
            };
        };
        let mu = medium.mu_t(seg.density);
        let len = seg.length();
        let x = mu * len;
        let le = medium.emission.le(seg.density, seg.source);
        if od + x > e {
            // Collide inside this segment
            let t = (seg.t0 + (e - od) / mu).clamp(seg.t0, seg.t1);
            match estimator {
                Estimator::Point => add(&mut f, le, 1.0 / mu),
                Estimator::Line => add(&mut f, le, t - seg.t0),
                Estimator::Blend { kappa } => {
                    let alpha = 1.0 / (1.0 + kappa * x);
                    add(&mut f, le, alpha * (t - seg.t0) + (1.0 - alpha) / mu);
                }
                Estimator::RayMarch => unreachable!("ray-march is tracked by track_expected"),
            }
            return ControlFlow::Break(DistanceSample::Collided {
                t,
                density: seg.density,
                source: seg.source,
                albedo: seg.albedo,
                classes: None,
            });
        }
        od += x;
        // Add emission along the whole segment
        match estimator {
            Estimator::Line => add(&mut f, le, len),
            Estimator::Blend { kappa } => add(&mut f, le, len / (1.0 + kappa * x)),
            _ => {}
        }
        ControlFlow::Continue(())
    });
    let (collision, optical_depth) = match collision {
        ControlFlow::Break(event) => (Some(event), e),
        ControlFlow::Continue(()) => (None, od),
    };
    let voxel_steps = it.voxel_steps();
    StretchWalk { collision, emission: f, optical_depth, weight: 1.0, segments, voxel_steps }
}

#[inline]
fn add_scaled(acc: &mut [f64; 3], v: [f64; 3], w: f64) {
    for (a, c) in acc.iter_mut().zip(v) {
        *a += c * w;
    }
}

/// `L_e` at `u` on a polynomial piece: each voxel's emission density interpolated
/// (`volume/trilinear/mod.rs`, "What is interpolated").
#[inline]
pub(super) fn emission_at<P: Piece>(piece: &P, le: &EmissionMemo<'_>, u: f64) -> [f64; 3] {
    /// [`Piece::emission_at`] as a task of the memo.
    struct At<'p, P>(&'p P, f64);
    impl<P: Piece> LeTask for At<'_, P> {
        type Out = [f64; 3];
        #[inline]
        fn run(self, le: &impl Fn(f32, f32) -> Rgb) -> [f64; 3] {
            self.0.emission_at(le, self.1)
        }
    }
    le.run(At(piece, u))
}

/// Density and `L_e` at a world point (a next-event sample), by the same rule as
/// `emission_at` along pieces: the field's reconstruction of each voxel's emission.
#[must_use]
pub fn emission_at_point<F: Field>(
    field: &F,
    medium: &Medium,
    p_world: glam::DVec3,
) -> PointValues {
    field.reconstruct(p_world, &|d, s| medium.emission.le(d, s))
}

/// `∫₀ᵘ L_e ds` on a polynomial piece, in closed form (a cubic per channel).
#[inline]
fn emission_integral<P: Piece>(piece: &P, le: &EmissionMemo<'_>, u: f64) -> [f64; 3] {
    /// [`Piece::emission_integral`] as a task of the memo.
    struct Integral<'p, P>(&'p P, f64);
    impl<P: Piece> LeTask for Integral<'_, P> {
        type Out = [f64; 3];
        #[inline]
        fn run(self, le: &impl Fn(f32, f32) -> Rgb) -> [f64; 3] {
            self.0.emission_integral(le, self.1)
        }
    }
    if !piece.may_emit() || u <= 0.0 {
        return [0.0; 3];
    }
    le.run(Integral(piece, u))
}

/// [`Piece::integrals`] over `[0, u]` with the memo's `L_e`.
#[inline]
fn integrals<P: Piece>(piece: &P, sigma_t: f64, le: &EmissionMemo<'_>, u: f64) -> PieceIntegrals {
    /// [`Piece::integrals`] as a task of the memo.
    struct Both<'p, P>(&'p P, f64, f64);
    impl<P: Piece> LeTask for Both<'_, P> {
        type Out = PieceIntegrals;
        #[inline]
        fn run(self, le: &impl Fn(f32, f32) -> Rgb) -> PieceIntegrals {
            self.0.integrals(self.1, le, self.2)
        }
    }
    le.run(Both(piece, sigma_t, u))
}

/// One polynomial piece of a free path: the same estimators as the constant case, with
/// the piece's closed forms (METHOD.md §12):
/// - the collision solves `OD(u) = E − OD_before` exactly ([`Piece::free_path`]);
/// - point: `L_e(u_c)/μ(u_c)`; line: `∫₀^{u_c} L_e du` ([`emission_integral`]), or over
///   the whole piece;
/// - blend: the piece's `α = 1/(1 + κ OD_piece)`, which does not depend on where the
///   collision falls, so the mix of two unbiased estimates stays unbiased.
///
/// Adds to `od` and `f`; returns the collision, if the free path ends here.
fn free_path_polynomial<P: Piece>(
    piece: &P,
    medium: &Medium,
    le: &EmissionMemo<'_>,
    estimator: Estimator,
    e: f64,
    od: &mut f64,
    f: &mut [f64; 3],
) -> Option<DistanceSample> {
    let len = piece.length();
    // The line part needs the whole piece's emission unless the path ends here: computed
    // with its optical depth (one set of trilinear weights), and unused in that one piece
    let (x, whole_emission) = match estimator {
        Estimator::Line | Estimator::Blend { .. } => {
            let whole = integrals(piece, medium.sigma_t, le, len);
            (whole.optical_depth, whole.emission)
        }
        Estimator::Point | Estimator::RayMarch => {
            (piece.optical_depth(medium.sigma_t, len), [0.0; 3])
        }
    };
    let alpha = match estimator {
        Estimator::Blend { kappa } => 1.0 / (1.0 + kappa * x),
        Estimator::Line => 1.0,
        Estimator::Point | Estimator::RayMarch => 0.0,
    };
    if *od + x > e {
        let u = piece.free_path(medium.sigma_t, e - *od);
        let density = piece.density_at(u);
        if alpha > 0.0 {
            add_scaled(f, emission_integral(piece, le, u), alpha);
        }
        let mu = medium.mu_t(density);
        if alpha < 1.0 && mu > 0.0 {
            add_scaled(f, emission_at(piece, le, u), (1.0 - alpha) / mu);
        }
        let t = (piece.t0() + u).clamp(piece.t0(), piece.t1());
        return Some(DistanceSample::Collided {
            t,
            density,
            source: piece.source_at(u),
            albedo: piece.albedo_at(u),
            classes: piece.class_weights(u),
        });
    }
    *od += x;
    if alpha > 0.0 {
        add_scaled(f, whole_emission, alpha);
    }
    None
}

/// A marched piece as its emission reads it: its length and optical depth `x`, the
/// optical depth `od` and roulette `weight` before it, `τ` before it where the roulette
/// formed it, and the one-point rule's point `(u, x(u))` on a polynomial piece.
#[derive(Clone, Copy)]
struct MarchedPiece {
    len: f64,
    x: f64,
    od: f64,
    weight: f64,
    tau: Option<f64>,
    x_at_point: Option<(f64, f64)>,
}

/// The optical depth of `piece`, and where a marched emitting polynomial piece needs it,
/// the one-point rule's point and the optical depth to it, both from one density cubic.
/// Its `ξ` (`xi`, `Some` where the point is needed) is drawn at the first such piece,
/// after the roulette, so the random sampler's stream keeps its order.
#[inline(always)]
fn piece_depths<P: Piece>(
    piece: &P,
    constant: Option<Segment>,
    medium: &Medium,
    xi: Option<&mut Option<f64>>,
    sampler: &mut Sampler,
) -> (f64, Option<(f64, f64)>) {
    let len = piece.length();
    match (constant, xi) {
        (Some(seg), _) => (medium.mu_t(seg.density) * len, None),
        (None, Some(xi)) => {
            let xi = *xi.get_or_insert_with(|| sampler.get_1d(plume_core::sampling::Dim::OnePoint));
            let u = xi * len;
            let [x, x_u] = piece.optical_depths(medium.sigma_t, [len, u]);
            (x, Some((u, x_u)))
        }
        (None, None) => (piece.optical_depth(medium.sigma_t, len), None),
    }
}

/// The expected-value estimator's emission on a marched emitting piece, added to `f`:
/// `τ Δ φ(x) L_e` on a constant piece, and on a polynomial one the one-point rule
/// (METHOD.md §12): `Δ τ(u_ξ) L_e(u_ξ)` with `u_ξ` uniform in the piece is unbiased for
/// `∫ τ L_e` over it. One `ξ` serves every piece of the ray (systematic sampling: each
/// piece's point is still uniform in it).
#[inline(always)]
fn add_marched_emission<P: Piece>(
    f: &mut [f64; 3],
    piece: &P,
    constant: Option<Segment>,
    memo: &EmissionMemo<'_>,
    medium: &Medium,
    at: MarchedPiece,
) {
    let MarchedPiece { len, x, od, weight, tau, x_at_point } = at;
    match constant {
        Some(seg) => {
            let le = medium.emission.le(seg.density, seg.source);
            let tau = tau.expect("invariant: a marched constant emitting piece forms τ");
            add(f, le, tau * len * phi(x));
        }
        None => {
            let (u, x_u) =
                x_at_point.expect("invariant: a marched emitting polynomial piece has its point");
            // Where the roulette did not need `τ`, it is `e^{−od} · weight`: one `exp`
            let tau_u = match tau {
                Some(tau) => tau * (-x_u).exp(),
                None => (-(od + x_u)).exp() * weight,
            };
            add_scaled(f, emission_at(piece, memo, u), tau_u * len);
        }
    }
}

/// A forced walk's collision, once the walk is done ([`ForcedCollision::draw`]); with
/// `split`, the split paths' first vertices are drawn first.
fn draw_forced<P: Piece>(
    forced: &ForcedCollision<P>,
    split: Option<SplitFirsts<'_>>,
    medium: &Medium,
    u: f64,
) -> Option<Forced> {
    if let Some(SplitFirsts { paths, firsts }) = split {
        forced.draw_split(medium, u, paths, firsts);
    }
    forced.draw(medium, u)
}

/// Where a ray-march walk starts: at `t0`, with the exponential `e` of its free path and
/// the weight it carries (the roulette's, and ratio tracking's before a dense stretch).
#[derive(Clone, Copy, Debug)]
struct MarchStart {
    t0: f64,
    e: f64,
    weight: f64,
}

impl MarchStart {
    /// A whole segment's walk: from 0, with `E = −ln(1 − u)` and weight 1.
    fn whole(u: f64) -> MarchStart {
        MarchStart { t0: 0.0, e: sample_exponential(u), weight: 1.0 }
    }
}

// Each argument is a distinct input of the walk (randomness stays an argument: STYLE §3)
#[allow(clippy::too_many_arguments)]
fn track_expected<F: Field, const FORCED: bool>(
    field: &F,
    medium: &Medium,
    ray: &Ray,
    start: MarchStart,
    t_max: f64,
    collision: Collision,
    u: f64,
    sampler: &mut Sampler,
    split: Option<SplitFirsts<'_>>,
) -> TrackResult {
    let memo = EmissionMemo::new(&medium.emission);
    // The analog free path is drawn on the way; a forced one once the walk is done
    let need_collision = collision == Collision::Analog;
    let mut forced = FORCED.then(ForcedCollision::new);
    let e = start.e;
    let mut od = 0.0f64;
    let mut weight = start.weight; // roulette weight
    let mut f = [0.0f64; 3];
    let mut segments = 0u32;
    let mut event = DistanceSample::Escaped;
    let mut marching = true;
    // Position of the one-point rule in every polynomial piece, drawn at the first one
    let mut xi: Option<f64> = None;
    // Below this optical depth the roulette cannot fire at the current weight
    let mut roulette_free_below = roulette_free_depth(weight);
    let mut it = field.segments(ray, start.t0, t_max);
    let _ = it.visit(|piece| {
        segments += 1;
        let len = piece.length();
        let constant = piece.constant();
        // Roulette first: it reads only the optical depth before the piece, and it decides
        // whether the piece is marched. Below `roulette_free_below` it cannot fire (no
        // random number is drawn while `τ · weight` is above the threshold), so `τ` is
        // formed only where something reads it: a forced collision's candidate, a
        // constant emitting piece; an emitting polynomial piece takes the transmittance
        // to its point in one `exp` (below). Elsewhere no `exp` is called.
        let emits = match constant {
            Some(seg) => seg.source != 0.0,
            None => piece.may_emit(),
        };
        // `τ` before the piece, roulette weight folded in; `None` where not formed
        let mut tau = None;
        if marching && (FORCED || od >= roulette_free_below || (emits && constant.is_some())) {
            let before = weight;
            match march_roulette((-od).exp() * weight, &mut weight, sampler) {
                Some(t) => tau = Some(t),
                None => marching = false,
            }
            if weight != before {
                roulette_free_below = roulette_free_depth(weight);
            }
        }
        // A marched emitting polynomial piece needs its optical depth at the one-point
        // rule's point too: both from one density cubic. Its point is drawn where it always
        // was (after the roulette, at the first such piece), so the random sampler's stream
        // keeps its order.
        let (x, x_at_point) =
            piece_depths(piece, constant, medium, (marching && emits).then_some(&mut xi), sampler);
        if need_collision && event == DistanceSample::Escaped && od + x > e {
            event = analog_collision(piece, medium, e - od);
        }
        if marching {
            if let Some(forced) = forced.as_mut() {
                forced.push(
                    piece,
                    x,
                    od,
                    tau.expect("invariant: a forced walk forms τ at every marched piece"),
                );
            }
            if emits {
                let at = MarchedPiece { len, x, od, weight, tau, x_at_point };
                add_marched_emission(&mut f, piece, constant, &memo, medium, at);
            }
        }
        od += x;
        if !marching && (!need_collision || event != DistanceSample::Escaped) {
            return ControlFlow::Break(());
        }
        ControlFlow::Continue(())
    });
    let transmittance = if marching { (-od).exp() * weight } else { 0.0 };
    let mut optical_depth = if matches!(event, DistanceSample::Collided { .. }) { e } else { od };
    let mut collision_weight = 1.0;
    if let Some(drawn) = forced.and_then(|forced| draw_forced(&forced, split, medium, u)) {
        (event, optical_depth, collision_weight) = (drawn.event, drawn.optical_depth, drawn.weight);
    }
    TrackResult {
        event,
        emission: f,
        transmittance,
        optical_depth,
        segments,
        voxel_steps: it.voxel_steps(),
        tentative_points: 0,
        collision_weight,
        channels: Channels::GREY,
    }
}

/// An optical depth below which [`march_roulette`] cannot fire at roulette weight
/// `weight` (`e^{−od} · weight` stays above the threshold): `ln(weight / threshold)`, less
/// a margin far above the rounding of `exp` and `ln`, so that skipping the roulette there
/// never changes its outcome.
#[inline]
fn roulette_free_depth(weight: f64) -> f64 {
    (weight / RAY_MARCH_ROULETTE_THRESHOLD).ln() - 1e-9
}

/// Russian roulette on the ray-march's transmittance `tau` (its roulette weight folded
/// in): below [`RAY_MARCH_ROULETTE_THRESHOLD`] the march goes on with probability
/// `tau / threshold`, `weight` scaled up by the inverse, and the piece is weighted by the
/// threshold; `None` ends it (`weight` 0). Keeps the walk finite.
#[inline]
pub(super) fn march_roulette(tau: f64, weight: &mut f64, sampler: &mut Sampler) -> Option<f64> {
    if tau < RAY_MARCH_ROULETTE_THRESHOLD {
        let q = tau / RAY_MARCH_ROULETTE_THRESHOLD;
        if sampler.next_f64() >= q {
            *weight = 0.0;
            return None;
        }
        *weight /= q;
        return Some(RAY_MARCH_ROULETTE_THRESHOLD);
    }
    Some(tau)
}

/// What [`optical_depth`] measured along a shadow ray.
#[derive(Clone, Copy, Debug, PartialEq)]
#[must_use]
pub struct OpticalDepth {
    /// Optical depth `OD = ∫ μ_t ds` (unitless; `τ = e^{−OD}`), possibly stopped early
    /// once it exceeded `od_stop`.
    pub optical_depth: f64,
    /// Voxel steps of the traversal (see [`SegmentIter::voxel_steps`]).
    pub voxel_steps: u64,
}

/// Exact optical depth along `ray` over `[0, t_max]` (for shadow rays: `τ = e^{−OD}`).
/// Stops early once OD exceeds `od_stop` (then `τ` is negligible anyway).
pub fn optical_depth<F: Field>(
    field: &F,
    medium: &Medium,
    ray: &Ray,
    t_max: f64,
    od_stop: f64,
) -> OpticalDepth {
    let (optical_depth, voxel_steps) = field.optical_depth(medium.sigma_t, ray, t_max, od_stop);
    OpticalDepth { optical_depth, voxel_steps }
}
