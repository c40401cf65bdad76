//! Min/max pyramid over the brick table, for empty-space skipping and majorants.
//!
//! Level 0 has one [`NodeBounds`] per brick-table cell (8³ voxels); level `k` has one per
//! `2^k × 2^k × 2^k` cells (`8·2^k` voxels on a side), up to a single root node. Cells
//! without a brick count as density 0 and source 0, so a node whose bounds are *uniform*
//! (`min == max` in both channels) is exactly constant over its whole footprint: the DDA
//! crosses it as one segment (a zero node is skipped in one step, METHOD.md §3). The
//! invariant tested in `tests/volume.rs`: every node's max ≥ every voxel beneath it, and
//! its min ≤ every voxel beneath it.

use glam::IVec3;

use super::brick::{Slot, Volume, BRICK};
use crate::vdb::LEAF_VOXELS;

/// Value bounds of one pyramid node.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NodeBounds {
    /// Smallest density beneath.
    pub density_min: f32,
    /// Largest density beneath (a majorant for μ_t / σ_t).
    pub density_max: f32,
    /// Smallest source beneath.
    pub source_min: f32,
    /// Largest source beneath.
    pub source_max: f32,
    /// Smallest albedo factor beneath (over voxels with density > 0; 1 without any).
    pub albedo_min: f32,
    /// Largest albedo factor beneath (over voxels with density > 0; 1 without any).
    pub albedo_max: f32,
}

impl NodeBounds {
    const ZERO: NodeBounds =
        NodeBounds { density_min: 0.0, density_max: 0.0, source_min: 0.0, source_max: 0.0, albedo_min: 1.0, albedo_max: 1.0 };

    /// True when the node is constant in every channel that matters: density, source,
    /// and albedo where there is density (no collision happens where density is 0).
    #[inline]
    #[must_use]
    pub fn is_uniform(&self) -> bool {
        self.density_min == self.density_max
            && self.source_min == self.source_max
            && (self.albedo_min == self.albedo_max || self.density_max == 0.0)
    }

    /// Albedo factor to report for a uniform node.
    #[inline]
    #[must_use]
    pub fn uniform_albedo(&self) -> f32 {
        if self.density_max == 0.0 { 1.0 } else { self.albedo_max }
    }

    fn union(self, o: NodeBounds) -> NodeBounds {
        NodeBounds {
            density_min: self.density_min.min(o.density_min),
            density_max: self.density_max.max(o.density_max),
            source_min: self.source_min.min(o.source_min),
            source_max: self.source_max.max(o.source_max),
            albedo_min: self.albedo_min.min(o.albedo_min),
            albedo_max: self.albedo_max.max(o.albedo_max),
        }
    }
}

/// One level of the pyramid.
#[derive(Clone, Debug, Default)]
pub struct Level {
    /// Nodes per axis.
    pub dims: IVec3,
    /// Nodes, x fastest.
    pub nodes: Vec<NodeBounds>,
}

impl Level {
    /// Node at level coordinate `c` (must be inside `dims`).
    #[inline]
    #[must_use]
    pub fn get(&self, c: IVec3) -> &NodeBounds {
        &self.nodes[c.x as usize + self.dims.x as usize * (c.y as usize + self.dims.y as usize * c.z as usize)]
    }
}

/// The min/max pyramid: `levels[0]` per brick, the last level a single node.
#[derive(Clone, Debug, Default)]
pub struct Pyramid {
    /// Levels from finest (bricks) to coarsest (root).
    pub levels: Vec<Level>,
}

fn slot_bounds(values: &[f32], slot: Slot) -> (f32, f32) {
    match slot {
        Slot::Constant(v) => (v, v),
        Slot::Dense(off) => values[off as usize..off as usize + LEAF_VOXELS]
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v))),
    }
}

/// Albedo bounds of a brick over its voxels with density > 0 (`(1, 1)` if none).
fn albedo_bounds(volume: &Volume, b: &super::brick::Brick) -> (f32, f32) {
    if let Slot::Constant(a) = b.albedo {
        let (_, dmax) = slot_bounds(&volume.density_values, b.density);
        return if dmax > 0.0 { (a, a) } else { (1.0, 1.0) };
    }
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for i in 0..LEAF_VOXELS {
        let d = match b.density {
            Slot::Constant(v) => v,
            Slot::Dense(off) => volume.density_values[off as usize + i],
        };
        if d > 0.0 {
            let a = match b.albedo {
                Slot::Constant(v) => v,
                Slot::Dense(off) => volume.albedo_values[off as usize + i],
            };
            lo = lo.min(a);
            hi = hi.max(a);
        }
    }
    if lo > hi { (1.0, 1.0) } else { (lo, hi) }
}

impl Pyramid {
    /// Build all levels of `volume`'s pyramid.
    #[must_use]
    pub fn build(volume: &Volume) -> Pyramid {
        if volume.dims.cmple(IVec3::ZERO).any() {
            return Pyramid::default();
        }
        let dims = volume.dims;
        let mut base = Level { dims, nodes: vec![NodeBounds::ZERO; volume.table.len()] };
        for (node, &bi) in base.nodes.iter_mut().zip(&volume.table) {
            if let Some(b) = volume.bricks.get(bi as usize) {
                let (dmin, dmax) = slot_bounds(&volume.density_values, b.density);
                let (smin, smax) = slot_bounds(&volume.source_values, b.source);
                let (amin, amax) = albedo_bounds(volume, b);
                *node = NodeBounds { density_min: dmin, density_max: dmax, source_min: smin, source_max: smax, albedo_min: amin, albedo_max: amax };
            }
        }
        let mut levels = vec![base];
        while levels.last().is_some_and(|l| l.dims.cmpgt(IVec3::ONE).any()) {
            let prev = levels.last().expect("invariant: at least one level");
            let nd = (prev.dims + 1) / 2;
            let mut nodes = Vec::with_capacity((nd.x * nd.y * nd.z) as usize);
            for z in 0..nd.z {
                for y in 0..nd.y {
                    for x in 0..nd.x {
                        let mut acc: Option<NodeBounds> = None;
                        for dz in 0..2 {
                            for dy in 0..2 {
                                for dx in 0..2 {
                                    let c = IVec3::new(2 * x + dx, 2 * y + dy, 2 * z + dz);
                                    // Cells beyond the table are empty space: zero.
                                    let v = if c.cmplt(prev.dims).all() { *prev.get(c) } else { NodeBounds::ZERO };
                                    acc = Some(acc.map_or(v, |a| a.union(v)));
                                }
                            }
                        }
                        nodes.push(acc.expect("invariant: 8 children"));
                    }
                }
            }
            levels.push(Level { dims: nd, nodes });
        }
        Pyramid { levels }
    }

    /// Heap bytes.
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        self.levels.iter().map(|l| l.nodes.len() * std::mem::size_of::<NodeBounds>()).sum()
    }

    /// Edge of a level-`k` node in voxels.
    #[must_use]
    pub fn node_voxels(k: usize) -> i32 {
        BRICK << k
    }
}
