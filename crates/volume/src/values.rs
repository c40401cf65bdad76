//! The plain values a field hands out: an axis-aligned box ([`Bounds3`]) and the channel
//! values of one voxel ([`VoxelValues`]). Shared by the field contract (`field`) and the
//! volume's bricks (`brick`), below both.

use glam::DVec3;

/// An axis-aligned box `[lo, hi]`, in the units of its space: world metres for
/// `Field::world_bounds`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[must_use]
pub struct Bounds3 {
    /// Minimum corner (componentwise smallest).
    pub lo: DVec3,
    /// Maximum corner (componentwise largest).
    pub hi: DVec3,
}

/// The channel values of one voxel (for an analytic field, of the cell or box around a
/// point): what `Field::values_at` and the nearest-voxel lookups of
/// [`crate::Volume`] return. Zero in empty space.
#[derive(Clone, Copy, Debug, PartialEq)]
#[must_use]
pub struct VoxelValues {
    /// Density ρ (unitless grid value; μ_t = σ_t ρ).
    pub density: f32,
    /// Emission source value: temperature in Kelvin after mapping and cutoff, or the
    /// emission grid's value. Zero means "emits nothing".
    pub source: f32,
}

impl VoxelValues {
    /// Empty space: density and source 0.
    pub const ZERO: VoxelValues = VoxelValues { density: 0.0, source: 0.0 };
}
