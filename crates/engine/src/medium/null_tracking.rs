//! Null-collision tracking with line integration (METHOD.md §13): free paths and
//! transmittance through a field known only point by point (a velocity-advected volume
//! for motion blur), under the majorants of `volume::majorant`.
//!
//! **Delta tracking.** On a majorant stretch with `μ̄ = σ_t ρ̄`, tentative collisions
//! follow at `Exp(μ̄)` steps; each is real with probability `μ(x)/μ̄`. The first real one
//! has density `μ(t) τ(t)` along the ray: the law regular tracking samples exactly, so
//! every estimator downstream is unchanged in expectation.
//!
//! **Line integration survives.** `Pr{min(t, d) > s} = τ(s)` still holds, so
//! `F = ∫₀^{min(t,d)} L_e ds` stays unbiased when the integral is replaced by an unbiased
//! estimate of it: the tentative points cut `[0, min(t, d)]` into sub-segments of lengths
//! `ℓ_j`, and `Σ_j ℓ_j L_e(s_j)` with `s_j` uniform in sub-segment `j` is unbiased given
//! the cut (nested expectations). Stretches whose source bound is 0 add nothing and are not
//! evaluated.
//!
//! **Ratio tracking** estimates `τ(s)` by `W(s) = Π_{x_i < s} (1 − μ(x_i)/μ̄)` over the
//! tentative points before `s`: shadow rays, and the expected-value (ray-march) estimator,
//! `∫ τ L_e ds ≈ Σ_j ℓ_j W_j L_e(s_j)` (`W` is constant on each sub-segment, so the same
//! nesting argument holds). Ray-march keeps its Russian roulette on small `W`, and finds
//! its collision (when the path scatters) by delta tracking on the same tentative points.
//!
//! **Stochastic point lookups** ([`PointField::picks`]; `integrator::tracker::PointLookup`):
//! a field may read a tentative point's density as one voxel picked with its
//! reconstruction weight, from one more number of the stream. What a tentative point's
//! density serves is linear in it (an acceptance probability, a ratio-tracking factor),
//! so an unbiased value keeps every estimate unbiased, and delta tracking's free-path law
//! is unchanged exactly. An emission point's `ℓ W L_e(s_j)` is linear in the corners'
//! `L_e` too, so a field may pick one corner there as well ([`PointField::picks_emission`],
//! one more number; an option, after scattering only, with a heavier tail:
//! `integrator::tracker::PointLookup`). A real collision reads exactly what its record
//! serves: the point estimator's score needs the density and `L_e` there; every other
//! estimator needs only the albedo factor ([`PointField::albedo`]), and its record's
//! density and source are NaN (nothing reads them, so the 8-corner gather they would
//! cost, a visible part of a render's instructions, is skipped).
//!
//! The point estimator scores `L_e(x)/μ(x)` at the real collision. Blend (a per-voxel
//! mix) has no voxels to mix over here and is refused before rendering.
//!
//! **Dense stretches.** A stretch of majorant `μ̄` costs `μ̄ ℓ` tentative points on
//! average, without bound as the density grows, while regular tracking costs the voxels
//! it crosses. Where a field can walk its voxels (a still volume) and `μ̄` exceeds
//! [`DENSE_TENTATIVE_PER_VOXEL`] tentative points per voxel crossed, the stretch is
//! tracked exactly ([`PointField::exact_stretch`]) with
//! what is left of the free path's exponential: delta tracking's `e` left at the
//! stretch's start is `Exp(1)` whatever came before (memorylessness), so it serves as the
//! target optical depth of the exact walk, and on escape `e − τ_stretch` is again `Exp(1)`
//! for the next stretch. The free path keeps its law; the line estimate is exact over
//! such a stretch, the point estimate scores where the exact walk collides, and ray-march
//! multiplies its ratio-tracking weight by the stretch's exact transmittance (its roulette
//! applies to the product). Every estimate stays unbiased, and a segment costs at most
//! about its voxels, whatever the density.
//!
//! Randomness: the first step uses the segment's `u` (a stratified dimension); every
//! later number comes from the sample's hashed stream, so a sample stays a pure function
//! of its key.

use super::coefficients::Medium;
use super::free_path::{
    sample_exponential, DistanceSample, ShadowResult, TrackResult, RAY_MARCH_ROULETTE_THRESHOLD,
};
use super::tracking::{StretchKind, StretchWalk};
use plume_core::sampling::Sampler;
use plume_scene::Estimator;
use plume_volume::field::Ray;
use plume_volume::majorant::MajorantGrid;

/// What the field holds at a point, as the tracker needs it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PointSample {
    /// Density (μ_t = σ_t ρ).
    pub density: f32,
    /// Emission source (for the collision record).
    pub source: f32,
    /// Emission density `L_e`, radiance per unit length.
    pub emission: [f64; 3],
    /// Albedo factor.
    pub albedo: f32,
}

/// The field as null collisions read it at world points: each read asks only for what
/// it uses (a tentative point its density; an emission point its `L_e`; a real
/// collision everything), so a lookup costs one gather of the reconstruction.
pub trait PointField {
    /// Density at `p`.
    fn density(&self, p: glam::DVec3) -> f32;
    /// Emission density `L_e` at `p`.
    fn emission(&self, p: glam::DVec3) -> [f64; 3];
    /// Everything at a real collision; its `L_e` only when `emission` (the point
    /// estimator scores it; zero otherwise, and a trilinear field reads no corner's `L_e`).
    fn sample(&self, p: glam::DVec3, emission: bool) -> PointSample;
    /// The albedo factor alone (exact), at a real collision whose record needs nothing
    /// else: [`null_track`] for every estimator but point.
    fn albedo(&self, p: glam::DVec3) -> f32 {
        self.sample(p, false).albedo
    }
    /// Whether the field reads tentative points by stochastic filtering
    /// ([`PointField::density_picked`]): [`null_track`] then draws one number per read.
    fn picks(&self) -> bool {
        false
    }
    /// An unbiased one-term estimate of [`PointField::density`] from the uniform `u`.
    fn density_picked(&self, p: glam::DVec3, _u: f64) -> f32 {
        self.density(p)
    }
    /// Whether emission points read by [`PointField::emission_picked`]: [`null_track`]
    /// then draws one more number per emission point.
    fn picks_emission(&self) -> bool {
        false
    }
    /// An unbiased one-term estimate of [`PointField::emission`] from the uniform `u`.
    fn emission_picked(&self, p: glam::DVec3, _u: f64) -> [f64; 3] {
        self.emission(p)
    }
    /// Whether the field can walk its voxels exactly ([`PointField::exact_stretch`]): a
    /// still volume can, a moving one cannot.
    fn walks_exactly(&self) -> bool {
        false
    }
    /// Regular tracking of `[t0, t1]` of `ray` as `kind` says
    /// (`medium::tracking::walk_stretch`), where [`PointField::walks_exactly`].
    fn exact_stretch(
        &self,
        _ray: &Ray,
        _t0: f64,
        _t1: f64,
        _kind: StretchKind,
        _sampler: &mut Sampler,
    ) -> Option<StretchWalk> {
        None
    }
}

/// Tentative points per voxel crossed above which a stretch is walked exactly: there a
/// regular walk (one closed form per voxel) costs less than the tentative points, whose
/// number grows with the density (module docs, "Dense stretches").
pub const DENSE_TENTATIVE_PER_VOXEL: f64 = 1.0;

/// `field`'s density at `p`, picked with a number of `sampler`'s when `picks` (the
/// field's [`PointField::picks`], asked once per walk).
#[inline]
fn density_of(field: &impl PointField, picks: bool, p: glam::DVec3, sampler: &mut Sampler) -> f32 {
    if picks {
        field.density_picked(p, sampler.next_f64())
    } else {
        field.density(p)
    }
}

/// A closure giving the whole [`PointSample`] is a [`PointField`] (tests, analytic fields).
impl<T: Fn(glam::DVec3) -> PointSample> PointField for T {
    fn density(&self, p: glam::DVec3) -> f32 {
        self(p).density
    }
    fn emission(&self, p: glam::DVec3) -> [f64; 3] {
        self(p).emission
    }
    fn sample(&self, p: glam::DVec3, emission: bool) -> PointSample {
        let s = self(p);
        PointSample { emission: if emission { s.emission } else { [0.0; 3] }, ..s }
    }
}

fn add(f: &mut [f64; 3], e: [f64; 3], w: f64) {
    for (a, v) in f.iter_mut().zip(e) {
        *a += w * v;
    }
}

/// What a null-collision walk has cost: voxel steps of its exact stretches, and its
/// tentative points.
#[derive(Clone, Copy, Debug, Default)]
struct Work {
    exact_steps: u64,
    tentative_points: u64,
}

/// What a null-collision walk carries from stretch to stretch.
struct Walk {
    /// The estimator's emission so far.
    f: [f64; 3],
    /// Ratio tracking's weight `W` (ray-march).
    weight: f64,
    /// The real collision, once found.
    event: DistanceSample,
    /// What is left of the free path's exponential, in majorant optical depth.
    e: f64,
    /// Null collisions do not know the optical depth to the collision (point NEE's MIS
    /// needs it; classic NEE is refused with motion blur): NaN once collided.
    od_to_collision: f64,
}

impl Walk {
    /// Whether the walk is over: ray-march once its weight is 0 and it needs no more
    /// collision; the others at their collision.
    fn ended(&self, expected: bool, need_collision: bool) -> bool {
        if expected {
            self.weight == 0.0 && (self.event != DistanceSample::Escaped || !need_collision)
        } else {
            self.event != DistanceSample::Escaped
        }
    }

    /// The walk's result: its transmittance estimate is ray-march's weight, or 0/1.
    fn result(self, expected: bool, segments: u32, work: Work) -> TrackResult {
        let transmittance = if expected {
            self.weight
        } else if self.event == DistanceSample::Escaped {
            1.0
        } else {
            0.0
        };
        TrackResult {
            event: self.event,
            emission: self.f,
            transmittance,
            optical_depth: self.od_to_collision,
            segments,
            voxel_steps: u64::from(segments) + work.exact_steps,
            tentative_points: work.tentative_points,
            collision_weight: 1.0,
            channels: super::free_path::Channels::GREY,
        }
    }

    /// Take in an exact walk of a dense stretch ("Dense stretches"); `collide` when it
    /// was asked to locate the collision.
    fn cross_exactly(&mut self, walk: &StretchWalk, collide: bool) {
        add(&mut self.f, walk.emission, 1.0);
        self.weight = walk.weight;
        match walk.collision {
            Some(collision) => {
                self.event = collision;
                self.od_to_collision = f64::NAN;
            }
            // What is left of the exponential, by memorylessness again Exp(1)
            None if collide => self.e -= walk.optical_depth,
            None => {}
        }
    }
}

/// The majorant above which a stretch of `ray` costs more tentative points than voxels
/// and is walked exactly ("Dense stretches"); infinite where `field` cannot walk.
fn dense_majorant(majorants: &MajorantGrid, field: &impl PointField, ray: &Ray) -> f64 {
    if field.walks_exactly() {
        DENSE_TENTATIVE_PER_VOXEL * majorants.voxel_crossings_per_length(ray)
    } else {
        f64::INFINITY
    }
}

/// Track `ray` over `[0, t_max]` by null collisions: the free path (delta tracking) and
/// the estimator's emission (module docs). `field` gives the field at world points.
///
/// # Panics
/// For [`Estimator::Blend`] (refused when the scene is built).
// Each argument is a distinct input of the walk (randomness stays an argument: STYLE §3)
#[allow(clippy::too_many_arguments)]
pub fn null_track(
    majorants: &MajorantGrid,
    field: &impl PointField,
    medium: &Medium,
    ray: &Ray,
    t_max: f64,
    estimator: Estimator,
    need_collision: bool,
    u: f64,
    sampler: &mut Sampler,
) -> TrackResult {
    assert!(!matches!(estimator, Estimator::Blend { .. }), "blend needs regular tracking");
    let expected = estimator == Estimator::RayMarch;
    // Line and ray-march integrate along the stretches; point scores at the collision
    let integrates = estimator != Estimator::Point;
    let picks = field.picks();
    let picks_emission = field.picks_emission();
    let mut w = Walk {
        f: [0.0; 3],
        weight: 1.0,
        event: DistanceSample::Escaped,
        e: sample_exponential(u),
        od_to_collision: 0.0,
    };
    let mut segments = 0u32;
    let mut done = false;
    let dense = dense_majorant(majorants, field, ray);
    let mut work = Work::default();
    for seg in majorants.segments(ray, 0.0, t_max) {
        segments += 1;
        let mu_bar = medium.mu_t(seg.bounds.density);
        if mu_bar > dense {
            let collide = w.event == DistanceSample::Escaped && (need_collision || !expected);
            let (e, weight) = (w.e, w.weight);
            let kind = if expected {
                StretchKind::Expected { need_collision: collide, e, weight }
            } else {
                StretchKind::FreePath { estimator, e }
            };
            if let Some(walk) = field.exact_stretch(ray, seg.t0, seg.t1, kind, sampler) {
                work.exact_steps += walk.voxel_steps;
                w.cross_exactly(&walk, collide);
                if w.ended(expected, need_collision) {
                    break;
                }
                continue;
            }
        }
        let emits = seg.bounds.source > 0.0;
        let mut s = seg.t0;
        loop {
            // The next tentative point, or the stretch's end
            let next = if mu_bar > 0.0 { s + w.e / mu_bar } else { f64::INFINITY };
            let end = next.min(seg.t1);
            if integrates
                && emits
                && end > s
                && (w.event == DistanceSample::Escaped || expected)
                && w.weight > 0.0
            {
                let x = s + sampler.next_f64() * (end - s);
                let le = if picks_emission {
                    field.emission_picked(ray.at(x), sampler.next_f64())
                } else {
                    field.emission(ray.at(x))
                };
                add(&mut w.f, le, (end - s) * w.weight);
            }
            if next >= seg.t1 {
                // Carry the unused part of the exponential into the next stretch
                if mu_bar > 0.0 {
                    w.e -= (seg.t1 - s) * mu_bar;
                }
                break;
            }
            // A tentative collision at `next`
            w.e = sample_exponential(sampler.next_f64());
            s = next;
            work.tentative_points += 1;
            let density = density_of(field, picks, ray.at(next), sampler);
            let ratio = (medium.mu_t(density) / mu_bar).clamp(0.0, 1.0);
            if w.event == DistanceSample::Escaped
                && (need_collision || !expected)
                && sampler.next_f64() < ratio
            {
                // The exact values (a picked density served the acceptance only): the
                // collision's law is the exact field's, and so must its record and score
                // be. Only the point estimator scores here; the others need only the
                // albedo factor, to carry the path on
                w.event = real_collision(field, medium, estimator, ray, next, &mut w.f);
                w.od_to_collision = f64::NAN; // not tracked by null collisions
            }
            if expected {
                w.weight = ratio_weight(w.weight, ratio, sampler);
            }
            if w.ended(expected, need_collision) {
                done = true;
                break;
            }
        }
        if done {
            break;
        }
    }
    w.result(expected, segments, work)
}

/// The record of a real collision at `ray.at(t)`, read from the exact field (a picked
/// density served the acceptance only: the collision's law is the exact field's, and so
/// must its record and score be). Only the point estimator scores here, adding to `f`;
/// the others need only the albedo factor, to carry the path on.
#[inline]
fn real_collision(
    field: &impl PointField,
    medium: &Medium,
    estimator: Estimator,
    ray: &Ray,
    t: f64,
    f: &mut [f64; 3],
) -> DistanceSample {
    let x = ray.at(t);
    if estimator == Estimator::Point {
        let p = field.sample(x, true);
        add(f, p.emission, 1.0 / medium.mu_t(p.density));
        DistanceSample::Collided {
            t,
            density: p.density,
            source: p.source,
            albedo: p.albedo,
            classes: None,
        }
    } else {
        DistanceSample::Collided {
            t,
            density: f32::NAN,
            source: f32::NAN,
            albedo: field.albedo(x),
            classes: None,
        }
    }
}

/// Ratio tracking's weight after a tentative point of acceptance `ratio`, with Russian
/// roulette below [`RAY_MARCH_ROULETTE_THRESHOLD`] (survivors carry the threshold).
#[inline]
fn ratio_weight(weight: f64, ratio: f64, sampler: &mut Sampler) -> f64 {
    let weight = weight * (1.0 - ratio);
    if weight < RAY_MARCH_ROULETTE_THRESHOLD {
        let q = weight / RAY_MARCH_ROULETTE_THRESHOLD;
        if sampler.next_f64() >= q {
            return 0.0;
        }
        return RAY_MARCH_ROULETTE_THRESHOLD;
    }
    weight
}

/// Ratio-tracking estimate of `τ(0, t_max)` along `ray` (module docs); stops early once
/// it is 0.
pub fn ratio_transmittance(
    majorants: &MajorantGrid,
    field: &impl PointField,
    medium: &Medium,
    ray: &Ray,
    t_max: f64,
    sampler: &mut Sampler,
) -> ShadowResult {
    let picks = field.picks();
    let mut r = ShadowResult {
        transmittance: 1.0,
        voxel_steps: 0,
        tentative_points: 0,
        channels: [1.0; 3],
    };
    for seg in majorants.segments(ray, 0.0, t_max) {
        r.voxel_steps += 1;
        let mu_bar = medium.mu_t(seg.bounds.density);
        if mu_bar <= 0.0 {
            continue;
        }
        let mut s = seg.t0;
        loop {
            s += sample_exponential(sampler.next_f64()) / mu_bar;
            if s >= seg.t1 {
                break;
            }
            r.tentative_points += 1;
            let ratio = (medium.mu_t(density_of(field, picks, ray.at(s), sampler)) / mu_bar)
                .clamp(0.0, 1.0);
            r.transmittance = ratio_weight(r.transmittance, ratio, sampler);
            if r.transmittance == 0.0 {
                return r;
            }
        }
    }
    r
}
