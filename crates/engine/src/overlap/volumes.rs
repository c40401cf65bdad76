//! Several volumes as one field ([`Volumes`]): each volume ([`Member`]) keeps its own data,
//! placement and medium (an instance shares another's data: `instance`), and a ray walks
//! the union of their piece streams ([`OverlapSegments`]): a k-way merge by distance that
//! cuts a new piece wherever any volume's piece ends, summing the volumes' coefficients
//! and emission over it ([`OverlapPiece`]). Where volumes overlap the medium is exactly
//! the sum of theirs. The volumes a ray or point meets are found through an R*-tree over
//! their world boxes (`plume_volume::instance::BoundsIndex`).
//!
//! - **Shadow rays** sum each shadow-casting volume's own optical depth (`τ = e^{−Σ OD_i}`),
//!   each volume walking the lighter view it walks alone; volumes with
//!   `casts_shadows = false` are left out.
//! - **Camera rays** see [`Volumes::camera_view`]: the volumes without
//!   `visible_to_camera = false`. Paths after a scattering event see every volume.
//! - **Point values** (a light sample's point) are sums of each volume's reconstruction.

use std::sync::Arc;

use glam::DVec3;

use super::member::Member;
use super::piece::OverlapPiece;
use super::stream::{Along, OverlapSegments};
use crate::medium::{Emission, EmissionKind, Extinction, Medium};
use plume_core::color::Rgb;
use plume_core::error::{Error, Result};
use plume_volume::field::{
    Bounds3, EmissionGroup, Field, PointValues, Ray, RayGrid, ScatterClass, VoxelValues,
};
use plume_volume::instance::BoundsIndex;
use plume_volume::overlap::MAX_CLASSES;

/// Several volumes rendered as one medium (see the module docs).
#[derive(Debug)]
pub struct Volumes<F: Field> {
    members: Vec<Member<F>>,
    /// Scattering class of each member (`None`: its medium does not scatter).
    class_of: Vec<Option<usize>>,
    classes: Vec<ScatterClass>,
    bounds: Bounds3,
    /// The members' world boxes.
    index: BoundsIndex,
    /// The volumes camera rays see, when some are hidden from them.
    camera: Option<Box<Volumes<F>>>,
    /// Views with one light group's emission each ([`Volumes::with_emission_groups`]).
    groups: Vec<EmissionGroup<Volumes<F>>>,
}

impl<F: Field> Volumes<F> {
    /// Several volumes; members whose media scatter alike (the same albedo and `g`) share
    /// a scattering class.
    ///
    /// # Errors
    /// No volume, a chromatic medium, or more than [`MAX_CLASSES`] scattering classes.
    pub fn new(members: Vec<Member<F>>) -> Result<Volumes<F>> {
        if members.is_empty() {
            return Err(Error::Scene("a scene of several volumes needs at least one".into()));
        }
        let mut classes: Vec<ScatterClass> = Vec::new();
        let mut class_of = Vec::with_capacity(members.len());
        for (i, m) in members.iter().enumerate() {
            if m.medium.extinction != Extinction::Grey {
                return Err(Error::Scene(format!(
                    "volume {i}: coloured absorption is supported for one volume only"
                )));
            }
            if m.medium.albedo.max_component() <= 0.0 {
                class_of.push(None);
                continue;
            }
            let class = ScatterClass { color: m.medium.albedo.0, g: m.medium.g };
            let k = match classes.iter().position(|c| *c == class) {
                Some(k) => k,
                None if classes.len() < MAX_CLASSES => {
                    classes.push(class);
                    classes.len() - 1
                }
                None => {
                    return Err(Error::Scene(format!(
                        "volume {i}: more than {MAX_CLASSES} different scattering media (albedo and g) in one scene"
                    )))
                }
            };
            class_of.push(Some(k));
        }
        let camera = members.iter().any(|m| !m.visible_to_camera).then(|| {
            let (members, class_of): (Vec<_>, Vec<_>) = members
                .iter()
                .zip(&class_of)
                .filter(|(m, _)| m.visible_to_camera)
                .map(|(m, c)| (Member { field: Arc::clone(&m.field), ..*m }, *c))
                .unzip();
            Box::new(Volumes::with_classes(members, class_of, classes.clone()))
        });
        Ok(Volumes { camera, ..Volumes::with_classes(members, class_of, classes) })
    }

    fn with_classes(
        members: Vec<Member<F>>,
        class_of: Vec<Option<usize>>,
        classes: Vec<ScatterClass>,
    ) -> Volumes<F> {
        let boxes: Vec<Bounds3> = members.iter().map(Member::world_bounds).collect();
        let bounds =
            boxes.iter().copied().reduce(|a, b| Bounds3 { lo: a.lo.min(b.lo), hi: a.hi.max(b.hi) });
        let bounds = bounds.unwrap_or(Bounds3 { lo: DVec3::ZERO, hi: DVec3::ZERO });
        let index = BoundsIndex::new(&boxes);
        Volumes { members, class_of, classes, bounds, index, camera: None, groups: Vec::new() }
    }

    /// The same volumes with their emission split between AOV layers: `layer_of[i]` is
    /// member `i`'s light group's layer (`None`: the `emission` and `scattered` layers).
    /// One view per layer that an emitting member has, in which only that layer's members
    /// emit ([`EmissionGroup`]); a walk of the view with the same numbers collects that
    /// layer's share of what the whole walk collects.
    ///
    /// # Errors
    /// `layer_of` not of one entry per member.
    pub fn with_emission_groups(self, layer_of: &[Option<usize>]) -> Result<Volumes<F>> {
        if layer_of.len() != self.members.len() {
            return Err(Error::Scene(format!(
                "{} light groups for {} volumes",
                layer_of.len(),
                self.members.len()
            )));
        }
        let mut layers: Vec<usize> = Vec::new();
        for (m, layer) in self.members.iter().zip(layer_of) {
            if let (Some(l), true) = (layer, m.medium.emission.kind != EmissionKind::None) {
                if !layers.contains(l) {
                    layers.push(*l);
                }
            }
        }
        let mut groups = Vec::with_capacity(layers.len());
        for layer in layers {
            let members = self
                .members
                .iter()
                .zip(layer_of)
                .map(|(m, l)| Member {
                    field: Arc::clone(&m.field),
                    medium: Medium {
                        emission: if *l == Some(layer) {
                            m.medium.emission
                        } else {
                            Emission::none()
                        },
                        ..m.medium
                    },
                    ..*m
                })
                .collect();
            groups.push(EmissionGroup { layer, field: Volumes::new(members)? });
        }
        Ok(Volumes { groups, ..self })
    }

    /// The volumes.
    #[must_use]
    pub fn members(&self) -> &[Member<F>] {
        &self.members
    }

    /// The medium a scene of these volumes is walked with: unit extinction (the pieces
    /// hold `μ_t` itself), no emission of its own (the pieces hold `L_e`), and as albedo
    /// the largest scattering colour per channel (only whether paths scatter is read from
    /// it: a collision's albedo and phase come from its classes).
    #[must_use]
    pub fn medium(&self) -> Medium {
        let albedo = self
            .classes
            .iter()
            .fold([0.0f32; 3], |a, c| std::array::from_fn(|k| a[k].max(c.color[k])));
        Medium {
            sigma_t: 1.0,
            albedo: Rgb(albedo),
            g: 0.0,
            emission: Emission::none(),
            extinction: Extinction::Grey,
        }
    }

    /// `le` of member `i`.
    fn le(&self, i: usize) -> impl Fn(f32, f32) -> Rgb + '_ {
        let emission = &self.members[i].medium.emission;
        move |d, s| emission.le(d, s)
    }

    /// The members whose boxes hold `p`, and `p` in each one's frame.
    fn at_point(&self, p: DVec3) -> impl Iterator<Item = (usize, DVec3)> + '_ {
        let mut found = Vec::new();
        self.index.at_point(p, &mut found);
        found.into_iter().map(move |i| (i, self.members[i].instance.map_or(p, |x| x.point(p))))
    }
}

impl<F: Field + Send> Field for Volumes<F> {
    type Piece = OverlapPiece;
    type Segments<'a>
        = OverlapSegments<'a, F>
    where
        F: 'a;

    fn world_bounds(&self) -> Bounds3 {
        self.bounds
    }

    fn segments(&self, ray: &Ray, t_min: f64, t_max: f64) -> OverlapSegments<'_, F> {
        OverlapSegments::new(
            Along { members: &self.members, class_of: &self.class_of, index: &self.index },
            ray,
            t_min,
            t_max,
        )
    }

    /// `μ_t` at the point (the unit medium's density); no one source.
    fn values_at(&self, p_world: DVec3) -> VoxelValues {
        let density = self
            .at_point(p_world)
            .map(|(i, p)| {
                let m = &self.members[i];
                m.medium.sigma_t * f64::from(m.field.values_at(p).density)
            })
            .sum::<f64>();
        VoxelValues { density: density as f32, source: 0.0 }
    }

    fn reconstruct(&self, p_world: DVec3, _le: &impl Fn(f32, f32) -> Rgb) -> PointValues {
        let mut out = PointValues { density: 0.0, source: 0.0, emission: [0.0; 3] };
        let mut mu = 0.0f64;
        for (i, p) in self.at_point(p_world) {
            let m = &self.members[i];
            let v = m.field.reconstruct(p, &self.le(i));
            mu += m.medium.sigma_t * f64::from(v.density);
            for (o, e) in out.emission.iter_mut().zip(v.emission) {
                *o += e;
            }
        }
        out.density = mu as f32;
        out
    }

    /// `Σ_i OD_i` over the shadow-casting volumes the ray meets, each walked alone (an
    /// instance along its base ray: `OD = (σ_t/s) ∫ρ dt'` over `t' ≤ s t_max`), stopped
    /// once the sum passes `od_stop`.
    fn optical_depth(&self, sigma_t: f64, ray: &Ray, t_max: f64, od_stop: f64) -> (f64, u64) {
        let (mut od, mut steps) = (0.0f64, 0u64);
        let mut met = Vec::new();
        self.index.on_ray(ray, 0.0, t_max, &mut met);
        for m in met.into_iter().map(|i| &self.members[i]).filter(|m| m.casts_shadows) {
            let (x, s) = match &m.instance {
                Some(i) => {
                    let b = i.ray(ray);
                    let sigma = sigma_t * m.medium.sigma_t / b.scale;
                    m.field.optical_depth(sigma, &b.ray, t_max * b.scale, od_stop - od)
                }
                None => m.field.optical_depth(sigma_t * m.medium.sigma_t, ray, t_max, od_stop - od),
            };
            od += x;
            steps += s;
            if od > od_stop {
                break;
            }
        }
        (od, steps)
    }

    fn prefetch(&self, grid: &RayGrid) -> u64 {
        self.members.iter().map(|m| m.field.prefetch(grid)).sum()
    }

    fn expect_prefetch(&self) {
        self.members.iter().for_each(|m| m.field.expect_prefetch());
    }

    fn is_mapped(&self) -> bool {
        self.members.iter().any(|m| m.field.is_mapped())
    }

    fn data_bytes(&self) -> usize {
        self.members.iter().map(|m| m.field.data_bytes()).sum()
    }

    fn member_voxels(&self, i: usize) -> Option<&plume_volume::Volume> {
        self.members.get(i).and_then(|m| m.field.voxels())
    }

    fn scatter_classes(&self) -> &[ScatterClass] {
        &self.classes
    }

    fn emission_groups(&self) -> &[EmissionGroup<Self>] {
        &self.groups
    }

    fn camera_view(&self) -> &Self {
        self.camera.as_deref().unwrap_or(self)
    }
}
