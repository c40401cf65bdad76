//! Volume data: sparse 8³ bricks in index space, the min/max pyramid, the hierarchical
//! DDA that turns a ray into [`Segment`]s (or, over the dual cells of [`trilinear`]
//! reconstruction, cubic pieces), and analytic test fields.
//!
//! This is the *data* half of plume. The optics (`plume_engine::medium`) see the volume only
//! through [`Field::segments`]: an ordered, gap-free sequence of constant-valued pieces
//! of the ray. Nothing downstream indexes a voxel.

pub use plume_scene::sets::Interpolation;
pub mod brick;
pub mod builder;
pub mod dda;
pub mod field;
pub mod grid;
pub mod instance;
pub mod layout;
pub mod majorant;
pub mod motion;
pub mod nearest;
pub mod out_of_core;
pub mod overlap;
pub mod proxy;
pub mod pyramid;
pub mod trilinear;
pub mod values;
pub mod velocity;

pub use brick::Volume;

pub use field::{Bounds3, Field, Segment, VoxelValues};
