//! Reading: [`list_grids`] for `plume info`, [`read_float_grid`] for rendering,
//! [`read_vec3_grid`] for velocities (motion blur).
//!
//! Both check the path in Rust first (exists, regular file, OpenVDB magic number; a
//! NanoVDB file gets its own message), then call the shim.

use std::collections::HashMap;
use std::fs;
use std::io::{self, Read};
use std::path::Path;

use glam::{DAffine3, IVec3};

use super::ffi;
use super::{FloatGrid, GridInfo, GridSelector, LEAF_VOXELS};
use plume_core::error::{Error, Result};
use plume_volume::out_of_core::memory::MemoryLimits;

/// OpenVDB's magic number, the int64 `0x56444220` (" BDV") in little-endian order.
const OPENVDB_MAGIC: [u8; 8] = [0x20, 0x42, 0x44, 0x56, 0, 0, 0, 0];
/// NanoVDB files start with `NanoVDB0` (grid buffers) or `NanoVDB1`/`NanoVDB2`.
const NANOVDB_MAGIC_PREFIX: &[u8] = b"NanoVDB";

/// Output bytes per leaf: 512 `f32` values plus an `i32` origin triple.
pub(crate) const BYTES_PER_LEAF: u64 = (LEAF_VOXELS * 4 + 3 * 4) as u64;

/// Resource limits for [`read_float_grid`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReadLimits {
    /// Most bytes the voxelized output of one grid may occupy (values and leaf origins).
    pub max_bytes: u64,
}

impl Default for ReadLimits {
    /// Half of physical memory or of this process's cgroup memory limit, whichever is
    /// smaller; 4 GiB where the OS does not say ([`MemoryLimits::default_budget`]).
    fn default() -> ReadLimits {
        ReadLimits { max_bytes: MemoryLimits::read().default_budget() }
    }
}

/// Summaries of every grid in the file at `path`, in file order.
///
/// Reads each grid's tree (one at a time) to count voxels and compute value statistics.
///
/// # Errors
/// [`Error::Open`] if the file is missing or not a regular file; [`Error::Vdb`] if it is
/// not a readable OpenVDB file (including NanoVDB files and truncated files).
pub fn list_grids(path: &Path) -> Result<Vec<GridInfo>> {
    let path_str = check_file(path)?;
    let summaries = ffi::list_grids(path_str).map_err(|e| vdb_error(path, &e))?;
    let mut occurrences: HashMap<String, usize> = HashMap::new();
    let infos = summaries
        .into_iter()
        .enumerate()
        .map(|(file_index, s)| {
            let occurrence = occurrences.entry(s.name.clone()).or_insert(0);
            let selector = GridSelector { name: s.name.clone(), occurrence: *occurrence };
            *occurrence += 1;
            GridInfo {
                selector: selector.to_string(),
                name: s.name,
                file_index,
                value_type: s.value_type,
                class: s.grid_class,
                active_voxels: s.active_voxels,
                leaf_count: s.leaf_count,
                active_tiles: s.active_tiles,
                index_bbox: s.has_bbox.then_some([s.bbox_min, s.bbox_max]),
                voxel_size: s.voxel_size,
                transform: s.transform,
                min: s.has_stats.then_some(s.min),
                max: s.has_stats.then_some(s.max),
                mean: s.has_stats.then_some(s.mean),
                memory_bytes: s.memory_bytes,
            }
        })
        .collect();
    Ok(infos)
}

/// Reads one scalar grid as a [`FloatGrid`], voxelizing its active tiles.
///
/// `float` and `double` grids are accepted (doubles are cast to `f32`; half-float storage
/// reads as float). Leaves come out in OpenVDB tree order, followed by one leaf-sized
/// block per 8³ cell of every active tile, filled with the tile value.
///
/// See also [`read_vec3_grid`] for vector grids.
///
/// # Errors
/// - [`Error::Open`]: the file is missing or not a regular file.
/// - [`Error::Vdb`]: not a readable OpenVDB file, or it holds NaN/infinite values.
/// - [`Error::GridNotFound`]: no grid matches `selector`; the error lists the selectors
///   that exist.
/// - [`Error::UnsupportedGrid`]: the grid is not `float`/`double`, or its transform is
///   not affine (e.g. a frustum).
/// - [`Error::TooLarge`]: the voxelized grid would need more than `limits.max_bytes`.
pub fn read_float_grid(
    path: &Path,
    selector: &GridSelector,
    limits: &ReadLimits,
) -> Result<FloatGrid> {
    let path_str = check_file(path)?;
    let reader = ffi::open_float_grid(path_str, &selector.name, selector.occurrence)
        .map_err(|e| vdb_error(path, &e))?;
    let header = reader.header().map_err(|e| vdb_error(path, &e))?;
    check_status(path, path_str, selector, header.status, &header.value_type, &header.transform)?;

    let output = Output::new(
        path,
        selector,
        header.leaf_count,
        header.tile_leaf_count,
        BYTES_PER_LEAF,
        limits,
    )?;
    let mut origins = output.buffer::<i32>(3)?;
    let mut values = output.buffer::<f32>(LEAF_VOXELS)?;
    reader.copy_leaves(&mut origins, &mut values).map_err(|e| vdb_error(path, &e))?;

    check_finite(path, selector, &[&values], &[header.background])?;
    Ok(FloatGrid {
        name: selector.name.clone(),
        world_from_index: DAffine3::from_cols_array(&header.world_from_index),
        background: header.background,
        origins: origins.chunks_exact(3).map(IVec3::from_slice).collect(),
        values,
    })
}

/// A vector grid as three float grids sharing leaves and transform (names `NAME.x`,
/// `NAME.y`, `NAME.z`).
///
/// `vec3s` grids (half-float storage included, which reads as float) and `vec3d` grids
/// (cast to `f32`) are accepted, e.g. Blender's `velocity` or Houdini's `vel`. The three
/// grids have identical [`FloatGrid::origins`], in the order [`read_float_grid`] uses (file
/// leaves in tree order, then one block per 8³ cell of every active tile, each component
/// filled with the tile's component), the grid's `world_from_index`, and as background
/// the matching component of the vector background. `NAME` is the bare grid name (for a
/// selector `vel[1]`, `vel.x`, …).
///
/// A velocity stored as three float grids (`vel.x`, `vel.y`, `vel.z`) is read with
/// [`read_float_grid`] once per component instead.
///
/// # Errors
/// - [`Error::Open`], [`Error::Vdb`] (NaN or infinite components included) and
///   [`Error::GridNotFound`]: as [`read_float_grid`].
/// - [`Error::UnsupportedGrid`]: the grid is not `vec3s`/`vec3d` (the message names its
///   type), or its transform is not affine.
/// - [`Error::TooLarge`]: the three voxelized components would need more than
///   `limits.max_bytes`, that is 3 × what a float grid of the same leaves needs.
pub fn read_vec3_grid(
    path: &Path,
    selector: &GridSelector,
    limits: &ReadLimits,
) -> Result<[FloatGrid; 3]> {
    let path_str = check_file(path)?;
    let reader = ffi::open_vec3_grid(path_str, &selector.name, selector.occurrence)
        .map_err(|e| vdb_error(path, &e))?;
    let header = reader.header().map_err(|e| vdb_error(path, &e))?;
    check_status(path, path_str, selector, header.status, &header.value_type, &header.transform)?;

    // Three FloatGrids, each with its own copy of the origins
    let output = Output::new(
        path,
        selector,
        header.leaf_count,
        header.tile_leaf_count,
        VEC3_BYTES_PER_LEAF,
        limits,
    )?;
    let mut origins = output.buffer::<i32>(3)?;
    let mut x = output.buffer::<f32>(LEAF_VOXELS)?;
    let mut y = output.buffer::<f32>(LEAF_VOXELS)?;
    let mut z = output.buffer::<f32>(LEAF_VOXELS)?;
    reader.copy_leaves(&mut origins, &mut x, &mut y, &mut z).map_err(|e| vdb_error(path, &e))?;
    drop(reader);

    check_finite(path, selector, &[&x, &y, &z], &header.background)?;
    let origins: Vec<IVec3> = origins.chunks_exact(3).map(IVec3::from_slice).collect();
    let world_from_index = DAffine3::from_cols_array(&header.world_from_index);
    let component =
        |axis: &str, values: Vec<f32>, background: f32, origins: Vec<IVec3>| FloatGrid {
            name: format!("{}.{axis}", selector.name),
            world_from_index,
            background,
            origins,
            values,
        };
    let [bx, by, bz] = header.background;
    Ok([
        component("x", x, bx, output.copy_of(&origins)?),
        component("y", y, by, output.copy_of(&origins)?),
        component("z", z, bz, origins),
    ])
}

/// Output bytes per leaf of [`read_vec3_grid`]: three component grids, each with its
/// values and its copy of the leaf origins.
pub(crate) const VEC3_BYTES_PER_LEAF: u64 = 3 * BYTES_PER_LEAF;

/// The size of a read's output, checked against [`ReadLimits::max_bytes`] before anything
/// is allocated; allocations that fail anyway become [`Error::TooLarge`].
struct Output<'a> {
    path: &'a Path,
    selector: &'a GridSelector,
    /// Output blocks: file leaves plus voxelized tile blocks.
    leaves: usize,
    needed: u64,
    limit: u64,
}

impl<'a> Output<'a> {
    /// Sizes the output from the tree (leaves + tiles), never from header metadata.
    fn new(
        path: &'a Path,
        selector: &'a GridSelector,
        leaf_count: u64,
        tile_leaf_count: u64,
        bytes_per_leaf: u64,
        limits: &ReadLimits,
    ) -> Result<Output<'a>> {
        let leaves = leaf_count.saturating_add(tile_leaf_count);
        let mut output = Output {
            path,
            selector,
            leaves: 0,
            needed: leaves.saturating_mul(bytes_per_leaf),
            limit: limits.max_bytes,
        };
        if output.needed > output.limit {
            return Err(output.too_large());
        }
        output.leaves = usize::try_from(leaves).map_err(|_| output.too_large())?;
        Ok(output)
    }

    fn too_large(&self) -> Error {
        Error::TooLarge {
            path: self.path.to_path_buf(),
            grid: self.selector.to_string(),
            needed: self.needed,
            limit: self.limit,
        }
    }

    /// A zero-filled buffer of `per_leaf` items per output leaf.
    fn buffer<T: Default + Clone>(&self, per_leaf: usize) -> Result<Vec<T>> {
        let len = per_leaf.checked_mul(self.leaves).ok_or_else(|| self.too_large())?;
        let mut v = Vec::new();
        v.try_reserve_exact(len).map_err(|_| self.too_large())?;
        v.resize(len, T::default());
        Ok(v)
    }

    /// A copy of `items`, allocated fallibly.
    fn copy_of<T: Clone>(&self, items: &[T]) -> Result<Vec<T>> {
        let mut v = Vec::new();
        v.try_reserve_exact(items.len()).map_err(|_| self.too_large())?;
        v.extend_from_slice(items);
        Ok(v)
    }
}

/// Refuses NaN or infinite values (or backgrounds) as corruption: OpenVDB reads damaged
/// leaf data without complaint.
fn check_finite(
    path: &Path,
    selector: &GridSelector,
    components: &[&[f32]],
    backgrounds: &[f32],
) -> Result<()> {
    let non_finite: usize =
        components.iter().map(|values| values.iter().filter(|v| !v.is_finite()).count()).sum();
    if non_finite == 0 && backgrounds.iter().all(|b| b.is_finite()) {
        return Ok(());
    }
    let total: usize = components.iter().map(|values| values.len()).sum();
    let what = if components.len() == 1 { "values" } else { "vector components" };
    Err(vdb_message(path, format!("grid {selector}: {non_finite} of {total} {what} (or the background) are NaN or infinite; the file is corrupt")))
}

/// The error for a grid the shim opened but cannot read, `Ok` for [`ffi::ReadStatus::Ready`].
///
/// # Errors
/// [`Error::GridNotFound`] (listing the selectors the file holds),
/// [`Error::UnsupportedGrid`] for a type the read does not take (not scalar for
/// [`read_float_grid`], not a vector for [`read_vec3_grid`]) or a non-affine transform.
pub(crate) fn check_status(
    path: &Path,
    path_str: &str,
    selector: &GridSelector,
    status: ffi::ReadStatus,
    value_type: &str,
    transform: &str,
) -> Result<()> {
    let unsupported = |message: String| Error::UnsupportedGrid {
        path: path.to_path_buf(),
        grid: selector.to_string(),
        message,
    };
    match status {
        ffi::ReadStatus::Ready => Ok(()),
        ffi::ReadStatus::NotFound => {
            Err(Error::GridNotFound { path: path.to_path_buf(), name: selector.to_string(), available: available_selectors(path, path_str)? })
        }
        ffi::ReadStatus::NotScalar => Err(unsupported(format!("value type {value_type} is not a scalar grid (plume reads float and double grids)"))),
        ffi::ReadStatus::NotVec3 => Err(unsupported(format!("value type {value_type} is not a vector grid (plume reads vec3s and vec3d grids as vectors)"))),
        ffi::ReadStatus::NonLinearTransform => Err(unsupported(format!("transform {transform} is not affine (plume needs a linear index-to-world map)"))),
        _ => Err(vdb_message(path, format!("shim returned an unknown status for {selector}"))),
    }
}

/// Selectors of every grid in the file, for [`Error::GridNotFound`].
fn available_selectors(path: &Path, path_str: &str) -> Result<Vec<String>> {
    Ok(file_selectors(path, path_str)?.iter().map(GridSelector::to_string).collect())
}

/// One selector per grid of the file, in file order.
fn file_selectors(path: &Path, path_str: &str) -> Result<Vec<GridSelector>> {
    let names = ffi::grid_names(path_str).map_err(|e| vdb_error(path, &e))?;
    let mut occurrences: HashMap<String, usize> = HashMap::new();
    Ok(names
        .into_iter()
        .map(|name| {
            let occurrence = occurrences.entry(name.clone()).or_insert(0);
            let selector = GridSelector { name, occurrence: *occurrence };
            *occurrence += 1;
            selector
        })
        .collect())
}

/// One grid a caller needs: the first of several selectors that the file holds.
///
/// `plume render --emission auto` asks for `temperature`, else `emission`, else `flame`,
/// … in one request, so that the file is opened once and only the grid used is read.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GridRequest {
    /// Selectors tried in order; the first one that exists is read. Not empty.
    pub alternatives: Vec<GridSelector>,
    /// When none exists: `true` gives [`Error::GridNotFound`] for the first alternative,
    /// `false` gives `None`.
    pub required: bool,
}

impl GridRequest {
    /// Exactly this grid; its absence is an error.
    #[must_use]
    pub fn required(selector: GridSelector) -> GridRequest {
        GridRequest { alternatives: vec![selector], required: true }
    }
}

/// The grid read for a [`GridRequest`].
#[derive(Clone, Debug)]
pub struct FoundGrid {
    /// Index into the request's `alternatives` of the grid that was read.
    pub alternative: usize,
    /// The grid.
    pub grid: FloatGrid,
}

/// Reads the grids of several requests from one file, in this process.
///
/// Returns one entry per request: the grid read, or `None` for an optional request none
/// of whose alternatives exists. [`crate::vdb::isolate`] does the same in a child process.
///
/// # Errors
/// As [`read_float_grid`]; [`Error::GridNotFound`] names a required request's first
/// alternative.
pub fn read_grids(
    path: &Path,
    requests: &[GridRequest],
    limits: &ReadLimits,
) -> Result<Vec<Option<FoundGrid>>> {
    plan_requests(path, requests)?
        .into_iter()
        .zip(requests)
        .map(|(choice, request)| {
            choice
                .map(|alternative| {
                    let grid = read_float_grid(path, &request.alternatives[alternative], limits)?;
                    Ok(FoundGrid { alternative, grid })
                })
                .transpose()
        })
        .collect()
}

/// For each request, the index of the first alternative the file holds (`None` for an
/// optional request with none). Reads the grid descriptors only.
///
/// # Errors
/// A file that cannot be opened or parsed; [`Error::GridNotFound`] for a required request
/// with no alternative in the file; [`Error::InvalidArgument`] for a request without
/// alternatives.
pub(crate) fn plan_requests(path: &Path, requests: &[GridRequest]) -> Result<Vec<Option<usize>>> {
    let path_str = check_file(path)?;
    let in_file = file_selectors(path, path_str)?;
    requests
        .iter()
        .map(|request| {
            let first = request
                .alternatives
                .first()
                .ok_or_else(|| Error::invalid("grid request", "no grid selector given"))?;
            let choice = request.alternatives.iter().position(|a| in_file.contains(a));
            if choice.is_none() && request.required {
                return Err(Error::GridNotFound {
                    path: path.to_path_buf(),
                    name: first.to_string(),
                    available: in_file.iter().map(GridSelector::to_string).collect(),
                });
            }
            Ok(choice)
        })
        .collect()
}

/// Checks that `path` is a regular OpenVDB file and returns it as UTF-8 for the shim.
pub(crate) fn check_file(path: &Path) -> Result<&str> {
    let open_error = |source: io::Error| Error::Open { path: path.to_path_buf(), source };
    let metadata = fs::metadata(path).map_err(open_error)?;
    if !metadata.is_file() {
        return Err(open_error(io::Error::new(io::ErrorKind::InvalidInput, "not a regular file")));
    }
    let mut magic = Vec::with_capacity(OPENVDB_MAGIC.len());
    fs::File::open(path)
        .and_then(|file| file.take(OPENVDB_MAGIC.len() as u64).read_to_end(&mut magic))
        .map_err(open_error)?;
    if magic.starts_with(NANOVDB_MAGIC_PREFIX) {
        return Err(vdb_message(
            path,
            format!(
                "this is a NanoVDB file, not OpenVDB; convert it with `nanovdb_convert {} out.vdb`",
                path.display()
            ),
        ));
    }
    if magic != OPENVDB_MAGIC {
        let hex: Vec<String> = magic.iter().map(|b| format!("{b:02x}")).collect();
        return Err(vdb_message(
            path,
            format!("not an OpenVDB file (starts with bytes {})", hex.join(" ")),
        ));
    }
    path.to_str().ok_or_else(|| {
        open_error(io::Error::new(io::ErrorKind::InvalidInput, "path is not valid UTF-8"))
    })
}

pub(crate) fn vdb_error(path: &Path, error: &cxx::Exception) -> Error {
    vdb_message(path, error.what().to_string())
}

pub(crate) fn vdb_message(path: &Path, message: String) -> Error {
    Error::Vdb { path: path.to_path_buf(), message }
}
