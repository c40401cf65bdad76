//! Volume data: sparse 8³ bricks in index space, the min/max pyramid, the hierarchical
//! DDA that turns a ray into [`Segment`]s (or, over the dual cells of [`trilinear`]
//! reconstruction, cubic pieces), and analytic test fields.
//!
//! This is the *data* half of plume. The optics (`crate::medium`) see the volume only
//! through [`Field::segments`]: an ordered, gap-free sequence of constant-valued pieces
//! of the ray. Nothing downstream indexes a voxel.

pub mod brick;
pub mod builder;
pub mod dda;
pub mod field;
pub mod majorant;
pub mod motion;
pub mod prefetch;
pub mod proxy;
pub mod pyramid;
pub mod storage;
pub mod trilinear;
pub mod velocity;

pub use brick::Volume;

/// How voxel values are reconstructed between voxel centres.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Interpolation {
    /// Each voxel constant over its box `[k − ½, k + ½]³`: the paper's piecewise-constant
    /// volume, exact and fastest; shows voxel blocks in close-ups.
    Nearest,
    /// Trilinear between voxel centres, OpenVDB's `BoxSampler` convention (`trilinear`,
    /// METHOD.md §12); exact tracking on dual cells.
    #[default]
    Linear,
}
pub use field::{Bounds3, Field, Segment, VoxelValues};
