//! Instances and finding the volumes a ray meets.
//!
//! An [`Instance`] places a shared volume once more: its data stay where they are (in the
//! volume's own world frame, the *base* frame) and rays are carried into that frame. With
//! `M` the instance's `world_from_base` and `L` the linear part of `M⁻¹`, a world ray
//! `x + t ω` is the base ray `M⁻¹x + t' ω'` with `ω' = Lω/|Lω|` and `t' = s t`,
//! `s = |Lω|`: the base walk's pieces are the world's with distances divided by `s`, and a
//! value's cubic in the base distance `Σ a_j v'^j` is `Σ (a_j s^j) v^j` in the world's.
//! Coefficients stay per world unit (what `space = "object"` changes is the medium's, as
//! for any placed volume). Geometry only: the engine's several volumes
//! (`plume_engine::overlap`) and their light sampling (`plume_engine::light::mixture`)
//! use it.
//!
//! [`BoundsIndex`] is an R*-tree (`rstar`, the georust crate) over the volumes' world
//! boxes: a ray, a point or a direction finds the volumes it meets in `O(log n + k)`, so
//! a thousand instances cost a ray what the few it crosses cost.

use glam::{DAffine3, DVec3};
use rstar::primitives::{GeomWithData, Rectangle};
use rstar::{RTree, SelectionFunction, AABB};

use crate::field::{Bounds3, Ray};

/// A shared volume's placement (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instance {
    /// The volume's own world frame to this instance's place.
    pub world_from_base: DAffine3,
    /// Its inverse.
    pub base_from_world: DAffine3,
}

/// A world ray in an instance's base frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BaseRay {
    /// The ray, with a unit base direction.
    pub ray: Ray,
    /// Base distance per world distance, `s = |Lω|`.
    pub scale: f64,
}

impl Instance {
    /// The instance `world_from_base`; `None` when it is singular or not finite.
    #[must_use]
    pub fn new(world_from_base: DAffine3) -> Option<Instance> {
        let det = world_from_base.matrix3.determinant();
        if !(det.is_finite() && det != 0.0 && world_from_base.translation.is_finite()) {
            return None;
        }
        Some(Instance { world_from_base, base_from_world: world_from_base.inverse() })
    }

    /// `ray` in the base frame.
    #[inline]
    #[must_use]
    pub fn ray(&self, ray: &Ray) -> BaseRay {
        let d = self.base_from_world.transform_vector3(ray.direction);
        let scale = d.length();
        BaseRay {
            ray: Ray {
                origin: self.base_from_world.transform_point3(ray.origin),
                direction: d / scale,
            },
            scale,
        }
    }

    /// A world point in the base frame.
    #[inline]
    #[must_use]
    pub fn point(&self, p: DVec3) -> DVec3 {
        self.base_from_world.transform_point3(p)
    }

    /// The world box around a base box.
    pub fn bounds(&self, b: Bounds3) -> Bounds3 {
        let corners = (0..8).map(|c| {
            let pick = |bit: usize, lo: f64, hi: f64| if c & bit == 0 { lo } else { hi };
            self.world_from_base.transform_point3(DVec3::new(
                pick(1, b.lo.x, b.hi.x),
                pick(2, b.lo.y, b.hi.y),
                pick(4, b.lo.z, b.hi.z),
            ))
        });
        let (lo, hi) = corners
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| (lo.min(p), hi.max(p)));
        Bounds3 { lo, hi }
    }

    /// `|det L|`, the base volume per world volume.
    #[must_use]
    pub fn base_per_world_volume(&self) -> f64 {
        self.base_from_world.matrix3.determinant().abs()
    }
}

/// Rescale a cubic in the base distance `v'` to the world distance `v = v'/s`.
#[inline]
#[must_use]
pub fn to_world(a: [f64; 4], s: f64) -> [f64; 4] {
    if s == 1.0 {
        return a;
    }
    [a[0], a[1] * s, a[2] * s * s, a[3] * s * s * s]
}

type Leaf = GeomWithData<Rectangle<[f64; 3]>, usize>;

/// The world boxes of a scene's volumes, for the queries of the module docs.
#[derive(Debug)]
pub struct BoundsIndex {
    tree: RTree<Leaf>,
}

impl BoundsIndex {
    /// An index over `boxes` (item `i` is box `i`).
    #[must_use]
    pub fn new(boxes: &[Bounds3]) -> BoundsIndex {
        let leaves = boxes
            .iter()
            .enumerate()
            .map(|(i, b)| {
                GeomWithData::new(Rectangle::from_corners(b.lo.to_array(), b.hi.to_array()), i)
            })
            .collect();
        BoundsIndex { tree: RTree::bulk_load(leaves) }
    }

    /// The items whose boxes `ray` meets over `[t_min, t_max]` (closed boxes), ascending.
    pub fn on_ray(&self, ray: &Ray, t_min: f64, t_max: f64, out: &mut Vec<usize>) {
        out.clear();
        let select = OnRay { ray: *ray, t_min, t_max };
        out.extend(self.tree.locate_with_selection_function(select).map(|l| l.data));
        out.sort_unstable();
    }

    /// The items whose boxes hold `p`, ascending.
    pub fn at_point(&self, p: DVec3, out: &mut Vec<usize>) {
        out.clear();
        out.extend(self.tree.locate_all_at_point(&p.to_array()).map(|l| l.data));
        out.sort_unstable();
    }
}

/// Selects the boxes a ray segment meets.
struct OnRay {
    ray: Ray,
    t_min: f64,
    t_max: f64,
}

impl OnRay {
    fn meets(&self, envelope: &AABB<[f64; 3]>) -> bool {
        meets(
            &self.ray,
            DVec3::from(envelope.lower()),
            DVec3::from(envelope.upper()),
            self.t_min,
            self.t_max,
        )
    }
}

impl SelectionFunction<Leaf> for OnRay {
    fn should_unpack_parent(&self, envelope: &AABB<[f64; 3]>) -> bool {
        self.meets(envelope)
    }

    fn should_unpack_leaf(&self, leaf: &Leaf) -> bool {
        self.meets(&rstar::RTreeObject::envelope(leaf))
    }
}

/// Whether `ray` meets the closed box `[lo, hi]` over `[t_min, t_max]` (conservative:
/// a grazing ray counts).
#[must_use]
pub fn meets(ray: &Ray, lo: DVec3, hi: DVec3, t_min: f64, t_max: f64) -> bool {
    crate::field::slabs(ray.origin, ray.direction, lo, hi, t_min, t_max, true)
        .is_some_and(|(t0, t1)| t0 <= t1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_index_finds_what_a_linear_scan_finds() {
        let boxes: Vec<Bounds3> = (0..300)
            .map(|i| {
                let c = DVec3::new(f64::from(i % 10), f64::from((i / 10) % 10), f64::from(i / 100))
                    * 1.5;
                Bounds3 { lo: c, hi: c + DVec3::splat(1.0 + 0.1 * f64::from(i % 7)) }
            })
            .collect();
        let index = BoundsIndex::new(&boxes);
        let mut found = Vec::new();
        for k in 0..50 {
            let k = f64::from(k);
            let ray = Ray {
                origin: DVec3::new(-3.0, 0.37 * k % 15.0, 0.21 * k % 4.0),
                direction: DVec3::new(1.0, 0.05 * (k - 25.0) / 25.0, 0.02).normalize(),
            };
            index.on_ray(&ray, 0.0, 40.0, &mut found);
            let scan: Vec<usize> = (0..boxes.len())
                .filter(|&i| meets(&ray, boxes[i].lo, boxes[i].hi, 0.0, 40.0))
                .collect();
            assert_eq!(found, scan);
        }
        index.at_point(DVec3::new(0.5, 0.2, 0.2), &mut found);
        assert_eq!(found, vec![0]);
    }

    #[test]
    fn a_scaled_instance_carries_rays_and_cubics() {
        let m = DAffine3::from_scale_rotation_translation(
            DVec3::new(2.0, 0.5, 1.0),
            glam::DQuat::from_rotation_z(0.3),
            DVec3::new(1.0, -2.0, 0.5),
        );
        let i = Instance::new(m).unwrap();
        let ray = Ray {
            origin: DVec3::new(0.2, 0.1, -3.0),
            direction: DVec3::new(0.3, 0.4, 1.0).normalize(),
        };
        let b = i.ray(&ray);
        for t in [0.0, 1.0, 2.5] {
            let world = ray.at(t);
            let base = b.ray.at(t * b.scale);
            assert!((i.point(world) - base).length() < 1e-12);
        }
        // A cubic in the base distance, read at world distance v
        let a = [1.0, 2.0, -0.5, 0.25];
        let w = to_world(a, b.scale);
        for v in [0.0, 0.3, 1.1] {
            let vb = v * b.scale;
            let (x, y) = (
                a[0] + vb * (a[1] + vb * (a[2] + vb * a[3])),
                w[0] + v * (w[1] + v * (w[2] + v * w[3])),
            );
            assert!((x - y).abs() < 1e-12, "{x} vs {y}");
        }
        assert!(Instance::new(DAffine3::from_scale(DVec3::new(1.0, 0.0, 1.0))).is_none());
    }
}
