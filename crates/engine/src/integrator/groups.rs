//! Light groups of volumes: with AOVs, the light a volume emits, seen directly and after
//! scattering, goes to the layer of the volume's `group` instead of `emission` and
//! `scattered` (as an external light's goes to its group's layer, `integrator::aov`).
//!
//! Every estimate of volume emission is linear in `L_e`: a walk's line integral, a
//! collision's `L_e/μ_t`, ray-march's sums, a light sample's `L_e(y)`. Where volumes of
//! several groups overlap, `L_e = Σ_g L_e,g`, so the estimate of a walk is the sum of the
//! estimates of the same walk — the same extinction, the same numbers, so the same
//! collisions — through views of the field in which only group `g`'s volumes emit
//! ([`plume_volume::field::EmissionGroup`]). A contribution `w · e` is then added to the
//! beauty once, and to the layers as `w · e_g` for each group and `w · (e − Σ_g e_g)` for
//! the volumes without one (where some emitting volume has none). The layers sum to the
//! beauty per sample up to rounding. `n` groups cost `n` more walks of each segment that
//! collects emission. (Where every emitter is grouped, the last group's share could be the
//! rest, one walk fewer; it is walked too, so that the sum of the layers checks every
//! group's walks.)
//!
//! The views are walked only with AOVs that keep light groups ([`Aovs::GROUPS`]) and only
//! when the scene has them: a render without AOVs runs the code it ran before groups.
//! When every emitting volume is of one group (one volume with a `group`, say), nothing
//! needs walking again: the whole emission goes to that group's layer
//! ([`super::lights::VolumeLayers`]).

use super::aov::{Aovs, Component};
use super::lights::VolumeLayers;
use super::path::contribute;
use super::scene::Scene;
use plume_core::sampling::Sampler;
use plume_volume::field::Field;

/// What a sample needs to walk the group views with its own numbers: a copy of its
/// sampler from before the walk, only where views will be walked.
pub(super) fn replay<F: Field, A: Aovs>(scene: &Scene<F>, sampler: &Sampler) -> Option<Sampler> {
    (A::GROUPS && !scene.field.emission_groups().is_empty()).then(|| sampler.clone())
}

/// Add `w · e`, volume emission of `component` (emission or scattered), to the beauty and
/// to the layers: whole to its group's layer where one group holds all emission, else
/// split by `of_view`, which gives the same estimate through a group's view (module docs).
pub(super) fn contribute_volume<F: Field, A: Aovs>(
    scene: &Scene<F>,
    l: &mut [f64; 3],
    aovs: &mut A,
    component: Component,
    w: [f64; 3],
    e: [f64; 3],
    mut of_view: impl FnMut(&F) -> [f64; 3],
) {
    if !A::GROUPS {
        return contribute(l, aovs, component, w, e);
    }
    let ungrouped = match scene.lights.volume_layers {
        VolumeLayers::Unsplit => return contribute(l, aovs, component, w, e),
        VolumeLayers::One(layer) => return contribute(l, aovs, Component::Light(layer), w, e),
        VolumeLayers::Split { ungrouped } => ungrouped,
    };
    if e == [0.0; 3] || w == [0.0; 3] {
        return contribute(l, aovs, component, w, e);
    }
    for ((a, v), w) in l.iter_mut().zip(e).zip(w) {
        *a += w * v;
    }
    let mut rest = e;
    for g in scene.field.emission_groups() {
        let eg = of_view(&g.field);
        aovs.add(Component::Light(g.layer), w, eg);
        for (r, v) in rest.iter_mut().zip(eg) {
            *r -= v;
        }
    }
    // Only rounding is left when every emitting volume has a group
    if ungrouped {
        aovs.add(component, w, rest);
    }
}
