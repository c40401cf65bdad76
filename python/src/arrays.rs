//! Dense arrays as sparse grids: `VolumeData` holds the float grids (and a velocity) made
//! from NumPy arrays, as the 8³ leaves a VDB file holds, and `write_vdb` writes them.
//!
//! **Layout.** Array element `a[i, j, k]` is voxel `(i, j, k)` of the grid's index space
//! (OpenVDB's: voxel centres at integer coordinates), whatever the array's memory order;
//! leaf `b` covers voxels `8b … 8b + 7` and voxels past the array's end are the
//! background. A leaf whose 512 voxels all equal the background is not stored, so memory
//! is that of the leaves that hold something, as in a file.
//!
//! **Values.** `float32` in any memory layout (the Python layer converts `float64`); each
//! array is copied once, in C order, while its leaves are built. A non-finite value
//! is refused, naming the grid, the count and the first voxel: a VDB file holding one is
//! refused as corrupt too.

use std::path::PathBuf;

use glam::{DAffine3, DMat3, DVec3, IVec3};
use pyo3::buffer::PyBuffer;
use pyo3::prelude::*;

use crate::{to_py, InputError};
use plume::vdb::{leaf_offset, write_grids, FloatGrid, VectorGrid, LEAF_VOXELS};

/// Float grids (and a velocity) made from dense arrays, in memory.
#[pyclass(module = "plume._plume", name = "VolumeData")]
pub struct VolumeData {
    pub(crate) world_from_index: DAffine3,
    pub(crate) background: f32,
    pub(crate) grids: Vec<FloatGrid>,
    /// The velocity's name and its x, y, z components on the same leaves.
    pub(crate) velocity: Option<(String, [FloatGrid; 3])>,
}

/// A 3-dimensional `float32` array, copied in C order, indexed by voxel.
struct Dense {
    values: Vec<f32>,
    shape: [usize; 3],
}

impl Dense {
    #[inline]
    fn at(&self, i: usize, j: usize, k: usize) -> f32 {
        let [_, ny, nz] = self.shape;
        self.values[(i * ny + j) * nz + k]
    }
}

/// `array`, a 3-dimensional float32 buffer of any layout, copied once in C order, its
/// values checked finite (the count and first voxel of those that are not).
fn dense(py: Python<'_>, array: &Bound<'_, PyAny>, name: &str) -> PyResult<Dense> {
    let buffer = PyBuffer::<f32>::get(array).map_err(|e| {
        InputError::new_err(format!("grid {name:?}: not a float32 array buffer ({e})"))
    })?;
    let shape = buffer.shape().to_vec();
    if shape.len() != 3 {
        return Err(InputError::new_err(format!(
            "grid {name:?}: a {}-dimensional array; a grid is 3-dimensional (nx, ny, nz)",
            shape.len()
        )));
    }
    let dense = Dense { values: buffer.to_vec(py)?, shape: [shape[0], shape[1], shape[2]] };
    let count = dense.values.iter().filter(|v| !v.is_finite()).count();
    if let Some(o) = dense.values.iter().position(|v| !v.is_finite()) {
        let [_, ny, nz] = dense.shape;
        let first = (o / (ny * nz), o / nz % ny, o % nz);
        return Err(InputError::new_err(format!(
            "grid {name:?}: {count} voxels are NaN or infinite (the first at index {first:?})"
        )));
    }
    Ok(dense)
}

/// The leaves of `dense` that hold a voxel other than `background`, in order of
/// `(x, y, z)`.
fn leaves(dense: &Dense, background: f32) -> Vec<IVec3> {
    let [nx, ny, nz] = dense.shape;
    let mut out = Vec::new();
    for bx in 0..nx.div_ceil(8) {
        for by in 0..ny.div_ceil(8) {
            for bz in 0..nz.div_ceil(8) {
                let holds = (8 * bx..(8 * bx + 8).min(nx)).any(|i| {
                    (8 * by..(8 * by + 8).min(ny)).any(|j| {
                        (8 * bz..(8 * bz + 8).min(nz)).any(|k| dense.at(i, j, k) != background)
                    })
                });
                if holds {
                    out.push(IVec3::new(8 * bx as i32, 8 * by as i32, 8 * bz as i32));
                }
            }
        }
    }
    out
}

/// The values of `dense` on `origins`' leaves, in OpenVDB's leaf order.
fn gather(dense: &Dense, origins: &[IVec3], background: f32) -> Vec<f32> {
    let [nx, ny, nz] = dense.shape;
    let mut values = vec![background; origins.len() * LEAF_VOXELS];
    for (leaf, o) in origins.iter().enumerate() {
        let block = &mut values[leaf * LEAF_VOXELS..(leaf + 1) * LEAF_VOXELS];
        for x in 0..8 {
            for y in 0..8 {
                for z in 0..8 {
                    let (i, j, k) = ((o.x + x) as usize, (o.y + y) as usize, (o.z + z) as usize);
                    if i < nx && j < ny && k < nz {
                        block[leaf_offset(x, y, z)] = dense.at(i, j, k);
                    }
                }
            }
        }
    }
    values
}

#[pymethods]
impl VolumeData {
    /// An empty set of grids with the index-to-world map `world_from_index` (three rows
    /// of an affine 4×4 matrix) and `background`.
    #[new]
    fn new(world_from_index: [[f64; 4]; 3], background: f32) -> PyResult<VolumeData> {
        let [r0, r1, r2] = world_from_index;
        let linear = DMat3::from_cols(
            DVec3::new(r0[0], r1[0], r2[0]),
            DVec3::new(r0[1], r1[1], r2[1]),
            DVec3::new(r0[2], r1[2], r2[2]),
        );
        let det = linear.determinant();
        if !det.is_finite() || det == 0.0 || !background.is_finite() {
            return Err(InputError::new_err(
                "the index-to-world transform must be finite and invertible, the background finite",
            ));
        }
        Ok(VolumeData {
            world_from_index: DAffine3::from_mat3_translation(
                linear,
                DVec3::new(r0[3], r1[3], r2[3]),
            ),
            background,
            grids: Vec::new(),
            velocity: None,
        })
    }

    /// Add the float grid `name` from the 3-dimensional float32 `array`.
    fn add_grid(&mut self, py: Python<'_>, name: String, array: &Bound<'_, PyAny>) -> PyResult<()> {
        let background = self.background;
        let dense = dense(py, array, &name)?;
        let origins = leaves(&dense, background);
        let values = gather(&dense, &origins, background);
        let grid = FloatGrid {
            name: name.clone(),
            world_from_index: self.world_from_index,
            background,
            origins,
            values,
        };
        self.grids.retain(|g| g.name != name);
        self.grids.push(grid);
        Ok(())
    }

    /// Add the vector grid `name` from its three 3-dimensional float32 components, stored
    /// on the leaves where any component differs from 0.
    fn add_vector(
        &mut self,
        py: Python<'_>,
        name: String,
        x: &Bound<'_, PyAny>,
        y: &Bound<'_, PyAny>,
        z: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let mut components = Vec::with_capacity(3);
        for (c, a) in ["x", "y", "z"].iter().zip([x, y, z]) {
            let label = format!("{name}.{c}");
            let d = dense(py, a, &label)?;
            components.push((label, d));
        }
        // One topology: the leaves where any component differs from 0
        let mut topology: Vec<IVec3> =
            components.iter().flat_map(|(_, d)| leaves(d, 0.0)).collect();
        topology.sort_by_key(|o| (o.x, o.y, o.z));
        topology.dedup();
        let components: Vec<FloatGrid> = components
            .into_iter()
            .map(|(label, d)| FloatGrid {
                name: label,
                world_from_index: self.world_from_index,
                background: 0.0,
                values: gather(&d, &topology, 0.0),
                origins: topology.clone(),
            })
            .collect();
        let [cx, cy, cz]: [FloatGrid; 3] =
            components.try_into().map_err(|_| InputError::new_err("three components"))?;
        self.velocity = Some((name, [cx, cy, cz]));
        Ok(())
    }

    /// The names of the float grids held.
    #[getter]
    fn grid_names(&self) -> Vec<String> {
        self.grids.iter().map(|g| g.name.clone()).collect()
    }

    /// Leaves stored per float grid, by name.
    #[getter]
    fn leaf_counts(&self) -> Vec<(String, usize)> {
        self.grids.iter().map(|g| (g.name.clone(), g.origins.len())).collect()
    }

    /// Write the grids to the `.vdb` file `path` (atomically).
    fn write(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| self.write_to(&path)).map_err(|e| to_py(&e))
    }
}

impl VolumeData {
    /// Write the grids (and the velocity as a vector grid) to `path`.
    pub(crate) fn write_to(&self, path: &std::path::Path) -> plume::Result<()> {
        let grids: Vec<&FloatGrid> = self.grids.iter().collect();
        let vectors: Vec<VectorGrid<'_>> = self
            .velocity
            .iter()
            .map(|(name, [x, y, z])| VectorGrid { name, components: [x, y, z] })
            .collect();
        write_grids(path, &grids, &vectors)
    }
}

/// Write `data`'s grids to the `.vdb` file `path`.
#[pyfunction]
pub fn write_vdb(py: Python<'_>, path: PathBuf, data: &VolumeData) -> PyResult<()> {
    py.detach(|| data.write_to(&path)).map_err(|e| to_py(&e))
}
