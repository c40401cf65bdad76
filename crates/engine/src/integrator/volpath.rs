//! The volumetric path integrator: forward (phase-sampled) paths with line-integrated
//! emission on every segment, optional next event estimation (classic NEE or FNEE), MIS,
//! Russian roulette. METHOD.md §5–8.
//!
//! Per segment leaving `x` along `ω` with throughput `β` (per channel: a coloured albedo,
//! and in a chromatic medium the hero channel's weights, `medium::extinction`):
//! 1. `L += β · w_fwd(ω) · F` on every segment, before roulette;
//! 2. at a collision, `β_c ← β_c · a_c` (times the walk's `channels.collision[c]`, 1 in a
//!    grey medium); light sampling at the collision point; roulette
//!    with `q = min(1, max_c β_c / t)` ([`ROULETTE_THRESHOLD`] `t`); HG sampling of the
//!    next direction (`f/p = 1`).
//!
//! No vertex emission is ever added: with line integration it would double count.
//!
//! **Splitting** (`--split N`): a sample's camera segment is walked once, and `N` paths
//! leave its collision, each with throughput `1/N` and numbers of its own
//! ([`Sampler::split`]: the `N · spp` paths of a pixel are one Sobol sequence). Any `N`
//! fixed before the paths are drawn keeps the estimate unbiased: it is the mean of `N`
//! estimates of the same in-scattered radiance. Roulette compares `β` with `1/N`, not
//! with 1, or it would undo the split at the first vertex. In thin media the camera walk,
//! which integrates the emission seen directly with almost no variance, is most of a
//! sample's cost while the scattered light carries almost all of its variance, so `N = 8`
//! paths a camera walk (the default) are more efficient than one, in thin and dense smoke
//! alike (docs/BENCHMARKS.md, "Splitting at the camera collision"). At about one sample per pixel fewer paths win,
//! since the camera collision is forced (`--split 4`; docs/BENCHMARKS.md, "Forced camera
//! collisions").
//!
//! **Forced camera collisions** (`medium::forced`, `--camera-collision`): where paths
//! scatter the camera segment is ray-marched by default, and its walk forces the
//! collision: with probability `min(1, K W)` (`W` the analog collision's probability) at the
//! analog law given a collision, weighted `W/q`, which the split paths' `β` carries. In thin
//! smoke few camera rays collide, so at a few samples per pixel this, not the split, is
//! what lowers the scattered light's noise (docs/BENCHMARKS.md, "Forced camera
//! collisions").
//! The split paths of a forced collision start apart, path `k` in stratum `k` of the
//! collision law (`medium::forced`, "Split paths start apart"); an analog or null-tracked
//! camera collision is shared by its paths.
//!
//! **Tracking** (`integrator::tracker`, `--tracking`): the camera segment and the
//! segments after a scattering event each get their tracker once per sample, regular or
//! null collisions; every estimator above is unbiased under either, so the split changes
//! cost and noise only.
//!
//! **Motion blur** (`volume::motion`): each sample draws its shutter time and tracks by
//! null collisions at that time (`integrator::tracker`). FNEE keeps the proxy built from
//! the frame's data: it only chooses directions, and wherever it gives a direction of the
//! moved emission no density, phase sampling carries that emission with full weight
//! (`w(p_ph, 0) = 1`), so the estimate stays unbiased. Classic NEE draws *points* from the
//! frame's emitters, which the motion moves off its support: refused with motion blur.
//!
//! **Light sampling and MIS weights** (balance `k = 1` or power `k = 2`,
//! `w(a, b) = aᵏ/(aᵏ + bᵏ)`; the volume is the only sampled light, `P_vol = 1`):
//! - `none`: `w_fwd = 1`.
//! - `fnee`: direction `ω ~ p_σ` from the proxy, then a free path along `ω` with the same
//!   estimator F: `L += β f F w(p_σ, p_ph) / p_σ`; the forward segment gets
//!   `w(p_ph, p_σ)`. Both techniques draw `ω` and then the *same* free-path law, so the
//!   distance pdfs cancel and MIS is in solid angle (METHOD §8). The FNEE segment is
//!   terminal. Camera segments have no partner (`w = 1`).
//! - `nee` with the point estimator: `y ~ p_V` (volume measure), exact shadow
//!   transmittance, `L += β f τ L_e(y) w(p_V, p_fwd) / (p_V r²)` with the forward
//!   density of the same point `p_fwd = p_ph μ_t(y) τ / r²`; a forward collision at `y′`
//!   is weighted `w(p_fwd(y′), p_V(y′))`, with `τ(x, y′) = e^{−E}` known exactly.
//! - `nee` with line, ray-march or blend: classic NEE cannot create the no-collision
//!   paths that line integration scores, so there is no MIS partner (the paper's
//!   conclusion table). The one unbiased split without MIS is used: NEE carries all
//!   in-scattered emission at full weight, and forward segments *after a scattering
//!   vertex* carry none (`w_fwd = 0`); camera segments keep full weight. Summing both at
//!   full weight would count in-scattered emission twice.

use super::aov::{Aovs, Component, NoAovs};
use super::buffered::BufferedPoints;
use super::groups;
use super::tracker::Tracker;
use crate::medium::forced::{Forced, SplitFirsts};
use crate::medium::{Collision, DistanceSample, Estimator, Extinction};
use plume_core::sampling::{Dim, Sampler};
use plume_scene::SplitBy;
use plume_scene::{LightSampling, MisHeuristic};
use plume_scene::{PointLookup, Tracking};
use plume_volume::field::{Field, Ray};

use super::counters::Counters;
use super::path::{contribute, Bounces, NoBounces, PathState, Vertex};
use super::scene::Scene;
use super::trace::{NoTrace, Trace};

/// Roulette plays only once a path's throughput `β` falls below this part of its start
/// (`1`, or `1/N` for split paths), with survival `β/(t·start)`; survivors carry `t·start`.
///
/// In an emissive medium every segment after a collision collects emission, so a path
/// ended early loses light it would surely have gathered: with `t = 1` (survival `β`, as
/// pbrt does) an albedo of 0.8 ends a fifth of the paths at their first vertex. A
/// threshold below 1 is more efficient (1/(relMSE · CPU s)) than `t = 1` on dense and thin
/// smoke, split or not, and no roulette at all is slower for the same noise.
pub const ROULETTE_THRESHOLD: f64 = 0.3;

/// Where the split paths of one camera sample start: the collision's vertex, how many
/// paths leave it, and, from a forced collision, each path's own first vertex.
#[derive(Clone, Copy)]
struct SplitStart<'f> {
    vertex: Vertex,
    paths: u32,
    firsts: &'f [Forced],
}

/// The path integrator and its settings.
#[derive(Clone, Copy, Debug)]
pub struct Integrator {
    /// Emission estimator on every free-path segment (but the camera segment's, when
    /// `camera_estimator` is given).
    pub estimator: Estimator,
    /// Emission estimator on the camera segment (`None`: `estimator`). The camera segment
    /// has no light-sampling partner, so any estimator serves it; the expected-value one
    /// (ray-march) makes its emission exact along each ray, which `--denoise` then keeps
    /// out of the filter (`crate::denoise`).
    pub camera_estimator: Option<Estimator>,
    /// Next event technique.
    pub light_sampling: LightSampling,
    /// MIS heuristic.
    pub mis: MisHeuristic,
    /// Largest number of scattering events (0: emission–absorption only).
    pub max_depth: u32,
    /// How segments are tracked (`integrator::tracker`).
    pub tracking: Tracking,
    /// Paths traced from a camera segment's collision, each carrying `1/split` (1: one
    /// path, as the paper has it; the module docs).
    pub split: u32,
    /// Whether `split` holds at every collision or is the mean of per-pixel counts from a
    /// pilot render (`integrator::split_map`; the renderer sets `split` per pixel).
    pub split_by: SplitBy,
    /// How the camera segment draws its collision when paths scatter: forced collisions
    /// (`medium::forced`) need the expected-value walk (`camera_estimator` ray-march) and
    /// regular tracking, and are drawn as analog ones elsewhere.
    pub camera_collision: Collision,
    /// How null collisions read a trilinear field at tentative points (exact, or one
    /// voxel picked by its weight; `integrator::tracker`).
    pub point_lookup: PointLookup,
}

impl Integrator {
    /// The camera segment's emission estimator.
    #[inline]
    #[must_use]
    pub fn camera_estimator(&self) -> Estimator {
        self.camera_estimator.unwrap_or(self.estimator)
    }

    /// The estimators as stats and the summary line name them: `Line`, or `Line, camera
    /// RayMarch` when the camera segment has its own.
    #[must_use]
    pub fn estimator_name(&self) -> String {
        match self.camera_estimator() {
            camera if camera == self.estimator => format!("{:?}", self.estimator),
            camera => format!("{:?}, camera {camera:?}", self.estimator),
        }
    }

    /// Emission–absorption only: no scattering, no light sampling.
    #[must_use]
    pub fn emission_only(estimator: Estimator) -> Integrator {
        Integrator {
            estimator,
            camera_estimator: None,
            light_sampling: LightSampling::None,
            mis: MisHeuristic::Power,
            max_depth: 0,
            tracking: Tracking::Regular,
            split: 1,
            split_by: SplitBy::Uniform,
            camera_collision: Collision::Analog,
            point_lookup: PointLookup::Exact,
        }
    }

    /// Radiance `[r, g, b]` and alpha along a camera ray.
    pub fn li<F: Field, T: Trace>(
        &self,
        scene: &Scene<F>,
        camera_ray: &Ray,
        sampler: &mut Sampler,
        c: &mut Counters,
        trace: &mut T,
    ) -> [f64; 4] {
        self.li_aovs(
            scene,
            camera_ray,
            None,
            PathState { sampler, counters: c, trace, aovs: &mut NoAovs },
        )
    }

    /// [`Integrator::li`] at shutter time `time` (seconds; drawn here when the scene moves
    /// and it is `None`), also handing every contribution to `aovs` by its component
    /// (`integrator::aov`). With `None` and [`NoAovs`] this is `li`.
    pub fn li_aovs<F: Field, T: Trace, A: Aovs>(
        &self,
        scene: &Scene<F>,
        camera_ray: &Ray,
        time: Option<f64>,
        state: PathState<'_, T, A>,
    ) -> [f64; 4] {
        self.li_camera(scene, camera_ray, time, state, None)
    }

    /// [`Integrator::li`] up to the camera segment's collision: the scattered paths that
    /// leave it are appended to `paths`, each with its sampler, for
    /// `integrator::deferred` to trace (only where [`Integrator::defers`] the scene's
    /// paths). The radiance returned is the camera segment's; each path adds to it.
    pub(crate) fn li_deferring<F: Field>(
        &self,
        scene: &Scene<F>,
        camera_ray: &Ray,
        time: Option<f64>,
        state: PathState<'_, NoTrace, NoAovs>,
        paths: &mut Vec<(Vertex, Sampler)>,
    ) -> [f64; 4] {
        self.li_camera(scene, camera_ray, time, state, Some(paths))
    }

    /// Whether the paths of `scene` can be deferred (`integrator::deferred`): they
    /// scatter, every segment after a scattering event is null-tracked through a still
    /// volume, and nothing on them walks the volume exactly (no classic NEE, no external
    /// lights) or scores a real collision's emission (not the point estimator).
    #[must_use]
    pub(crate) fn defers<F: Field>(&self, scene: &Scene<F>) -> bool {
        let scatters = scene.medium.albedo.max_component() > 0.0 && self.max_depth > 0;
        let null_after = matches!(
            self.still_tracker(scene, self.tracking.null_after_scattering(), self.point_lookup),
            Tracker::Null { .. }
        );
        scatters
            && null_after
            && scene.motion.is_none()
            && scene.lights.external.is_none()
            && self.estimator != Estimator::Point
            && matches!(self.light_sampling, LightSampling::Fnee | LightSampling::None)
    }

    /// A deferred path (one that [`Integrator::li_deferring`] handed out) traced with the
    /// values in `points`, adding to `l`. Whether it got every value it asked for is
    /// `points`' to say; where it did not, `l` and `c` hold nothing meaningful.
    pub(crate) fn deferred_path<F: Field>(
        &self,
        scene: &Scene<F>,
        points: &BufferedPoints<'_>,
        vertex: Vertex,
        mut state: PathState<'_, NoTrace, NoAovs>,
        bounces: &mut impl Bounces,
        l: &mut [f64; 3],
    ) {
        let Some(majorants) = scene.majorants.as_ref() else {
            points.give_up();
            return;
        };
        let tracker = Tracker::Deferred { majorants, points };
        self.scattered_path(scene, &tracker, vertex, &mut state, bounces, l);
    }

    /// A deferred path traced directly, reading the volume as [`Integrator::li`] would.
    pub(crate) fn direct_path<F: Field>(
        &self,
        scene: &Scene<F>,
        vertex: Vertex,
        mut state: PathState<'_, NoTrace, NoAovs>,
        l: &mut [f64; 3],
    ) {
        // Deferred paths are of a still volume (`defers`)
        let tracker =
            self.still_tracker(scene, self.tracking.null_after_scattering(), self.point_lookup);
        self.scattered_path(scene, &tracker, vertex, &mut state, &mut NoBounces, l);
    }

    /// [`Integrator::li_aovs`], or with `defer`, up to the camera segment's collision
    /// ([`Integrator::li_deferring`]).
    fn li_camera<F: Field, T: Trace, A: Aovs>(
        &self,
        scene: &Scene<F>,
        camera_ray: &Ray,
        time: Option<f64>,
        mut state: PathState<'_, T, A>,
        defer: Option<&mut Vec<(Vertex, Sampler)>>,
    ) -> [f64; 4] {
        let m = &scene.medium;
        let mut l = [0.0f64; 3];
        let scatters = m.albedo.max_component() > 0.0 && self.max_depth > 0;
        let external = scene.lights.external.as_ref();
        let (camera, tracker) = self.trackers(scene, time, state.sampler);
        // The camera segment ends at the first sphere light it hits (they are opaque)
        let hit = external.and_then(|e| e.hit(camera_ray));
        let t_max = hit.map_or(f64::INFINITY, |(t, _)| t);
        let u = state.sampler.get_1d(Dim::FreePath);
        // The depth layer wants the camera ray's first collision (ray-march draws it
        // with the same number; nothing else changes). A forced collision has the analog
        // one's law given that one happens, so the layer's mean depth is the same.
        let collision = match (scatters, A::ON) {
            (true, _) => self.camera_collision,
            (false, true) => Collision::Analog,
            (false, false) => Collision::Skip,
        };
        // Split paths from a forced collision start at vertices of their own
        // (`medium::forced`); otherwise they share the walk's collision
        let paths = if scatters { self.split.max(1) } else { 1 };
        let mut firsts = Vec::new();
        let replay = groups::replay::<F, A>(scene, state.sampler);
        let walk = |tracker: &Tracker<'_, F>, sampler: &mut Sampler, firsts: &mut Vec<_>| {
            let estimator = self.camera_estimator();
            if paths > 1 {
                let split = SplitFirsts { paths, firsts };
                tracker.track_split(m, camera_ray, t_max, estimator, collision, u, sampler, split)
            } else {
                tracker.track(m, camera_ray, t_max, estimator, collision, u, sampler)
            }
        };
        let r = walk(&camera, state.sampler, &mut firsts);
        state.counters.add_track(&r);
        let e = r.emission;
        groups::contribute_volume(
            scene,
            &mut l,
            state.aovs,
            Component::Emission,
            [1.0; 3],
            e,
            |v| {
                let mut sampler =
                    replay.clone().expect("invariant: views are walked with a replay");
                walk(&Tracker::Regular(v.camera_view()), &mut sampler, &mut Vec::new()).emission
            },
        );
        state.trace.event(|| {
            format!(
                "segment depth 0: origin {:?} dir {:?} -> {:?} (weight {}), F {:?}, w_fwd 1, beta 1, tau {}",
                camera_ray.origin, camera_ray.direction, r.event, r.collision_weight, r.emission, r.transmittance
            )
        });
        let alpha = 1.0 - r.transmittance;
        if let (true, DistanceSample::Collided { t, .. }) = (A::ON, r.event) {
            state.aovs.first_collision(t);
        }
        if let Some(e) = external.filter(|e| r.transmittance != 0.0 && e.reachable()) {
            // The lights this segment reaches (no light sampling partner on camera rays)
            e.arriving(camera_ray, hit.map(|(_, i)| i), None, self.mis, |i, w, radiance| {
                contribute(
                    &mut l,
                    state.aovs,
                    Component::Light(e.group(i)),
                    r.channels.transmittance.map(|c| r.transmittance * w * c),
                    radiance,
                );
                state.trace.event(|| {
                    format!("  reaches light {i}: L {radiance:?}, w {w}, tau {}", r.transmittance)
                });
            });
        }
        if let (true, DistanceSample::Collided { t, albedo, classes, .. }) = (scatters, r.event) {
            // Splitting: `split` paths share the camera walk, each of weight 1/split and
            // with numbers of its own (`Sampler::split`); from a forced collision each
            // starts at its own vertex, of the same weight
            let n = paths;
            let scale = 1.0 / f64::from(n);
            // A forced collision carries its weight W/q (`medium::forced`); roulette still
            // compares β with `scale`, so a light one is played for at its first vertex
            let vertex = Vertex {
                incoming: *camera_ray,
                t,
                albedo,
                classes,
                beta: r.channels.collision.map(|c| scale * r.collision_weight * c),
                scale,
                depth: 0,
            };
            let start = SplitStart { vertex, paths: n, firsts: &firsts };
            self.split_paths(scene, &tracker, start, &mut state, defer, &mut l);
        }
        state.trace.event(|| format!("result L {l:?} alpha {alpha}"));
        [l[0], l[1], l[2], alpha]
    }

    /// The paths that leave the camera segment's collision: `start.paths` of them, each
    /// with numbers of its own (`Sampler::split`) and, from a forced collision, its own
    /// first vertex; traced, or with `defer` handed out for `integrator::deferred`.
    fn split_paths<F: Field, T: Trace, A: Aovs>(
        &self,
        scene: &Scene<F>,
        tracker: &Tracker<'_, F>,
        start: SplitStart<'_>,
        state: &mut PathState<'_, T, A>,
        mut defer: Option<&mut Vec<(Vertex, Sampler)>>,
        l: &mut [f64; 3],
    ) {
        let SplitStart { vertex, paths: n, firsts } = start;
        for k in 0..n {
            if n > 1 {
                state.trace.event(|| format!("split path {} of {n}", k + 1));
            }
            let vertex = match firsts.get(k as usize).map(|first| first.event) {
                Some(DistanceSample::Collided { t, albedo, classes, .. }) => {
                    state.trace.event(|| format!("  first vertex at t {t}"));
                    Vertex { t, albedo, classes, ..vertex }
                }
                _ => vertex,
            };
            // One path (n = 1) draws the sample's own numbers: `split` is then a copy
            let mut path_sampler = state.sampler.split(k, n);
            if let Some(paths) = defer.as_deref_mut() {
                paths.push((vertex, path_sampler));
                continue;
            }
            self.scattered_path(
                scene,
                tracker,
                vertex,
                &mut state.with_sampler(&mut path_sampler),
                &mut NoBounces,
                l,
            );
        }
    }

    /// The trackers of one sample: for the camera segment, and for every segment after
    /// a scattering event (`integrator::tracker`). Null collisions need the scene's
    /// majorants and an estimator they serve ([`Tracking::applies`]); without either,
    /// segments track regularly.
    fn trackers<'s, F: Field>(
        &self,
        scene: &'s Scene<F>,
        time: Option<f64>,
        sampler: &mut Sampler,
    ) -> (Tracker<'s, F>, Tracker<'s, F>) {
        if let Some(motion) = &scene.motion {
            // Null collisions at this sample's shutter time
            let time = time.unwrap_or_else(|| motion.time(sampler.get_1d(Dim::Time)));
            let t = |lookup| Tracker::Moving { field: &scene.field, motion, time, lookup };
            return (t(self.point_lookup.on_camera()), t(self.point_lookup));
        }
        // The camera segment's own estimator must be one null collisions serve, too
        let camera_null = self.tracking.null_on_camera()
            && Tracking::applies(self.camera_estimator(), self.light_sampling);
        // Camera rays see the volumes visible to the camera (all but in a scene of several)
        let camera = match self.still_tracker(scene, camera_null, self.point_lookup.on_camera()) {
            Tracker::Regular(field) => Tracker::Regular(field.camera_view()),
            tracker => tracker,
        };
        (
            camera,
            self.still_tracker(scene, self.tracking.null_after_scattering(), self.point_lookup),
        )
    }

    /// The tracker of a still volume's segments: null collisions where `use_null`, the
    /// estimator and light sampling let them serve and the scene has majorants; regular
    /// tracking otherwise.
    fn still_tracker<'s, F: Field>(
        &self,
        scene: &'s Scene<F>,
        use_null: bool,
        lookup: PointLookup,
    ) -> Tracker<'s, F> {
        // A chromatic medium tracks regularly (`medium::chromatic`)
        let grey = scene.medium.extinction == Extinction::Grey;
        match &scene.majorants {
            Some(majorants)
                if use_null && grey && Tracking::applies(self.estimator, self.light_sampling) =>
            {
                Tracker::Null { field: &scene.field, majorants, lookup }
            }
            _ => Tracker::Regular(&scene.field),
        }
    }
}
