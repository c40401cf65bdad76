//! A scalar grid as plain data: leaf origins plus 8³ value blocks in index space, and the
//! affine `world_from_index` transform. This is what the VDB reader produces and what the
//! volume's bricks are built from; voxel `(i, j, k)` is centred at index point `(i, j, k)`,
//! as in OpenVDB.

use glam::{DAffine3, IVec3};

/// Voxels per leaf edge (OpenVDB's `LeafNode<float, 3>`).
pub const LEAF_DIM: i32 = 8;
/// Voxels per leaf.
pub const LEAF_VOXELS: usize = 512;

/// Offset of local voxel `(x, y, z)`, each in `0..8`, inside a leaf's value block.
///
/// Same order as OpenVDB's `LeafNode::coordToOffset`: x-major, `(x << 6) | (y << 3) | z`.
#[inline]
#[must_use]
pub const fn leaf_offset(x: i32, y: i32, z: i32) -> usize {
    (((x & 7) << 6) | ((y & 7) << 3) | (z & 7)) as usize
}

/// One scalar float grid as plain data, in index space (also one component of a vector
/// grid, see [`read_vec3_grid`]).
#[derive(Clone, Debug)]
pub struct FloatGrid {
    /// Grid name as stored in the file (for duplicates, the bare name).
    pub name: String,
    /// Affine map from index coordinates to world coordinates (voxel (i,j,k) is centred at
    /// index (i,j,k)).
    pub world_from_index: DAffine3,
    /// Value outside all leaves.
    pub background: f32,
    /// Leaf origins in index space; each component a multiple of 8.
    pub origins: Vec<IVec3>,
    /// [`LEAF_VOXELS`] values per leaf, in [`leaf_offset`] order, leaf after leaf.
    /// Inactive voxels inside a leaf keep their stored value (OpenVDB `getValue` semantics).
    pub values: Vec<f32>,
}

impl FloatGrid {
    /// Number of leaves.
    #[must_use]
    pub fn leaf_count(&self) -> usize {
        self.origins.len()
    }

    /// The value block of leaf `i`.
    ///
    /// # Panics
    /// If `i >= self.leaf_count()`.
    #[must_use]
    pub fn leaf_values(&self, i: usize) -> &[f32] {
        &self.values[i * LEAF_VOXELS..(i + 1) * LEAF_VOXELS]
    }
}
