//! The FNEE proxy grid (METHOD.md §7): a coarse grid of cells carrying emitted power, used
//! to sample *directions* towards emission and to evaluate their density.
//!
//! **Cells.** Cubes of `e` voxels on a side in index space, aligned to voxel faces and
//! starting at the volume's `index_bounds().lo`. The longest axis of the index bounds is
//! split into `resolution` cells, `e = ⌈extent/resolution⌉ ≥ 1` voxels; the other axes get
//! `⌈extent/e⌉` cells (the last cells may reach past the data into empty space). With
//! `A` the linear part of `world_from_index`, a cell's world volume is `V_j = |det A| e³`.
//!
//! **Power.** `Φ_j = Σ_{voxels i ∈ j} |det A| · Y(L_e(ρ_i, s_i))`, summed over *every* voxel
//! (dense bricks voxel by voxel, constant bricks with one call per brick), in `f64`. The
//! luminance function is passed in, so the grid stays optics-agnostic. A voxel whose
//! source is 0 emits nothing by the volume's contract (`volume::brick`) and is skipped.
//! `P_j = Φ_j/ΣΦ` lives in an `f64` alias table over the emitting cells.
//!
//! **Memory:** 8 bytes per cell (its `P_j`, 0 for a cell that emits nothing, so the
//! direction walk reads a cell's probability with one load instead of an entry and then
//! its alias slot) plus 20 bytes per emitting cell (16 for the alias slot, 4 for the
//! entry's cell index) plus 1 byte per 4³-cell block. A 64³ proxy costs at most 7.0 MiB.
//!
//! This module is the proxy's *data*: cells, their power, the alias table and the block
//! occupancy. Sampling from it (the point density `p_V`, the direction density `p_σ(ω)`
//! and the cell walk that evaluates it) is light sampling: [`plume_engine::light::fnee`].

use glam::{DAffine3, DVec3, IVec3};
use rayon::prelude::*;

use super::brick::{brick_local, PackedSlot, Slot, Volume, BRICK};
use plume_core::error::{Error, Result};
use plume_core::sampling::alias::AliasTable;

/// Edge of an occupancy block in cells: the walk crosses a block without emission in one
/// step (1 byte per 64 cells).
pub const BLOCK: i32 = 4;

/// The scene key that sets the proxy resolution (named in errors; the binary shows the
/// flag `--proxy-resolution` when it was given as one).
pub const RESOLUTION_KEY: &str = "integrator.proxy_resolution";

/// The FNEE proxy: emitted power per coarse cell. See the module docs.
///
/// The fields that [`plume_engine::light::fnee`] walks are visible to the crate; they are set only
/// here.
#[derive(Clone, Debug)]
pub struct ProxyGrid {
    /// The volume's index space to world space.
    pub world_from_index: DAffine3,
    /// World space to the volume's index space.
    pub index_from_world: DAffine3,
    /// Index-space corner of cell (0,0,0): a voxel face (half-integer).
    pub origin: DVec3,
    /// Cell edge in voxels.
    pub edge: i32,
    /// Cells per axis.
    pub dims: IVec3,
    resolution: u32,
    /// `P_j` per cell (x fastest), the alias table's own `pmf` of its entry; 0 for a cell
    /// that emits nothing.
    pub cell_pmf: Vec<f64>,
    /// Cell per alias entry.
    pub cells: Vec<u32>,
    /// Alias table over the emitting cells, by power.
    pub alias: AliasTable,
    /// `|det A| e³`, world volume of one cell.
    pub cell_volume: f64,
    /// Bounding box of the emitting cells, `[lo, hi)` in cell coordinates.
    pub occupied_lo: IVec3,
    /// One past the last emitting cell per axis.
    pub occupied_hi: IVec3,
    /// Blocks of [`BLOCK`]³ cells per axis.
    pub block_dims: IVec3,
    /// Per block (x fastest): does any of its cells emit?
    pub block_occupied: Vec<bool>,
    /// `ΣΦ_j`, luminance power of the whole volume (world volume × emission luminance).
    total_power: f64,
}

/// The paper's proxy resolution (64³), used when the user gives none.
pub const DEFAULT_RESOLUTION: u32 = 64;

impl ProxyGrid {
    /// The largest valid resolution for `volume`: the smallest power of two ≥ its longest
    /// axis in voxels (one cell per voxel), at least 8.
    #[must_use]
    pub fn max_resolution(volume: &Volume) -> u32 {
        let longest = (volume.dims * BRICK).max_element().max(8);
        (longest as u32).next_power_of_two()
    }

    /// `--proxy-resolution` when given, else [`DEFAULT_RESOLUTION`] capped at
    /// [`ProxyGrid::max_resolution`] (so small volumes work without the flag).
    #[must_use]
    pub fn resolution_for(volume: &Volume, requested: Option<u32>) -> u32 {
        requested.unwrap_or_else(|| DEFAULT_RESOLUTION.min(Self::max_resolution(volume)))
    }
}

/// Check `resolution` against the data: a power of two from 8 up to the smallest power of
/// two ≥ the longest axis in voxels (which gives one cell per voxel). An empty volume
/// (`None`) only needs a power of two ≥ 8.
fn validate_resolution(resolution: u32, longest_voxels: Option<i32>) -> Result<()> {
    let power_of_two = resolution.is_power_of_two() && resolution >= 8;
    match longest_voxels {
        None if !power_of_two => {
            Err(Error::invalid(RESOLUTION_KEY, format!("{resolution} is not a power of two ≥ 8")))
        }
        Some(longest)
            if !power_of_two || resolution > (longest.max(8) as u32).next_power_of_two() =>
        {
            let max = (longest.max(8) as u32).next_power_of_two();
            Err(Error::invalid(
                RESOLUTION_KEY,
                format!(
                    "{resolution} is not a power of two between 8 and {max} (the volume spans {longest} voxels \
                     along its longest axis; {max} gives one cell per voxel)"
                ),
            ))
        }
        _ => Ok(()),
    }
}

/// Emitted power summed per proxy cell, before normalisation: what a brick cache stores
/// so that opening it does not need a pass over every voxel.
#[derive(Clone, Debug, PartialEq)]
pub struct CellPower {
    /// Cells along the longest axis.
    pub resolution: u32,
    /// `Σ_{voxels in cell} power(ρ, s)` per cell (x fastest), without the voxel volume.
    pub sums: Vec<f64>,
}

/// Cell edge (voxels) and cells per axis for `resolution`, or `None` for an empty volume.
fn cell_layout(volume: &Volume, resolution: u32) -> Result<Option<(i32, IVec3)>> {
    let (_, brick_dims) = volume.brick_range();
    if volume.is_empty() {
        validate_resolution(resolution, None)?;
        return Ok(None);
    }
    let extent = brick_dims * BRICK;
    let longest = extent.max_element();
    validate_resolution(resolution, Some(longest))?;
    let edge = (longest as u32).div_ceil(resolution) as i32;
    let dims = (extent + (edge - 1)) / edge;
    let count = dims.x as u64 * dims.y as u64 * dims.z as u64;
    if count >= u64::from(u32::MAX) {
        return Err(Error::invalid(RESOLUTION_KEY, format!("{resolution} needs {count} proxy cells, more than plume supports; choose a smaller resolution")));
    }
    Ok(Some((edge, dims)))
}

impl CellPower {
    /// Sum `power(density, source)` over every emitting voxel of `volume` into the cells
    /// of a proxy of `resolution`, one z-layer of cells per task (a fixed order, so the
    /// sums do not depend on the thread count). `Ok(None)` for an empty volume.
    ///
    /// # Errors
    /// As [`ProxyGrid::build`].
    pub fn sum(
        volume: &Volume,
        resolution: u32,
        power: impl Fn(f32, f32) -> f64 + Sync,
    ) -> Result<Option<CellPower>> {
        let Some((edge, dims)) = cell_layout(volume, resolution)? else { return Ok(None) };
        let (brick_lo, brick_dims) = volume.brick_range();
        let extent = brick_dims * BRICK;
        let voxel_lo = brick_lo * BRICK;
        let layers: Vec<(Vec<f64>, Option<BadPower>)> = (0..dims.z)
            .into_par_iter()
            .map(|cz| layer_power(volume, &power, voxel_lo, extent, edge, dims, cz))
            .collect();
        if let Some(bad) = layers.iter().find_map(|l| l.1) {
            return Err(Error::Scene(format!(
                "emitted power {} at voxel {} (density {}, source {}) is negative or not finite",
                bad.power, bad.voxel, bad.density, bad.source
            )));
        }
        Ok(Some(CellPower { resolution, sums: layers.into_iter().flat_map(|l| l.0).collect() }))
    }
}

/// What goes wrong while summing power (reported after the parallel pass).
#[derive(Clone, Copy, Debug)]
struct BadPower {
    voxel: IVec3,
    density: f32,
    source: f32,
    power: f64,
}

impl ProxyGrid {
    /// Build the proxy of `volume` with `resolution` cells along its longest axis.
    ///
    /// `power(density, source)` is the luminance of the emission density, `Y(L_e)`, per
    /// unit world volume (any consistent unit); it is called once per emitting voxel (once
    /// per constant brick), in parallel.
    ///
    /// Returns `Ok(None)` when nothing emits.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for `--proxy-resolution` when `resolution` is not a power
    /// of two from 8 up to the data resolution, or when the grid would need more than
    /// `u32::MAX` cells; [`Error::Scene`] when `power` returns a negative or non-finite value
    /// or the total power overflows.
    pub fn build(
        volume: &Volume,
        resolution: u32,
        power: impl Fn(f32, f32) -> f64 + Sync,
    ) -> Result<Option<ProxyGrid>> {
        match CellPower::sum(volume, resolution, power)? {
            Some(cells) => ProxyGrid::from_cell_power(volume, &cells),
            None => Ok(None),
        }
    }

    /// The proxy from per-cell power sums (from [`CellPower::sum`], or stored in a brick
    /// cache file): bit-identical to [`ProxyGrid::build`] for the same sums.
    ///
    /// Returns `Ok(None)` when nothing emits.
    ///
    /// # Errors
    /// Sums that do not fit `volume` at their resolution, or a non-finite total.
    pub fn from_cell_power(volume: &Volume, power: &CellPower) -> Result<Option<ProxyGrid>> {
        let Some((edge, dims)) = cell_layout(volume, power.resolution)? else { return Ok(None) };
        if power.sums.len() != dims.x as usize * dims.y as usize * dims.z as usize {
            return Err(Error::Scene(format!(
                "proxy power holds {} cells, but resolution {} needs {}x{}x{}",
                power.sums.len(),
                power.resolution,
                dims.x,
                dims.y,
                dims.z
            )));
        }
        let resolution = power.resolution;
        let layer_len = dims.x as usize * dims.y as usize;
        let voxel_volume = volume.voxel_volume();
        let mut cells = Vec::new();
        let mut weights = Vec::new();
        let mut occupied_lo = IVec3::MAX;
        let mut occupied_hi = IVec3::MIN;
        for (cz, layer) in power.sums.chunks(layer_len).enumerate() {
            for (k, &sum) in layer.iter().enumerate() {
                if !(sum >= 0.0 && sum.is_finite()) {
                    return Err(Error::Scene(format!(
                        "proxy cell power {sum} is negative or not finite"
                    )));
                }
                if sum > 0.0 {
                    let cell = k + cz * layer.len();
                    let c = IVec3::new(
                        (k % dims.x as usize) as i32,
                        (k / dims.x as usize) as i32,
                        cz as i32,
                    );
                    occupied_lo = occupied_lo.min(c);
                    occupied_hi = occupied_hi.max(c + 1);
                    cells.push(cell as u32);
                    weights.push(voxel_volume * sum);
                }
            }
        }
        if weights.is_empty() {
            return Ok(None);
        }
        let total_power: f64 = weights.iter().sum();
        let Some(alias) = AliasTable::new(&weights) else {
            return Err(Error::Scene(format!(
                "total emitted power {total_power} of the volume is not finite"
            )));
        };
        let mut cell_pmf = vec![0.0; power.sums.len()];
        for (i, &cell) in cells.iter().enumerate() {
            cell_pmf[cell as usize] = alias.pmf(i);
        }
        let block_dims = (dims + (BLOCK - 1)) / BLOCK;
        let mut block_occupied = vec![false; (block_dims.x * block_dims.y * block_dims.z) as usize];
        for &cell in &cells {
            let c = IVec3::new(
                (cell % dims.x as u32) as i32,
                ((cell / dims.x as u32) % dims.y as u32) as i32,
                (cell / (dims.x as u32 * dims.y as u32)) as i32,
            ) / BLOCK;
            block_occupied[(c.x + block_dims.x * (c.y + block_dims.y * c.z)) as usize] = true;
        }
        let e = f64::from(edge);
        Ok(Some(ProxyGrid {
            world_from_index: volume.world_from_index(),
            index_from_world: volume.index_from_world(),
            origin: volume.index_bounds().lo,
            edge,
            dims,
            resolution,
            cell_pmf,
            cells,
            alias,
            cell_volume: voxel_volume * e * e * e,
            occupied_lo,
            occupied_hi,
            block_dims,
            block_occupied,
            total_power,
        }))
    }

    /// The requested resolution (cells along the longest axis).
    #[must_use]
    pub fn resolution(&self) -> u32 {
        self.resolution
    }

    /// Cells per axis.
    #[must_use]
    pub fn dims(&self) -> IVec3 {
        self.dims
    }

    /// Cell edge in voxels.
    #[must_use]
    pub fn cell_edge_voxels(&self) -> i32 {
        self.edge
    }

    /// Number of cells, emitting or not.
    #[must_use]
    pub fn cell_count(&self) -> usize {
        self.cell_pmf.len()
    }

    /// Number of cells with positive power.
    #[must_use]
    pub fn emitting_cell_count(&self) -> usize {
        self.cells.len()
    }

    /// World volume of one cell, `|det A| e³`.
    #[must_use]
    pub fn cell_volume(&self) -> f64 {
        self.cell_volume
    }

    /// `ΣΦ_j`: the volume's emitted luminance power (`|det A| Σ Y(L_e)` over all voxels).
    #[must_use]
    pub fn total_power(&self) -> f64 {
        self.total_power
    }

    /// Cell coordinates of linear cell index `cell`.
    #[must_use]
    pub fn cell_coords(&self, cell: usize) -> IVec3 {
        let (nx, ny) = (self.dims.x as usize, self.dims.y as usize);
        IVec3::new((cell % nx) as i32, ((cell / nx) % ny) as i32, (cell / (nx * ny)) as i32)
    }

    /// Index-space box `[lo, hi]` of linear cell `cell`.
    #[must_use]
    pub fn cell_index_bounds(&self, cell: usize) -> (DVec3, DVec3) {
        let e = f64::from(self.edge);
        let lo = self.origin + self.cell_coords(cell).as_dvec3() * e;
        (lo, lo + e)
    }

    /// Probability `P_j` of choosing linear cell `cell` (0 for a cell that emits nothing).
    ///
    /// # Panics
    /// If `cell >= self.cell_count()`.
    #[must_use]
    pub fn cell_probability(&self, cell: usize) -> f64 {
        self.cell_pmf[cell]
    }

    /// Heap bytes: 8 per cell, 20 per emitting cell and 1 per block of 4³ cells.
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        self.cell_pmf.len() * 8
            + self.cells.len() * 4
            + self.alias.memory_bytes()
            + self.block_occupied.len()
    }
}

/// Voxel-power sums (without `|det A|`) of the cells in layer `cz`, plus the first invalid
/// power met.
fn layer_power(
    volume: &Volume,
    power: &(impl Fn(f32, f32) -> f64 + Sync),
    voxel_lo: IVec3,
    extent: IVec3,
    edge: i32,
    dims: IVec3,
    cz: i32,
) -> (Vec<f64>, Option<BadPower>) {
    let (brick_lo, brick_dims) = volume.brick_range();
    let mut acc = vec![0.0f64; dims.x as usize * dims.y as usize];
    let mut bad = None;
    let mut check = |p: f64, voxel: IVec3, density: f32, source: f32| {
        if !(p >= 0.0 && p.is_finite()) && bad.is_none() {
            bad = Some(BadPower { voxel, density, source, power: p });
        }
    };
    // Voxel z range of the layer
    let z0 = voxel_lo.z + cz * edge;
    let z1 = (z0 + edge).min(voxel_lo.z + extent.z);
    let cell_of = |v: i32, a: usize| ((v - voxel_lo[a]) / edge) as usize;
    for bz in z0.div_euclid(BRICK)..=(z1 - 1).div_euclid(BRICK) {
        for by in brick_lo.y..brick_lo.y + brick_dims.y {
            for bx in brick_lo.x..brick_lo.x + brick_dims.x {
                let b = IVec3::new(bx, by, bz);
                let Some(brick) = volume.brick(b) else { continue };
                let origin = b * BRICK;
                let (lz0, lz1) = ((z0 - origin.z).max(0), (z1 - origin.z).min(BRICK));
                if let Some((density, source)) = Volume::brick_constant(brick) {
                    // Constant brick: one power call, 64 column adds
                    if source == 0.0 {
                        continue;
                    }
                    let p = power(density, source);
                    check(p, origin, density, source);
                    let column = p * f64::from(lz1 - lz0);
                    for ly in 0..BRICK {
                        let row = cell_of(origin.y + ly, 1) * dims.x as usize;
                        for lx in 0..BRICK {
                            acc[row + cell_of(origin.x + lx, 0)] += column;
                        }
                    }
                    continue;
                }
                if edge % BRICK == 0 {
                    // Cells are whole bricks (they start at the table's first brick): the
                    // brick's voxels, in storage order, all go to one cell
                    let k = cell_of(origin.x, 0) + cell_of(origin.y, 1) * dims.x as usize;
                    let channel = |slot| (volume.slot_block(slot), slot_constant(slot));
                    let ((dense_d, const_d), (dense_s, const_s)) =
                        (channel(brick.density), channel(brick.source));
                    let mut sum = 0.0;
                    for i in 0..BRICK_VOXELS {
                        let source = dense_s.map_or(const_s, |b| b[i]);
                        if source == 0.0 {
                            continue;
                        }
                        let density = dense_d.map_or(const_d, |b| b[i]);
                        let p = power(density, source);
                        if !(p >= 0.0 && p.is_finite()) {
                            check(p, origin + brick_local(i), density, source);
                        }
                        sum += p;
                    }
                    acc[k] += sum;
                    continue;
                }
                for lx in 0..BRICK {
                    let cx = cell_of(origin.x + lx, 0);
                    for ly in 0..BRICK {
                        let k = cx + cell_of(origin.y + ly, 1) * dims.x as usize;
                        for lz in lz0..lz1 {
                            let l = IVec3::new(lx, ly, lz);
                            let crate::VoxelValues { density, source } =
                                volume.brick_voxel(brick, l);
                            if source == 0.0 {
                                continue;
                            }
                            let p = power(density, source);
                            check(p, origin + l, density, source);
                            acc[k] += p;
                        }
                    }
                }
            }
        }
    }
    (acc, bad)
}

/// Voxels per brick.
const BRICK_VOXELS: usize = (BRICK * BRICK * BRICK) as usize;

/// The value of a constant slot (0 for a dense one, whose values are read instead).
fn slot_constant(slot: PackedSlot) -> f32 {
    match slot.get() {
        Slot::Constant(v) => v,
        Slot::Dense(_) => 0.0,
    }
}
