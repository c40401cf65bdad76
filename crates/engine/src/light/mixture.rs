//! FNEE over several volumes (METHOD.md §14): each emitting volume keeps its own proxy
//! ([`ProxyGrid`], in its own index space), one is chosen with probability `P_i ∝ Φ_i`,
//! and a direction is drawn through its proxy. The direction's density is the mixture
//!
//! ```text
//! p_σ(ω) = Σ_i P_i p_σ^i(ω),
//! ```
//!
//! each `p_σ^i` the volume's own (`light::fnee`; 0 for a volume the ray misses), so MIS
//! with phase sampling stays exact where volumes overlap. `Φ_i` is the volume's proxy power
//! times its emission scale and the luminance of its tint (the proxies leave both out);
//! any positive weights keep the estimator unbiased, power makes it efficient.
//! **Instances** share their volume's proxy ([`PlacedProxy`]): a direction is drawn in the
//! volume's own frame and carried out, and its density picks up the change of solid angle
//! under the instance's map, `p(ω) = p'(ω') |det L|/|Lω|³` with `L` the linear part of
//! `base_from_world` and `ω' = Lω/|Lω|` (the Jacobian of a linear map on directions). Only
//! the proxies whose emitting boxes a direction's ray meets are evaluated, found through an
//! R*-tree (`plume_volume::instance::BoundsIndex`).
//!
//! [`VolumeProxy`] is what the integrator samples: one volume's proxy as before, or the
//! mixture.

use std::sync::Arc;

use glam::DVec3;

use super::by_power::{shared_bytes, ByPower, Chosen};
use super::fnee::{ProxyPoint, ProxySampling};
use plume_volume::field::{Bounds3, Ray};
use plume_volume::instance::{BoundsIndex, Instance};
use plume_volume::proxy::ProxyGrid;

/// A volume's proxy where the volume is placed: its own, or an instance's of a shared one.
#[derive(Clone, Debug)]
pub struct PlacedProxy {
    /// The proxy, in its volume's own world frame.
    pub proxy: Arc<ProxyGrid>,
    /// The instance's placement of that frame, if any.
    pub instance: Option<Instance>,
}

impl PlacedProxy {
    /// The world box of the proxy's emitting cells.
    pub fn emitting_bounds(&self) -> Bounds3 {
        let p = &self.proxy;
        let corner = |k: glam::IVec3| p.origin + k.as_dvec3() * f64::from(p.edge);
        let index = Bounds3 { lo: corner(p.occupied_lo), hi: corner(p.occupied_hi) };
        let world =
            Instance { world_from_base: p.world_from_index, base_from_world: p.index_from_world }
                .bounds(index);
        self.instance.map_or(world, |i| i.bounds(world))
    }

    fn sample_direction_only(&self, x: DVec3, u_cell: f64, u_pos: [f64; 3]) -> Option<DVec3> {
        match &self.instance {
            None => self.proxy.sample_direction_only(x, u_cell, u_pos),
            Some(i) => {
                let w = self.proxy.sample_direction_only(i.point(x), u_cell, u_pos)?;
                let v = i.world_from_base.transform_vector3(w);
                let n = v.length();
                (n > 0.0 && n.is_finite()).then(|| v / n)
            }
        }
    }

    fn direction_pdf(&self, x: DVec3, w: DVec3) -> f64 {
        match &self.instance {
            None => self.proxy.direction_pdf(x, w),
            Some(i) => {
                let v = i.base_from_world.transform_vector3(w);
                let n = v.length();
                if !(n > 0.0 && n.is_finite()) {
                    return 0.0;
                }
                self.proxy.direction_pdf(i.point(x), v / n) * i.base_per_world_volume()
                    / (n * n * n)
            }
        }
    }
}

/// Several volumes' proxies and the probability of choosing each (see the module docs).
#[derive(Debug)]
pub struct ProxyMixture {
    proxies: ByPower<PlacedProxy>,
    /// The emitting boxes.
    index: BoundsIndex,
}

impl ProxyMixture {
    /// The proxies with their weights `Φ_i`; proxies of zero (or non-finite) weight are
    /// left out. `None` when no proxy is left.
    #[must_use]
    pub fn new(proxies: Vec<(PlacedProxy, f64)>) -> Option<ProxyMixture> {
        let proxies = ByPower::new(proxies)?;
        let boxes: Vec<Bounds3> =
            proxies.lights().iter().map(PlacedProxy::emitting_bounds).collect();
        Some(ProxyMixture { proxies, index: BoundsIndex::new(&boxes) })
    }

    /// The proxies kept, and their probabilities.
    pub fn proxies(&self) -> impl Iterator<Item = (&PlacedProxy, f64)> {
        self.proxies.iter()
    }

    /// Bytes held by the proxies (a shared one once) and the mixture's own tables.
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        let lights = self.proxies.lights();
        shared_bytes(lights, |p| &p.proxy, ProxyGrid::memory_bytes)
            + lights.len() * (std::mem::size_of::<PlacedProxy>() + 64)
            + self.proxies.table_bytes()
    }
}

impl ProxySampling for ProxyMixture {
    /// A point of the chosen volume's proxy; `cell` is that proxy's cell and `pmf` the
    /// product of the two choices.
    fn sample_point(&self, u_cell: f64, u_pos: [f64; 3]) -> ProxyPoint {
        let Chosen { index, pmf: p, u: v } = self.proxies.choose(u_cell);
        let placed = &self.proxies.lights()[index];
        let point = placed.proxy.sample_point(v, u_pos);
        let p_world = placed
            .instance
            .map_or(point.p_world, |x| x.world_from_base.transform_point3(point.p_world));
        ProxyPoint { pmf: p * point.pmf, p_world, ..point }
    }

    fn sample_direction_only(&self, x_world: DVec3, u_cell: f64, u_pos: [f64; 3]) -> Option<DVec3> {
        let Chosen { index, u, .. } = self.proxies.choose(u_cell);
        self.proxies.lights()[index].sample_direction_only(x_world, u, u_pos)
    }

    /// `Σ_i P_i p_σ^i(ω)` over the proxies whose emitting boxes the ray `x + tω` meets.
    fn direction_pdf(&self, x_world: DVec3, w_world: DVec3) -> f64 {
        let mut met = Vec::new();
        let ray = Ray { origin: x_world, direction: w_world };
        self.index.on_ray(&ray, 0.0, f64::INFINITY, &mut met);
        let proxies = self.proxies.lights();
        met.into_iter()
            .map(|i| self.proxies.pmf(i) * proxies[i].direction_pdf(x_world, w_world))
            .sum()
    }
}

/// The proxy FNEE samples: one volume's, or several volumes' mixture.
#[derive(Clone, Copy, Debug)]
pub enum VolumeProxy<'a> {
    /// One volume.
    One(&'a ProxyGrid),
    /// Several volumes.
    Several(&'a ProxyMixture),
}

impl ProxySampling for VolumeProxy<'_> {
    #[inline]
    fn sample_point(&self, u_cell: f64, u_pos: [f64; 3]) -> ProxyPoint {
        match self {
            VolumeProxy::One(p) => p.sample_point(u_cell, u_pos),
            VolumeProxy::Several(m) => m.sample_point(u_cell, u_pos),
        }
    }

    #[inline]
    fn sample_direction_only(&self, x_world: DVec3, u_cell: f64, u_pos: [f64; 3]) -> Option<DVec3> {
        match self {
            VolumeProxy::One(p) => p.sample_direction_only(x_world, u_cell, u_pos),
            VolumeProxy::Several(m) => m.sample_direction_only(x_world, u_cell, u_pos),
        }
    }

    #[inline]
    fn direction_pdf(&self, x_world: DVec3, w_world: DVec3) -> f64 {
        match self {
            VolumeProxy::One(p) => p.direction_pdf(x_world, w_world),
            VolumeProxy::Several(m) => m.direction_pdf(x_world, w_world),
        }
    }
}
