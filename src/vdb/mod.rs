//! Reading and writing OpenVDB files.
//!
//! This module is the only place that talks to OpenVDB, through the C++ shim in `cpp/`
//! (one concept per file; `cpp/vdb_shim.h` is the header the bridge includes) bridged by
//! [`cxx`] (see `ffi.rs`). No OpenVDB type and no C++ exception crosses the bridge: every
//! call that can throw returns `Result`.
//!
//! Data comes out as plain [`FloatGrid`]s: leaf origins plus 8³ value blocks in index
//! space, and the affine `world_from_index` transform. Active tiles are voxelized into
//! leaves on the C++ side, so constant regions are never lost. A vector grid (a velocity
//! for motion blur) comes out of [`read_vec3_grid`] as three `FloatGrid`s, one per
//! component, with identical leaves and transform.
//!
//! # Conventions
//!
//! - **Grids are addressed in file order** by a [`GridSelector`]: `density` is the first
//!   grid named `density`, `density[1]` the second, and so on. (OpenVDB's `io::File`
//!   lists grids alphabetically; the shim recovers the order in which they are stored.)
//! - **Index space**: voxel `(i, j, k)` is centred at index point `(i, j, k)`, as in
//!   OpenVDB; `world_from_index` maps index points to world points.
//! - **Leaves**: [`FloatGrid::origins`] lists the file's leaves first, in OpenVDB's tree
//!   order, then one leaf-sized block per 8³ cell of each active tile (tile value
//!   everywhere). Inactive tiles are not voxelized: outside the leaves the grid reads as
//!   its background.
//! - **Types**: [`read_float_grid`] reads `float` grids (including half-float storage,
//!   which reads as float) and `double` grids (cast to `f32`); [`read_vec3_grid`] reads
//!   `vec3s` (half-float storage included) and `vec3d` grids, as components `NAME.x`,
//!   `NAME.y`, `NAME.z`. Any other type is
//!   [`Error::UnsupportedGrid`](crate::Error::UnsupportedGrid) naming it, as is a
//!   non-affine (frustum) transform. A velocity stored as three float grids (`vel.x`,
//!   `vel.y`, `vel.z`, as Houdini may write it) is three [`read_float_grid`] calls.
//! - **Memory**: [`read_float_grid`] computes the bytes its output needs (file leaves plus
//!   voxelized tiles) before allocating and refuses with
//!   [`Error::TooLarge`](crate::Error::TooLarge) above [`ReadLimits::max_bytes`];
//!   [`read_vec3_grid`] does the same for three times those bytes. Header
//!   metadata such as `file_bbox_min/max` is never used to size anything.
//! - **Hostile files**: before OpenVDB parses a file, the shim walks its header and grid
//!   descriptors with every length checked against the file size, so a truncated file is
//!   an error rather than silently missing data (OpenVDB 10 itself reads a truncated file
//!   without complaint and fills the missing leaves with garbage). Values that come out
//!   NaN or infinite are rejected as corrupt.
//! - **Untrusted files** are read in a child process ([`isolate`]): a crash, hang or
//!   runaway allocation in OpenVDB becomes [`Error::ReaderFailed`](crate::Error::ReaderFailed)
//!   instead of taking plume down. The CLI reads this way by default. Vector grids too:
//!   [`ReadIsolation::read_vec3_grid`] / [`read_vec3_grid_isolated`].
//! - **Streaming**: [`stream_float_grid`] (and [`ReadIsolation::stream_float_grid`]) visit
//!   one grid block by block in bounded memory, with OpenVDB's delayed loading; the blocks
//!   and values are exactly those of [`read_float_grid`], tiles as constant blocks.
//! - **Writing** is atomic: a temp file in the target directory, then a rename.

mod ffi;
pub mod isolate;
mod read;
mod stream;
#[doc(hidden)]
pub mod wire;
mod write;

pub use isolate::{
    list_grids_isolated, read_float_grids_isolated, read_grids_isolated, read_vec3_grid_isolated,
    IsolationLimits, ReadIsolation,
};
pub use plume_scene::selector::GridSelector;
pub use plume_volume::grid::{leaf_offset, FloatGrid, LEAF_DIM, LEAF_VOXELS};
pub use read::{
    list_grids, read_float_grid, read_grids, read_vec3_grid, FoundGrid, GridRequest, ReadLimits,
};
pub(crate) use stream::FileStamp;
pub use stream::{
    stream_float_grid, stream_float_grid_isolated, HeaderVisitor, LeafData, LeafVisitor,
    StreamedGrid,
};
pub use write::{write_float_grids, write_grids, VectorGrid};

use serde::Serialize;

/// Summary of one grid in a file, as printed by `plume info`.
#[derive(Clone, Debug, Serialize)]
pub struct GridInfo {
    /// Grid name (duplicates appear once per grid, with the same name).
    pub name: String,
    /// Position of the grid in the file (0-based).
    pub file_index: usize,
    /// Selector that binds exactly this grid (`density`, or `density[1]` for the second
    /// grid named `density`).
    pub selector: String,
    /// OpenVDB value type name (`float`, `double`, `vec3s`, `int32`, …).
    #[serde(rename = "type")]
    pub value_type: String,
    /// Grid class (`fog volume`, `level set`, `staggered`, `unknown`).
    pub class: String,
    /// Active voxels, active tiles counted voxel by voxel.
    pub active_voxels: u64,
    /// Leaf nodes.
    pub leaf_count: u64,
    /// Active tiles (above leaf level).
    pub active_tiles: u64,
    /// Inclusive index bounding box of active voxels, `None` for an empty grid.
    pub index_bbox: Option<[[i32; 3]; 2]>,
    /// World size of one voxel along index x, y, z.
    pub voxel_size: [f64; 3],
    /// Transform kind: OpenVDB's map type in kebab case (`uniform-scale`,
    /// `uniform-scale-translate`, `scale`, `scale-translate`, `translation`, `unitary`,
    /// `affine`), or `frustum` for the non-linear frustum map.
    pub transform: String,
    /// Minimum of active values, tiles included (`float`, `double`, `int32`, `int64`;
    /// `vec3s`/`vec3d`: of the magnitude). `None` for an empty grid or another type.
    pub min: Option<f64>,
    /// Maximum of active values.
    pub max: Option<f64>,
    /// Mean of active values.
    pub mean: Option<f64>,
    /// In-memory size of the tree in bytes, as OpenVDB reports it.
    pub memory_bytes: u64,
}
