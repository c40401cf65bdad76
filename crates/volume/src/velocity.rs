//! Velocity fields for motion blur: world units per second at world points.
//!
//! A grid is three float components on the leaves of the velocity grid(s) — a vec3 grid
//! split by the reader, or three float grids `NAME.x`, `NAME.y`, `NAME.z` (Houdini) — looked
//! up at the nearest voxel (0 outside every leaf). Velocity is sampled where the motion is
//! traced back from (`volume::motion`), so it only moves the lookup point: nearest is
//! enough, and keeps the majorant bound (`max |v|`) exact.

use std::collections::HashMap;

use glam::{DAffine3, DVec3, IVec3};

use crate::grid::{leaf_offset, FloatGrid, LEAF_DIM, LEAF_VOXELS};
use plume_core::error::{Error, Result};

/// A velocity field.
#[derive(Clone, Debug)]
pub enum Velocity {
    /// The same velocity everywhere (tests, and whole-volume motion).
    Uniform(DVec3),
    /// A sparse grid.
    Grid(VelocityGrid),
}

/// A sparse velocity grid: leaves of 8³ voxels, three components each.
#[derive(Clone, Debug)]
pub struct VelocityGrid {
    index_from_world: DAffine3,
    /// Leaf origin → first of its 512 values.
    leaves: HashMap<IVec3, usize>,
    values: Vec<[f32; 3]>,
    max_speed: f64,
}

impl Velocity {
    /// Velocity at world point `p` (world units per second).
    #[inline]
    #[must_use]
    pub fn at(&self, p: DVec3) -> DVec3 {
        match self {
            Velocity::Uniform(v) => *v,
            Velocity::Grid(g) => g.at(p),
        }
    }

    /// Largest speed anywhere (world units per second).
    #[must_use]
    pub fn max_speed(&self) -> f64 {
        match self {
            Velocity::Uniform(v) => v.length(),
            Velocity::Grid(g) => g.max_speed,
        }
    }
}

impl VelocityGrid {
    /// The grid of components `x`, `y`, `z` (one transform; leaves may differ between
    /// components: a component absent from a leaf is 0 there). `what` names the file and
    /// grid in errors.
    ///
    /// # Errors
    /// [`Error::Scene`] when the components have different transforms or a value is not
    /// finite.
    pub fn from_components(components: [&FloatGrid; 3], what: &str) -> Result<VelocityGrid> {
        let xf = components[0].world_from_index;
        for (axis, c) in components.iter().enumerate() {
            if c.world_from_index != xf {
                return Err(Error::Scene(format!(
                    "{what}: velocity component {} has another transform than x",
                    ["x", "y", "z"][axis]
                )));
            }
        }
        let mut leaves: HashMap<IVec3, usize> = HashMap::new();
        let mut values: Vec<[f32; 3]> = Vec::new();
        for (axis, c) in components.iter().enumerate() {
            for (leaf, &origin) in c.origins.iter().enumerate() {
                let base = *leaves.entry(origin).or_insert_with(|| {
                    values.resize(values.len() + LEAF_VOXELS, [0.0; 3]);
                    values.len() - LEAF_VOXELS
                });
                for (k, &v) in
                    c.values[leaf * LEAF_VOXELS..(leaf + 1) * LEAF_VOXELS].iter().enumerate()
                {
                    if !v.is_finite() {
                        return Err(Error::Scene(format!("{what}: velocity component {} is not finite ({v}) in the leaf at {origin}", ["x", "y", "z"][axis])));
                    }
                    values[base + k][axis] = v;
                }
            }
        }
        // World velocity: the components are world-space vectors (Blender, Houdini)
        let max_speed = max_speed(&values);
        Ok(VelocityGrid { index_from_world: xf.inverse(), leaves, values, max_speed })
    }

    /// Velocity at world point `p`: the nearest voxel's, 0 outside the leaves.
    #[must_use]
    pub fn at(&self, p: DVec3) -> DVec3 {
        let ijk = (self.index_from_world.transform_point3(p) + 0.5).floor().as_ivec3();
        let origin = IVec3::new(
            ijk.x.div_euclid(LEAF_DIM),
            ijk.y.div_euclid(LEAF_DIM),
            ijk.z.div_euclid(LEAF_DIM),
        ) * LEAF_DIM;
        self.leaves.get(&origin).map_or(DVec3::ZERO, |&base| {
            let l = ijk - origin;
            let v = self.values[base + leaf_offset(l.x, l.y, l.z)];
            DVec3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2]))
        })
    }

    /// The grid placed in the world by `world_from_file` (invertible), as the volume it
    /// moves ([`crate::Volume::placed`]): positions through the whole map, and the
    /// velocities, world vectors, through its linear part (so a volume scaled by 2 moves
    /// twice as far, and a rotated one along its rotated flow).
    #[must_use]
    pub fn placed(mut self, world_from_file: DAffine3) -> VelocityGrid {
        let linear = world_from_file.matrix3;
        self.index_from_world *= world_from_file.inverse();
        for v in &mut self.values {
            let w = linear * DVec3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2]));
            *v = [w.x as f32, w.y as f32, w.z as f32];
        }
        self.max_speed = max_speed(&self.values);
        self
    }

    /// Bytes held.
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        self.values.len() * 12 + self.leaves.len() * 24
    }
}

/// The largest speed among `values` (world units per second).
fn max_speed(values: &[[f32; 3]]) -> f64 {
    values
        .iter()
        .map(|v| v.iter().map(|c| f64::from(*c).powi(2)).sum::<f64>())
        .fold(0.0, f64::max)
        .sqrt()
}
