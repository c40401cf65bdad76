//! The `cxx` bridge to the C++ shim in `cpp/` (through `cpp/vdb_shim.h`): the only
//! `unsafe` that talks to C++ (the isolated reader's process set-up has its own).
//!
//! Every C++ function is declared `-> Result`: the shim turns any exception into a
//! `std::runtime_error`, which cxx hands to Rust as a [`cxx::Exception`]. An exception
//! escaping a function *not* declared `Result` would call `std::terminate`.
//!
//! Nothing here is public outside [`crate::vdb`]; the safe API lives in `vdb/mod.rs`.

#[cxx::bridge(namespace = "plume::shim")]
mod bridge {
    /// Summary of one grid (see [`crate::vdb::GridInfo`] for the meaning of each field).
    struct GridSummary {
        name: String,
        value_type: String,
        grid_class: String,
        active_voxels: u64,
        leaf_count: u64,
        active_tiles: u64,
        /// False for an empty grid; then `bbox_min`/`bbox_max` are meaningless.
        has_bbox: bool,
        bbox_min: [i32; 3],
        bbox_max: [i32; 3],
        voxel_size: [f64; 3],
        transform: String,
        /// False for value types without statistics (bool, mask, points) and empty grids.
        has_stats: bool,
        min: f64,
        max: f64,
        mean: f64,
        memory_bytes: u64,
    }

    /// Outcome of opening one grid for reading.
    enum ReadStatus {
        /// Tree read; `header()` and `copy_leaves()` are valid.
        Ready,
        /// No grid with that name and occurrence.
        NotFound,
        /// The grid's value type is not `float` or `double` (a scalar read).
        NotScalar,
        /// The transform is not affine (e.g. a frustum).
        NonLinearTransform,
        /// The grid's value type is not `vec3s` or `vec3d` (a vector read).
        NotVec3,
    }

    /// What a [`FloatGridReader`] holds, before any value is copied.
    struct FloatGridHeader {
        status: ReadStatus,
        /// OpenVDB value type name (`float`, `vec3s`, …); empty when not found.
        value_type: String,
        /// Map kind (`uniform-scale-translate`, `affine`, `frustum`, …).
        transform: String,
        /// Columns of the 3×4 world_from_index matrix: x axis, y axis, z axis,
        /// translation (glam's `DAffine3::to_cols_array` order).
        world_from_index: [f64; 12],
        background: f32,
        /// Leaves stored in the file.
        leaf_count: u64,
        /// Leaf-sized blocks produced by voxelizing active tiles (saturating).
        tile_leaf_count: u64,
        /// Active tiles above leaf level.
        active_tiles: u64,
    }

    /// What a [`Vec3GridReader`] holds, before any value is copied; as
    /// [`FloatGridHeader`] but for three components.
    struct Vec3GridHeader {
        status: ReadStatus,
        value_type: String,
        transform: String,
        world_from_index: [f64; 12],
        /// Background of the x, y and z components.
        background: [f32; 3],
        /// Leaves stored in the file.
        leaf_count: u64,
        /// Leaf-sized blocks produced by voxelizing active tiles (saturating).
        tile_leaf_count: u64,
        /// Active tiles above leaf level.
        active_tiles: u64,
    }

    /// What a [`LeafStream`] holds after reading a grid's topology, before any leaf
    /// buffer is loaded.
    struct LeafStreamHeader {
        status: ReadStatus,
        /// As in [`FloatGridHeader`].
        value_type: String,
        transform: String,
        world_from_index: [f64; 12],
        background: f32,
        /// Leaves stored in the file (the leaves `next_leaves()` will copy).
        leaf_count: u64,
        /// False when the grid has neither leaves nor active tiles.
        has_bbox: bool,
        /// Inclusive index bounds of every leaf and active tile.
        bbox_min: [i32; 3],
        bbox_max: [i32; 3],
        /// Bytes the stream holds while open: OpenVDB's tree without leaf buffers, the
        /// list of leaf origins and the tiles.
        resident_bytes: u64,
    }

    /// An active tile above leaf level: a constant, inclusive box of voxels.
    struct ActiveTile {
        min: [i32; 3],
        max: [i32; 3],
        value: f32,
    }

    unsafe extern "C++" {
        include!("plume/cpp/vdb_shim.h");

        /// One float or double grid read into memory (opaque, owned by C++).
        type FloatGridReader;
        /// One vec3s or vec3d grid read into memory (opaque, owned by C++).
        type Vec3GridReader;
        /// Collects float grids and writes them to a file (opaque, owned by C++).
        type GridWriter;
        /// One float or double grid's topology, its leaves still in the file (opaque).
        type LeafStream;

        /// Grid names in file order, duplicates repeated; reads no tree.
        fn grid_names(path: &str) -> Result<Vec<String>>;
        /// One summary per grid in file order; reads every tree, one at a time.
        fn list_grids(path: &str) -> Result<Vec<GridSummary>>;
        /// Reads the `occurrence`-th grid named `name` (file order), unless its type or
        /// transform is unusable; the outcome is in `header().status`.
        fn open_float_grid(
            path: &str,
            name: &str,
            occurrence: usize,
        ) -> Result<UniquePtr<FloatGridReader>>;
        /// Status, transform and output size of an opened grid.
        fn header(self: &FloatGridReader) -> Result<FloatGridHeader>;
        /// Copies every leaf, then every voxelized tile block: 3 origin components and
        /// 512 values per block. The slices must match the sizes in `header()`.
        fn copy_leaves(
            self: &FloatGridReader,
            origins: &mut [i32],
            values: &mut [f32],
        ) -> Result<()>;

        /// As [`open_float_grid`] for a `vec3s` or `vec3d` grid (another type is
        /// `ReadStatus::NotVec3`).
        fn open_vec3_grid(
            path: &str,
            name: &str,
            occurrence: usize,
        ) -> Result<UniquePtr<Vec3GridReader>>;
        /// Status, transform and output size of an opened vector grid.
        fn header(self: &Vec3GridReader) -> Result<Vec3GridHeader>;
        /// Copies every leaf, then every voxelized tile block, in [`FloatGridReader`]'s
        /// order: 3 origin components per block and 512 values per block into each of `x`,
        /// `y` and `z`. The slices must match the sizes in `header()`.
        fn copy_leaves(
            self: &Vec3GridReader,
            origins: &mut [i32],
            x: &mut [f32],
            y: &mut [f32],
            z: &mut [f32],
        ) -> Result<()>;

        /// Opens the `occurrence`-th grid named `name` (file order) with delayed loading
        /// and reads its topology, unless its type or transform is unusable; the outcome
        /// is in `stream_header().status`.
        fn open_leaf_stream(
            path: &str,
            name: &str,
            occurrence: usize,
        ) -> Result<UniquePtr<LeafStream>>;
        /// Status, transform, leaf count, bounds and memory of an opened stream.
        fn stream_header(self: &LeafStream) -> Result<LeafStreamHeader>;
        /// Active tiles above leaf level, in tree order.
        fn stream_tiles(self: &LeafStream) -> Result<Vec<ActiveTile>>;
        /// Copies the next leaves in tree order into the slices (3 origin components and
        /// 512 values each, as many whole leaves as both hold), loading each from the file
        /// and freeing it once copied. Returns the number copied; 0 at the end.
        fn next_leaves(
            self: Pin<&mut LeafStream>,
            origins: &mut [i32],
            values: &mut [f32],
        ) -> Result<usize>;

        /// An empty writer.
        fn new_grid_writer() -> Result<UniquePtr<GridWriter>>;
        /// Adds one fog-volume float grid; voxels that differ from `background` are active.
        fn add_float_grid(
            self: Pin<&mut GridWriter>,
            name: &str,
            world_from_index: &[f64],
            background: f32,
            origins: &[i32],
            values: &[f32],
        ) -> Result<()>;
        /// Adds one vec3s grid (background 0) from the x, y, z value blocks of each leaf;
        /// voxels that are not the zero vector are active.
        fn add_vec3_grid(
            self: Pin<&mut GridWriter>,
            name: &str,
            world_from_index: &[f64],
            origins: &[i32],
            x: &[f32],
            y: &[f32],
            z: &[f32],
        ) -> Result<()>;
        /// Writes all added grids to `path` (truncating it), blosc-compressed.
        fn write(self: &GridWriter, path: &str) -> Result<()>;
    }
}

pub(crate) use bridge::*;
