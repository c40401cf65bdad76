//! The tracker a sample traces with, chosen once per sample and per kind of segment:
//! regular tracking through a still volume (exact free paths and transmittance, METHOD
//! §3 and §12), or null collisions (METHOD §13) under the majorants of
//! `volume::majorant`, through a still volume or through a moving one at the sample's
//! shutter time (`volume::motion`, `medium::null_tracking`).
//!
//! **Which segments track how** ([`Tracking`], `--tracking`): regular tracking walks
//! every cell a segment crosses and integrates each in closed form; null collisions look
//! the field up only at tentative points (`Exp(μ̄)` apart) and estimate the emission
//! integral from one point per stretch between them. On a camera ray the exact walk pays
//! for itself: its emission *is* the image of an emission–absorption render, and Sobol
//! points stratify it. After a scattering event a segment's emission is one sample of the
//! in-scattered radiance, far noisier than the integral's own estimate, and in thin media
//! it crosses the whole volume: there the cheap tentative points win (`Tracking::Mixed`,
//! the default where it applies; measured in docs/BENCHMARKS.md, "Tracking: null collisions after scattering").
//! Shadow rays (NEE, external lights) of a still volume are exact under every tracking:
//! they only sum optical depth, and an exact `τ` adds no noise to the light it carries.
//! A moving volume is tracked by null collisions everywhere (no closed form exists).

use super::buffered::{Ask, BufferedPoints, Request};
use crate::medium::chromatic::track_chromatic;
use crate::medium::emission::EmissionMemo;
use crate::medium::forced::SplitFirsts;
use crate::medium::null_tracking::{null_track, ratio_transmittance, PointField, PointSample};
use crate::medium::tracking::{
    optical_depth, track_split, walk_stretch, OpticalDepth, StretchKind, StretchWalk,
};
use crate::medium::{track, Collision, Estimator, Extinction, Medium, ShadowResult, TrackResult};
use plume_core::sampling::Sampler;
pub use plume_scene::sets::{PointLookup, Tracking};
use plume_volume::field::{Field, Ray};
use plume_volume::majorant::MajorantGrid;
use plume_volume::motion::Motion;

/// How a sample tracks rays.
pub enum Tracker<'a, F: Field> {
    /// Regular tracking of a still volume.
    Regular(&'a F),
    /// Null collisions through a still volume.
    Null {
        /// The volume.
        field: &'a F,
        /// Its majorants (no displacement).
        majorants: &'a MajorantGrid,
        /// How tentative points read the volume.
        lookup: PointLookup,
    },
    /// Null collisions through the volume advected to `time` (seconds).
    Moving {
        /// The frame's volume.
        field: &'a F,
        /// Velocity, shutter, majorants.
        motion: &'a Motion,
        /// The sample's time.
        time: f64,
        /// How tentative points read the volume.
        lookup: PointLookup,
    },
    /// Null collisions through a still volume whose values are served from what earlier
    /// rounds read for this path (`integrator::deferred`): a segment whose values are
    /// not all there is recorded instead of walked.
    Deferred {
        /// The volume's majorants.
        majorants: &'a MajorantGrid,
        /// The values read so far, and what the path still needs.
        points: &'a BufferedPoints<'a>,
    },
}

impl<F: Field> Clone for Tracker<'_, F> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<F: Field> Copy for Tracker<'_, F> {}

/// The field as null collisions read it (`medium::null_tracking`), at the sample's time:
/// world point `p` reads the frame's field at `motion.source_point(p, time)`, or at `p`
/// in a still volume. Emission goes through a memo of the corners' `L_e` (consecutive
/// points along a ray share voxels).
pub(super) struct Points<'a, F: Field> {
    field: &'a F,
    medium: &'a Medium,
    motion: Option<(&'a Motion, f64)>,
    memo: EmissionMemo<'a>,
    /// Tentative points read one voxel picked by its weight ([`PointLookup::picks_density`]
    /// on a field whose points combine several voxels).
    picks: bool,
    /// Emission points too ([`PointLookup::picks_emission`]).
    picks_emission: bool,
}

impl<'a, F: Field> Points<'a, F> {
    pub(super) fn new(
        field: &'a F,
        medium: &'a Medium,
        motion: Option<(&'a Motion, f64)>,
        lookup: PointLookup,
    ) -> Self {
        let fewer = field.picks_fewer();
        let (picks, picks_emission) =
            (fewer && lookup.picks_density(), fewer && lookup.picks_emission());
        let memo = EmissionMemo::new(&medium.emission);
        Points { field, medium, motion, memo, picks, picks_emission }
    }

    #[inline]
    fn source_point(&self, p: glam::DVec3) -> glam::DVec3 {
        self.motion.map_or(p, |(motion, time)| motion.source_point(p, time))
    }
}

impl<F: Field> Points<'_, F> {
    /// [`PointField::emission`] for the fill of deferred paths (`integrator::deferred`):
    /// the same value, bit for bit, through an instance of the reconstruction of its own,
    /// so that the walk's instance keeps its single caller: with the fill calling
    /// `emission` too, the in-core walk, where nothing is deferred, runs more instructions.
    #[inline(never)]
    pub(super) fn emission_for_fill(&self, p: glam::DVec3) -> [f64; 3] {
        self.field.reconstruct(self.source_point(p), &|d, s| self.memo.le(d, s)).emission
    }
}

impl<F: Field> PointField for Points<'_, F> {
    #[inline]
    fn density(&self, p: glam::DVec3) -> f32 {
        self.field.values_at(self.source_point(p)).density
    }

    #[inline]
    fn emission(&self, p: glam::DVec3) -> [f64; 3] {
        self.field.reconstruct(self.source_point(p), &|d, s| self.memo.le(d, s)).emission
    }

    #[inline]
    fn picks(&self) -> bool {
        self.picks
    }

    #[inline]
    fn density_picked(&self, p: glam::DVec3, u: f64) -> f32 {
        self.field.values_picked(self.source_point(p), u).density
    }

    #[inline]
    fn picks_emission(&self) -> bool {
        self.picks_emission
    }

    /// The picked corner's `le`: `E_u[le(ρ_c, s_c)] = Σ_c w_c le(ρ_c, s_c)`, the
    /// trilinear field's per-voxel emission.
    #[inline]
    fn emission_picked(&self, p: glam::DVec3, u: f64) -> [f64; 3] {
        let v = self.field.values_picked(self.source_point(p), u);
        self.memo.le(v.density, v.source).to_f64()
    }

    #[inline]
    fn albedo(&self, p: glam::DVec3) -> f32 {
        self.field.albedo_at(self.source_point(p))
    }

    #[inline]
    fn walks_exactly(&self) -> bool {
        self.motion.is_none()
    }

    fn exact_stretch(
        &self,
        ray: &Ray,
        t0: f64,
        t1: f64,
        kind: StretchKind,
        sampler: &mut Sampler,
    ) -> Option<StretchWalk> {
        self.walks_exactly()
            .then(|| walk_stretch(self.field, self.medium, ray, t0, t1, kind, sampler))
    }

    fn sample(&self, p: glam::DVec3, emission: bool) -> PointSample {
        let q = self.source_point(p);
        let albedo = self.field.albedo_at(q);
        if emission {
            // The source comes with the reconstruction: a trilinear field gathers its 8
            // corners once (reading them again for `values_at` would cost a visible part of
            // a render's instructions)
            let v = self.field.reconstruct(q, &|d, s| self.memo.le(d, s));
            PointSample { density: v.density, source: v.source, emission: v.emission, albedo }
        } else {
            // The same gather without the corners' `L_e`, which only the point estimator uses
            let v = self.field.values_at(q);
            PointSample { density: v.density, source: v.source, emission: [0.0; 3], albedo }
        }
    }
}

/// Most points a [`Recorder`] keeps for a read-ahead: at most a few megabytes of pages
/// asked for per segment.
const MAX_READ_AHEAD_POINTS: usize = 512;

/// Out of core, a scattered segment asks for its pages before it reads any (one batch of
/// reads the disk can serve in parallel, instead of one fault at a time): it is first
/// tracked with a copy of its sampler through this field, which records where it is read
/// and holds nothing. Null collisions draw their numbers independently of the values they
/// read up to the first real collision (tentative distances, acceptance draws and
/// emission points all come from the majorants and the stream), so the recorded points
/// are the real walk's up to its collision, then those of the rest of the segment.
/// Ray-march's ratio-tracking roulette does depend on the values: there the hint is
/// approximate. A hint either way: nothing recorded changes a result.
///
/// Deferred paths (`integrator::deferred`) use the same walk to learn which values a
/// segment will ask for, each with what it asks ([`Ask`]) and the number a picked lookup
/// draws.
pub(super) struct Recorder<'a> {
    requests: std::cell::RefCell<Vec<Request>>,
    /// Most requests kept.
    cap: usize,
    /// As the real walk's field: the walk draws a number per read when it picks.
    picks: bool,
    picks_emission: bool,
    /// The field of the walk it mirrors where that walk tracks dense stretches exactly:
    /// the recording walk tracks them the same way (reading their voxels now), so that
    /// its tentative points after them are the real walk's.
    exact: Option<&'a dyn PointField>,
}

impl<'a> Recorder<'a> {
    /// A recorder that draws what the walk through `points` draws, keeping at most `cap`
    /// requests.
    fn mirroring<F: Field>(points: &'a Points<'_, F>, cap: usize) -> Recorder<'a> {
        let recorder = Recorder::with_picks(points.picks, points.picks_emission, cap);
        let exact = points.walks_exactly().then_some(points as &dyn PointField);
        Recorder { exact, ..recorder }
    }

    /// A recorder of a walk whose field picks as said.
    pub(super) fn with_picks(picks: bool, picks_emission: bool, cap: usize) -> Recorder<'a> {
        let requests = std::cell::RefCell::default();
        Recorder { requests, cap, picks, picks_emission, exact: None }
    }

    fn record(&self, p: glam::DVec3, ask: Ask, u: f64) {
        let mut requests = self.requests.borrow_mut();
        if requests.len() < self.cap {
            requests.push(Request { p, ask, u });
        }
    }

    /// What the walk asked for, in order.
    pub(super) fn into_requests(self) -> Vec<Request> {
        self.requests.into_inner()
    }
}

impl PointField for Recorder<'_> {
    fn picks(&self) -> bool {
        self.picks
    }
    fn picks_emission(&self) -> bool {
        self.picks_emission
    }
    fn density(&self, p: glam::DVec3) -> f32 {
        self.record(p, Ask::Density, 0.0);
        0.0
    }
    fn density_picked(&self, p: glam::DVec3, u: f64) -> f32 {
        self.record(p, Ask::DensityPicked, u);
        0.0
    }
    fn emission(&self, p: glam::DVec3) -> [f64; 3] {
        self.record(p, Ask::Emission, 0.0);
        [0.0; 3]
    }
    fn emission_picked(&self, p: glam::DVec3, u: f64) -> [f64; 3] {
        self.record(p, Ask::EmissionPicked, u);
        [0.0; 3]
    }
    fn albedo(&self, p: glam::DVec3) -> f32 {
        self.record(p, Ask::Albedo, 0.0);
        1.0
    }
    fn sample(&self, p: glam::DVec3, _emission: bool) -> PointSample {
        self.record(p, Ask::Albedo, 0.0);
        PointSample::default()
    }
    fn walks_exactly(&self) -> bool {
        self.exact.is_some()
    }
    fn exact_stretch(
        &self,
        ray: &Ray,
        t0: f64,
        t1: f64,
        kind: StretchKind,
        sampler: &mut Sampler,
    ) -> Option<StretchWalk> {
        self.exact?.exact_stretch(ray, t0, t1, kind, sampler)
    }
}

/// [`Tracker::track`] of a deferred path's segment: walked on the values gathered for it
/// when the recording walk (the same numbers) finds every one it lists there; otherwise
/// recorded, not walked, and the sampler moves on as the recording drew, so that the
/// path's next segment is recorded as if this one had no real collision, which in thin
/// media it mostly has not (a guess, checked when the path is rerun). Kept out of
/// [`Tracker::track`], whose other arms the compiler then inlines.
// Each argument is a distinct input of the walk (randomness stays an argument: STYLE §3)
#[allow(clippy::too_many_arguments)]
#[inline(never)]
fn track_deferred(
    majorants: &MajorantGrid,
    points: &BufferedPoints<'_>,
    medium: &Medium,
    ray: &Ray,
    t_max: f64,
    estimator: Estimator,
    need_collision: bool,
    u: f64,
    sampler: &mut Sampler,
) -> TrackResult {
    let recorder = Recorder::with_picks(points.picks(), points.picks_emission(), usize::MAX);
    let mut ahead = sampler.clone();
    null_track(majorants, &recorder, medium, ray, t_max, estimator, need_collision, u, &mut ahead);
    if points.has_all(&recorder.into_requests()) {
        null_track(majorants, points, medium, ray, t_max, estimator, need_collision, u, sampler)
    } else {
        *sampler = ahead;
        TrackResult::nothing()
    }
}

impl<F: Field> Tracker<'_, F> {
    /// [`Tracker::track`] for the camera segment of `paths` split paths: where regular
    /// tracking forces the collision, their first vertices are appended to `firsts`
    /// (`medium::tracking::track_split`); null collisions draw the analog collision,
    /// which the paths share, and leave `firsts` as it is.
    // Each argument is a distinct input of the walk (randomness stays an argument: STYLE §3)
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn track_split(
        &self,
        medium: &Medium,
        ray: &Ray,
        t_max: f64,
        estimator: Estimator,
        collision: Collision,
        u: f64,
        sampler: &mut Sampler,
        split: SplitFirsts<'_>,
    ) -> TrackResult {
        match (*self, medium.extinction) {
            (Tracker::Regular(field), Extinction::Grey) => {
                track_split(field, medium, ray, t_max, estimator, collision, u, sampler, split)
            }
            _ => self.track(medium, ray, t_max, estimator, collision, u, sampler),
        }
    }

    /// A free path and the estimator's emission along `ray` over `[0, t_max]`
    /// ([`track`] or [`null_track`]).
    // Each argument is a distinct input of the walk (randomness stays an argument: STYLE §3)
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub fn track(
        &self,
        medium: &Medium,
        ray: &Ray,
        t_max: f64,
        estimator: Estimator,
        collision: Collision,
        u: f64,
        sampler: &mut Sampler,
    ) -> TrackResult {
        // Null collisions draw every collision as the analog one (`medium::forced`)
        let need_collision = collision.needed();
        match *self {
            Tracker::Regular(field) => match &medium.extinction {
                Extinction::Grey => {
                    track(field, medium, ray, t_max, estimator, collision, u, sampler)
                }
                Extinction::Chromatic(chromatic) => track_chromatic(
                    field, medium, chromatic, ray, t_max, estimator, collision, u, sampler,
                ),
            },
            Tracker::Null { field, majorants, lookup } => {
                let points = Points::new(field, medium, None, lookup);
                if let Some(volume) = field.voxels().filter(|v| v.reading_ahead()) {
                    let recorder = Recorder::mirroring(&points, MAX_READ_AHEAD_POINTS);
                    null_track(
                        majorants,
                        &recorder,
                        medium,
                        ray,
                        t_max,
                        estimator,
                        need_collision,
                        u,
                        &mut sampler.clone(),
                    );
                    let points: Vec<glam::DVec3> =
                        recorder.into_requests().iter().map(|r| r.p).collect();
                    volume.read_ahead_points(&points);
                }
                null_track(
                    majorants,
                    &points,
                    medium,
                    ray,
                    t_max,
                    estimator,
                    need_collision,
                    u,
                    sampler,
                )
            }
            Tracker::Deferred { majorants, points } => track_deferred(
                majorants,
                points,
                medium,
                ray,
                t_max,
                estimator,
                need_collision,
                u,
                sampler,
            ),
            Tracker::Moving { field, motion, time, lookup } => null_track(
                &motion.majorants,
                &Points::new(field, medium, Some((motion, time)), lookup),
                medium,
                ray,
                t_max,
                estimator,
                need_collision,
                u,
                sampler,
            ),
        }
    }

    /// Transmittance along `ray` over `[0, t_max]` and what the walk cost: exact in a
    /// still volume (regular tracking, stopped once the optical depth passes 745, where
    /// `e^{−OD}` is 0), ratio tracking's unbiased estimate in a moving one.
    #[inline]
    pub fn transmittance(
        &self,
        medium: &Medium,
        ray: &Ray,
        t_max: f64,
        sampler: &mut Sampler,
    ) -> ShadowResult {
        match *self {
            // A still volume's shadow rays stay exact under null collisions too: they only
            // sum optical depth (no emission cubics), and an exact τ adds no noise to the
            // light it carries
            Tracker::Regular(field) | Tracker::Null { field, .. } => {
                if let Some(volume) = field.voxels().filter(|v| v.reading_ahead()) {
                    volume.read_ahead_ray(ray, t_max);
                }
                let OpticalDepth { optical_depth: od, voxel_steps } =
                    optical_depth(field, medium, ray, t_max, medium.extinction.od_stop());
                let (transmittance, channels) = match &medium.extinction {
                    Extinction::Grey => ((-od).exp(), [1.0; 3]),
                    Extinction::Chromatic(chromatic) => chromatic.transmittance_ratios(od, 1.0),
                };
                ShadowResult { transmittance, voxel_steps, tentative_points: 0, channels }
            }
            Tracker::Deferred { points, .. } => {
                // Not deferred: shadow rays are exact walks (light sampling that needs
                // them keeps its paths out of deferral); the path is rerun directly
                points.give_up();
                ShadowResult {
                    transmittance: 0.0,
                    voxel_steps: 0,
                    tentative_points: 0,
                    channels: [1.0; 3],
                }
            }
            Tracker::Moving { field, motion, time, lookup } => ratio_transmittance(
                &motion.majorants,
                &Points::new(field, medium, Some((motion, time)), lookup),
                medium,
                ray,
                t_max,
                sampler,
            ),
        }
    }
}

#[cfg(test)]
mod tests;
