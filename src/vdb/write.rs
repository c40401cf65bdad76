//! Writing: [`write_float_grids`] and [`write_grids`] (with vector grids), used by the
//! procedural generator and by tests.
//!
//! Atomic: the grids are built in memory first, written to a temp file in the target
//! directory, synced, then renamed over the target. A failure at any step removes the
//! temp file, so the target is either the old file or the complete new one.

use std::fs;
use std::io;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use super::{ffi, FloatGrid, LEAF_DIM, LEAF_VOXELS};
use plume_core::error::{Error, Result};

/// Writes `grids` to one `.vdb` file at `path` (replacing it atomically).
///
/// Each grid becomes an OpenVDB `FloatGrid` of class fog volume with the grid's name,
/// transform and background; a voxel is active iff its value differs from the
/// background, and leaves that are entirely background are dropped. The file is
/// blosc-compressed and carries the file metadata `creator = plume`.
///
/// # Errors
/// [`Error::Write`] if a grid is malformed (value count not 512 per origin, an origin not
/// a multiple of 8, a singular transform), if the directory is not writable, or if
/// OpenVDB fails; no file is left behind in either case.
pub fn write_float_grids(path: &Path, grids: &[&FloatGrid]) -> Result<()> {
    write_grids(path, grids, &[])
}

/// A vector grid to write: its name and three components on the same leaves and
/// transform (their own names are not used).
#[derive(Clone, Copy, Debug)]
pub struct VectorGrid<'a> {
    /// The grid's name in the file.
    pub name: &'a str,
    /// x, y, z.
    pub components: [&'a FloatGrid; 3],
}

/// [`write_float_grids`], and `vectors` as OpenVDB `Vec3SGrid`s (background 0; a voxel
/// is active iff it is not the zero vector).
///
/// # Errors
/// As [`write_float_grids`]; components on different leaves or transforms.
pub fn write_grids(path: &Path, grids: &[&FloatGrid], vectors: &[VectorGrid<'_>]) -> Result<()> {
    let write_error = |source: io::Error| Error::Write { path: path.to_path_buf(), source };
    let invalid =
        |message: String| write_error(io::Error::new(io::ErrorKind::InvalidInput, message));

    // Build every grid before touching the file system.
    let mut writer = ffi::new_grid_writer().map_err(|e| write_error(io::Error::other(e.what())))?;
    for grid in grids {
        validate(grid).map_err(|message| invalid(format!("grid {:?}: {message}", grid.name)))?;
        let origins: Vec<i32> = grid.origins.iter().flat_map(|o| o.to_array()).collect();
        writer
            .pin_mut()
            .add_float_grid(
                &grid.name,
                &grid.world_from_index.to_cols_array(),
                grid.background,
                &origins,
                &grid.values,
            )
            .map_err(|e| write_error(io::Error::other(e.what())))?;
    }
    for v in vectors {
        let [x, y, z] = v.components;
        for c in [x, y, z] {
            validate(c).map_err(|message| invalid(format!("grid {:?}: {message}", v.name)))?;
        }
        if y.origins != x.origins
            || z.origins != x.origins
            || y.world_from_index != x.world_from_index
            || z.world_from_index != x.world_from_index
        {
            return Err(invalid(format!(
                "grid {:?}: its components have different leaves or transforms",
                v.name
            )));
        }
        let origins: Vec<i32> = x.origins.iter().flat_map(|o| o.to_array()).collect();
        writer
            .pin_mut()
            .add_vec3_grid(
                v.name,
                &x.world_from_index.to_cols_array(),
                &origins,
                &x.values,
                &y.values,
                &z.values,
            )
            .map_err(|e| write_error(io::Error::other(e.what())))?;
    }

    let temp = temp_path(path).map_err(invalid)?;
    let temp_str = temp.to_str().ok_or_else(|| invalid("path is not valid UTF-8".to_string()))?;
    fs::OpenOptions::new().write(true).create_new(true).open(&temp).map_err(write_error)?;
    let result = writer
        .write(temp_str)
        .map_err(|e| io::Error::other(e.what()))
        .and_then(|()| fs::File::open(&temp)?.sync_all())
        .and_then(|()| fs::rename(&temp, path))
        .map_err(write_error);
    if result.is_err() {
        // Best effort: the temp file may already be gone.
        let _ = fs::remove_file(&temp);
    }
    result
}

/// Checks the [`FloatGrid`] invariants the shim relies on.
fn validate(grid: &FloatGrid) -> std::result::Result<(), String> {
    if grid.values.len() != grid.origins.len() * LEAF_VOXELS {
        return Err(format!(
            "{} values for {} leaves (expected {} per leaf)",
            grid.values.len(),
            grid.origins.len(),
            LEAF_VOXELS
        ));
    }
    if let Some(origin) = grid.origins.iter().find(|o| (**o % LEAF_DIM) != glam::IVec3::ZERO) {
        return Err(format!("leaf origin {origin} is not a multiple of {LEAF_DIM}"));
    }
    let det = grid.world_from_index.matrix3.determinant();
    if !det.is_finite() || det == 0.0 || !grid.world_from_index.translation.is_finite() {
        return Err("world_from_index is singular or not finite".to_string());
    }
    Ok(())
}

/// `dir/.name.<pid>.<n>.tmp`, beside the target so that the rename stays on one file system.
fn temp_path(path: &Path) -> std::result::Result<PathBuf, String> {
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let file_name =
        path.file_name().ok_or_else(|| "not a file path".to_string())?.to_string_lossy();
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let temp_name = format!(".{file_name}.{}.{n}.tmp", std::process::id());
    Ok(path.with_file_name(temp_name))
}
