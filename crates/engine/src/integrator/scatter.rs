//! A scattered path from a collision on (METHOD.md §5–8): at each vertex the volume's
//! light sampling (FNEE or classic NEE) and the external lights' own, Russian roulette,
//! the phase function's next direction, then the next segment's emission with its MIS
//! weight, until the path escapes, is absorbed or reaches the largest depth. The weights
//! are stated in `integrator::volpath`'s module docs.

use glam::DVec3;

use super::aov::{Aovs, Component};
use super::groups;
use super::path::{contribute, times, Beta, Bounces, ForwardWeight, PathState, Vertex};
use super::scene::Scene;
use super::trace::Trace;
use super::tracker::Tracker;
use super::volpath::{Integrator, ROULETTE_THRESHOLD};
use crate::light::external::{ChosenLight, ExternalLights};
use crate::light::fnee::ProxySampling;
use crate::medium::tracking::emission_at_point;
use crate::medium::{Collision, DistanceSample, Medium};
use crate::overlap::scattering::{mixture, Phase, PhaseValue};
use plume_core::sampling::Dim;
use plume_scene::{Estimator, LightSampling};
use plume_volume::field::{ClassWeights, Field, PointValues, Ray};

/// A scattering vertex as light sampling sees it: the point, the direction the path
/// arrived along, the throughput after the vertex's albedo, and its phase function.
#[derive(Clone, Copy, Debug)]
struct ScatterPoint<'p> {
    x: DVec3,
    incoming: DVec3,
    beta: Beta,
    phase: &'p Phase,
}

impl Integrator {
    /// The path from `vertex` on, adding to `l` and to `state`'s AOVs; `bounces` is told
    /// of every vertex before its bounce.
    pub(super) fn scattered_path<F: Field, T: Trace, B: Bounces, A: Aovs>(
        &self,
        scene: &Scene<F>,
        tracker: &Tracker<'_, F>,
        vertex: Vertex,
        state: &mut PathState<'_, T, A>,
        bounces: &mut B,
        l: &mut [f64; 3],
    ) {
        let m = &scene.medium;
        let external = scene.lights.external.as_ref();
        let point_nee =
            self.light_sampling == LightSampling::Nee && self.estimator == Estimator::Point;
        let Vertex {
            incoming: mut ray,
            mut t,
            mut albedo,
            mut classes,
            mut beta,
            scale,
            mut depth,
        } = vertex;
        loop {
            bounces.at(
                Vertex { incoming: ray, t, albedo, classes, beta, scale, depth },
                state.sampler,
                l,
                state.counters,
            );
            state.counters.collisions += 1;
            depth += 1;
            // Scattering albedo of the collision's own segment (METHOD §10.3), per channel,
            // or of its classes where volumes overlap (`overlap::scattering`)
            let phase = match classes {
                None => {
                    for (b, a) in beta.iter_mut().zip(m.albedo.0) {
                        *b *= f64::from(a * albedo);
                    }
                    Phase::Hg(m.g)
                }
                Some(w) => {
                    let (alpha, phase) = mixture(scene.field.scatter_classes(), &w);
                    for (b, a) in beta.iter_mut().zip(alpha) {
                        *b *= a;
                    }
                    phase
                }
            };
            if beta == [0.0; 3] {
                break; // absorbed: nothing more to carry
            }
            let at = ScatterPoint { x: ray.at(t), incoming: ray.direction, beta, phase: &phase };
            // Sample the volume light at x
            state.sampler.start_light_segment(depth);
            self.sample_volume_light(scene, tracker, at, state, l);
            // Sample the external lights at x (a strategy of their own)
            if let Some(e) = external {
                self.sample_external(m, tracker, e, at, state, l);
            }
            // Russian roulette after this segment's emission
            state.sampler.start_vertex(depth);
            // On the largest channel: a grey path plays exactly as with a scalar β
            let q = (beta[0].max(beta[1]).max(beta[2]) / (scale * ROULETTE_THRESHOLD)).min(1.0);
            if q < 1.0 {
                if state.sampler.get_1d(Dim::Roulette) >= q {
                    state.trace.event(|| format!("  roulette: terminated (q {q})"));
                    break;
                }
                beta = beta.map(|b| b / q);
            }
            // Sample the phase function for the next direction (f/p = 1 for one lobe)
            let ps = phase.sample(ray.direction, state.sampler.get_2d(Dim::Direction));
            if let Some(w) = ps.weight {
                for (b, w) in beta.iter_mut().zip(w) {
                    *b *= w;
                }
            }
            ray = Ray { origin: at.x, direction: ps.direction };
            let need_collision = depth < self.max_depth;
            let next = Segment { ray, beta, depth, p_phase: ps.pdf, need_collision, point_nee };
            match self.forward_segment(scene, tracker, next, state, l) {
                Some(end) if need_collision => {
                    (t, albedo, classes) = (end.t, end.albedo, end.classes);
                    // A chromatic walk's weights of the collision (all 1 when grey)
                    for (b, w) in beta.iter_mut().zip(end.channels) {
                        *b *= w;
                    }
                }
                _ => break,
            }
        }
    }

    /// The segment a path takes after bouncing: its emission, weighted against the light
    /// sampling technique that could have drawn it, and the external lights it reaches.
    /// Returns the collision that ends it, if any.
    fn forward_segment<F: Field, T: Trace, A: Aovs>(
        &self,
        scene: &Scene<F>,
        tracker: &Tracker<'_, F>,
        next: Segment,
        state: &mut PathState<'_, T, A>,
        l: &mut [f64; 3],
    ) -> Option<SegmentEnd> {
        let (m, lights) = (&scene.medium, &scene.lights);
        let external = lights.external.as_ref();
        let Segment { ray, beta, depth, p_phase, need_collision, point_nee } = next;
        // MIS weight of the new segment, evaluated only if it collects emission: `p_σ`
        // needs a proxy walk, and the weight of a zero F is irrelevant
        let w_fwd = match self.light_sampling {
            LightSampling::None => ForwardWeight::One,
            LightSampling::Fnee if lights.volume_proxy().is_some() => {
                ForwardWeight::Fnee { p_phase }
            }
            LightSampling::Fnee => ForwardWeight::One,
            LightSampling::Nee if point_nee => ForwardWeight::One, // weighted at the collision
            LightSampling::Nee if lights.nee.is_some() || lights.nee_several.is_some() => {
                ForwardWeight::Zero
            }
            LightSampling::Nee => ForwardWeight::One,
        };
        // The next segment, which ends at the first sphere light it hits
        let hit = external.and_then(|e| e.hit(&ray));
        let t_max = hit.map_or(f64::INFINITY, |(t, _)| t);
        let u = state.sampler.get_1d(Dim::FreePath);
        let collision = if need_collision { Collision::Analog } else { Collision::Skip };
        let replay = groups::replay::<F, A>(scene, state.sampler);
        let r = tracker.track(m, &ray, t_max, self.estimator, collision, u, state.sampler);
        state.counters.add_track(&r);
        // Add emission along the segment
        let has_emission = r.emission.iter().any(|&v| v != 0.0);
        let mut w = match w_fwd {
            ForwardWeight::One => 1.0,
            ForwardWeight::Zero => 0.0,
            ForwardWeight::Fnee { p_phase } if has_emission => {
                lights.volume_proxy().map_or(1.0, |p| {
                    self.mis.weight(p_phase, p.direction_pdf(ray.origin, ray.direction))
                })
            }
            ForwardWeight::Fnee { .. } => 0.0,
        };
        if let (true, Some(nee), DistanceSample::Collided { t, density, .. }) =
            (point_nee, lights.volume_emitters(&scene.field), r.event)
        {
            // MIS in volume measure against NEE at the collision point
            let p_fwd = p_phase * m.mu_t(density) * m.extinction.collision_density(r.optical_depth)
                / (t * t);
            w = self.mis.weight(p_fwd, nee.pdf(ray.at(t)));
        }
        groups::contribute_volume(
            scene,
            l,
            state.aovs,
            Component::Scattered,
            times(beta, w),
            r.emission,
            |v| {
                let mut sampler =
                    replay.clone().expect("invariant: views are walked with a replay");
                let view = Tracker::Regular(v);
                view.track(m, &ray, t_max, self.estimator, collision, u, &mut sampler).emission
            },
        );
        state.trace.event(|| {
            format!(
                "segment depth {depth}: origin {:?} dir {:?} -> {:?}, F {:?}, w_fwd {w}, beta {beta:?}, tau {}",
                ray.origin, ray.direction, r.event, r.emission, r.transmittance
            )
        });
        if let Some(e) = external.filter(|e| r.transmittance != 0.0 && e.reachable()) {
            // The lights this segment reaches, each weighted against light sampling
            let mut weight = times(beta, r.transmittance);
            for (v, c) in weight.iter_mut().zip(r.channels.transmittance) {
                *v *= c;
            }
            e.arriving(&ray, hit.map(|(_, i)| i), Some(p_phase), self.mis, |i, w, radiance| {
                contribute(l, state.aovs, Component::Light(e.group(i)), times(weight, w), radiance);
                state.trace.event(|| {
                    format!("  reaches light {i}: L {radiance:?}, w {w}, tau {}", r.transmittance)
                });
            });
        }
        match r.event {
            DistanceSample::Collided { t, albedo, classes, .. } => {
                Some(SegmentEnd { t, albedo, classes, channels: r.channels.collision })
            }
            DistanceSample::Escaped => None,
        }
    }

    /// Light sampling of the volume's emission at a scattering vertex: an FNEE direction
    /// and a free path along it, or a classic NEE point with its exact shadow
    /// transmittance.
    fn sample_volume_light<F: Field, T: Trace, A: Aovs>(
        &self,
        scene: &Scene<F>,
        tracker: &Tracker<'_, F>,
        at: ScatterPoint<'_>,
        state: &mut PathState<'_, T, A>,
        l: &mut [f64; 3],
    ) {
        let (m, lights) = (&scene.medium, &scene.lights);
        let ScatterPoint { x, incoming, beta, phase } = at;
        let sampler = &mut *state.sampler;
        let c = &mut *state.counters;
        match self.light_sampling {
            LightSampling::Fnee => {
                let Some(proxy) = lights.volume_proxy() else { return };
                let u_cell = sampler.get_1d(Dim::LightChoice);
                let u_pos = sampler.get_3d(Dim::LightPosition);
                let Some(wi) = proxy.sample_direction_only(x, u_cell, u_pos) else { return };
                c.fnee_samples += 1;
                let u2 = sampler.get_1d(Dim::FreePath);
                let replay = groups::replay::<F, A>(scene, sampler);
                let rl = tracker.track(
                    m,
                    &Ray { origin: x, direction: wi },
                    f64::INFINITY,
                    self.estimator,
                    Collision::Skip,
                    u2,
                    sampler,
                );
                c.add_track(&rl);
                // p_σ only when the free path collected emission
                if rl.emission.iter().any(|&v| v != 0.0) {
                    let p_sigma = proxy.direction_pdf(x, wi);
                    if p_sigma > 0.0 {
                        let PhaseValue { f, pdf } = phase.eval(incoming.dot(wi));
                        let w_l = self.mis.weight(p_sigma, pdf);
                        let w = std::array::from_fn(|c| beta[c] * f[c] * w_l / p_sigma);
                        let scattered = Component::Scattered;
                        groups::contribute_volume(
                            scene,
                            l,
                            state.aovs,
                            scattered,
                            w,
                            rl.emission,
                            |v| {
                                let mut sampler = replay.clone().expect("invariant: a replay");
                                let ray = Ray { origin: x, direction: wi };
                                let view = Tracker::Regular(v);
                                view.track(
                                    m,
                                    &ray,
                                    f64::INFINITY,
                                    self.estimator,
                                    Collision::Skip,
                                    u2,
                                    &mut sampler,
                                )
                                .emission
                            },
                        );
                        state.trace.event(|| {
                            format!(
                                "  fnee: dir {wi:?} p_sigma {p_sigma} f {pdf} w {w_l} F {:?}",
                                rl.emission
                            )
                        });
                    }
                }
            }
            LightSampling::Nee => {
                let Some(nee) = lights.volume_emitters(&scene.field) else { return };
                let point_nee = self.estimator == Estimator::Point;
                let u_voxel = sampler.get_1d(Dim::LightChoice);
                let u_pos = sampler.get_3d(Dim::LightPosition);
                let Some(vs) = nee.sample(u_voxel, u_pos) else { return };
                let d = vs.p_world - x;
                let r2 = d.length_squared();
                if r2 > 0.0 {
                    c.nee_samples += 1;
                    let dist = r2.sqrt();
                    let wi = d / dist;
                    // (Classic NEE is refused with motion blur: its table is the frame's)
                    let shadow =
                        tracker.transmittance(m, &Ray { origin: x, direction: wi }, dist, sampler);
                    c.add_shadow(&shadow);
                    let (tau, channels) = (shadow.transmittance, shadow.channels);
                    if tau > 0.0 {
                        // L_e and ρ at y as the field reconstructs them (the table's
                        // pdf follows the same reconstruction: light/nee.rs)
                        let PointValues { density: dy, emission: le, .. } =
                            emission_at_point(&scene.field, m, vs.p_world);
                        let PhaseValue { f, pdf } = phase.eval(incoming.dot(wi));
                        let w_l = if point_nee {
                            let p_fwd = m.extinction.collision_density_of(tau, channels);
                            self.mis.weight(vs.pdf, pdf * m.mu_t(dy) * p_fwd / r2)
                        } else {
                            1.0
                        };
                        let w: Beta = std::array::from_fn(|c| {
                            beta[c] * f[c] * (tau * channels[c]) * w_l / (vs.pdf * r2)
                        });
                        groups::contribute_volume(
                            scene,
                            l,
                            state.aovs,
                            Component::Scattered,
                            w,
                            le,
                            |v| emission_at_point(v, m, vs.p_world).emission,
                        );
                        state.trace.event(|| {
                            format!(
                                "  nee: y {:?} p_V {} tau {tau} f {pdf} w {w_l} L_e {le:?}",
                                vs.p_world, vs.pdf
                            )
                        });
                    }
                }
            }
            LightSampling::None => {}
        }
    }

    /// Light sampling of the external lights at a scattering vertex:
    /// `L += β f τ L_i w(P_i p_i, f) / (P_i p_i)` with the tracker's shadow transmittance
    /// (exact, or ratio tracking's unbiased estimate) (`light::external`).
    fn sample_external<F: Field, T: Trace, A: Aovs>(
        &self,
        m: &Medium,
        tracker: &Tracker<'_, F>,
        lights: &ExternalLights,
        at: ScatterPoint<'_>,
        state: &mut PathState<'_, T, A>,
        l: &mut [f64; 3],
    ) {
        let ScatterPoint { x, incoming, beta, phase } = at;
        let u_choice = state.sampler.get_1d(Dim::ExternalLightChoice);
        let u = state.sampler.get_2d(Dim::ExternalLightDirection);
        let Some(ChosenLight { index, pmf, sample: s }) = lights.sample(x, u_choice, u) else {
            return;
        };
        state.counters.external_light_samples += 1;
        let PhaseValue { f, pdf } = phase.eval(incoming.dot(s.direction));
        let shadow = tracker.transmittance(
            m,
            &Ray { origin: x, direction: s.direction },
            s.distance,
            state.sampler,
        );
        state.counters.add_shadow(&shadow);
        let (tau, channels) = (shadow.transmittance, shadow.channels);
        if tau > 0.0 {
            let w = if s.pdf > 0.0 { self.mis.weight(pmf * s.pdf, pdf) } else { 1.0 };
            let weight: Beta =
                std::array::from_fn(|c| beta[c] * f[c] * (tau * channels[c]) * w / pmf);
            contribute(l, state.aovs, Component::Light(lights.group(index)), weight, s.value);
            state.trace.event(|| {
                format!("  light {index}: dir {:?} dist {} pmf {pmf} pdf {} tau {tau} f {pdf} w {w} L/p {:?}", s.direction, s.distance, s.pdf, s.value)
            });
        }
    }
}

/// Where a forward segment's free path ended in a collision: the distance, the albedo
/// factor of its segment, and the chromatic walk's weights of it (all 1 when grey).
#[derive(Clone, Copy, Debug)]
struct SegmentEnd {
    t: f64,
    albedo: f32,
    classes: Option<ClassWeights>,
    channels: [f64; 3],
}

/// The segment a path takes after a bounce, as [`Integrator::forward_segment`] walks it.
#[derive(Clone, Copy, Debug)]
struct Segment {
    ray: Ray,
    beta: Beta,
    depth: u32,
    /// Phase pdf of the segment's direction.
    p_phase: f64,
    /// Whether the path may collide again (below the largest depth).
    need_collision: bool,
    /// Classic NEE with the point estimator: MIS in volume measure at the collision.
    point_nee: bool,
}
