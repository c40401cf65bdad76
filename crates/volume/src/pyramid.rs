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

use crate::layout::{BRICK, NO_BRICK};
use crate::out_of_core::storage::Buffer;

/// Value bounds of one pyramid node.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
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
    /// Bounds of empty space (no brick): density and source 0, albedo 1.
    pub const ZERO: NodeBounds = NodeBounds {
        density_min: 0.0,
        density_max: 0.0,
        source_min: 0.0,
        source_max: 0.0,
        albedo_min: 1.0,
        albedo_max: 1.0,
    };

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
        if self.density_max == 0.0 {
            1.0
        } else {
            self.albedo_max
        }
    }

    /// Bounds of both nodes' footprints together.
    #[must_use]
    pub fn union(self, o: NodeBounds) -> NodeBounds {
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
#[derive(Debug, Default)]
pub struct Level {
    /// Nodes per axis.
    pub dims: IVec3,
    /// Nodes, x fastest.
    pub nodes: Buffer<NodeBounds>,
}

impl Level {
    /// Node at level coordinate `c` (must be inside `dims`).
    #[inline]
    #[must_use]
    pub fn get(&self, c: IVec3) -> &NodeBounds {
        &self.nodes[c.x as usize
            + self.dims.x as usize * (c.y as usize + self.dims.y as usize * c.z as usize)]
    }
}

/// The min/max pyramid: `levels[0]` per brick, the last level a single node.
#[derive(Debug, Default)]
pub struct Pyramid {
    /// Levels from finest (bricks) to coarsest (root).
    pub levels: Vec<Level>,
}

/// Node counts per axis of every level for a brick table of `dims`: level 0 is `dims`,
/// each next level halves (rounding up) until a single node.
#[must_use]
pub fn level_dims(dims: IVec3) -> Vec<IVec3> {
    if dims.cmple(IVec3::ZERO).any() {
        return Vec::new();
    }
    let mut out = vec![dims];
    while let Some(&d) = out.last().filter(|d| d.cmpgt(IVec3::ONE).any()) {
        out.push((d + 1) / 2);
    }
    out
}

impl Pyramid {
    /// Build all levels over a brick table of `dims`, where `bounds[i]` are the bounds of
    /// brick `i` (`table` maps cells to bricks; cells without a brick count as
    /// [`NodeBounds::ZERO`]).
    #[must_use]
    pub fn from_brick_bounds(dims: IVec3, table: &[u32], bounds: &[NodeBounds]) -> Pyramid {
        let base: Vec<NodeBounds> = table
            .iter()
            .map(|&bi| if bi == NO_BRICK { NodeBounds::ZERO } else { bounds[bi as usize] })
            .collect();
        Pyramid::from_base(dims, base)
    }

    /// Build all levels over a table of `dims` cells whose level-0 nodes are `base` (x
    /// fastest): each coarser node is the union of its 2×2×2 children, cells beyond the
    /// table counting as [`NodeBounds::ZERO`].
    ///
    /// # Panics
    /// If `base` does not hold one node per cell.
    #[must_use]
    pub fn from_base(dims: IVec3, base: Vec<NodeBounds>) -> Pyramid {
        let all = level_dims(dims);
        if all.is_empty() {
            return Pyramid::default();
        }
        assert_eq!(
            base.len(),
            (dims.x * dims.y * dims.z) as usize,
            "one level-0 node per table cell"
        );
        let mut levels = vec![Level { dims, nodes: Buffer::from_vec(base) }];
        for &nd in &all[1..] {
            let prev = levels.last().expect("invariant: at least one level");
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
                                    let v = if c.cmplt(prev.dims).all() {
                                        *prev.get(c)
                                    } else {
                                        NodeBounds::ZERO
                                    };
                                    acc = Some(acc.map_or(v, |a| a.union(v)));
                                }
                            }
                        }
                        nodes.push(acc.expect("invariant: 8 children"));
                    }
                }
            }
            levels.push(Level { dims: nd, nodes: Buffer::from_vec(nodes) });
        }
        Pyramid { levels }
    }

    /// Bytes of all levels, wherever they live.
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        self.levels.iter().map(|l| l.nodes.byte_len()).sum()
    }

    /// Heap bytes of all levels (0 when mapped).
    #[must_use]
    pub fn heap_bytes(&self) -> usize {
        self.levels.iter().map(|l| l.nodes.heap_bytes()).sum()
    }

    /// Edge of a level-`k` node in voxels.
    #[must_use]
    pub fn node_voxels(k: usize) -> i32 {
        BRICK << k
    }
}
