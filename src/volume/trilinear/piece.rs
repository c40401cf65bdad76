//! [`CubicSegment`]: one dual cell's piece of a ray, and its [`Piece`] maths
//! (METHOD.md §12).

use glam::DVec3;

use super::poly;
use crate::color::Rgb;
use crate::volume::field::{Piece, Segment, VoxelValues};

/// A piece of a ray inside one dual cell (or a constant run of them).
///
/// Corner `c` (bit 0: +x, bit 1: +y, bit 2: +z) is voxel `i + c` of the dual cell `i`.
/// Along the piece, the cell-local coordinates are `f(u) = f0 + d u`, `u ∈ [0, t1 − t0]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CubicSegment {
    /// Entry distance.
    pub t0: f64,
    /// Exit distance.
    pub t1: f64,
    /// `ρ(u) = Σ_j density[j] uʲ`, from [`poly::cubic_along`].
    pub density: [f64; 4],
    /// Cell-local coordinates at `u = 0`, each in `[0, 1]`.
    pub f0: DVec3,
    /// Index-space direction per world unit (`df/du`).
    pub d: DVec3,
    /// Density and source of the 8 corner voxels.
    pub corners: [VoxelValues; 8],
    /// Albedo factors of the 8 corner voxels (1 where density is 0).
    pub albedo: [f32; 8],
    /// True when all corners agree (e.g. a uniform pyramid node, or empty space): the
    /// piece is one [`Segment`].
    pub constant: bool,
}
