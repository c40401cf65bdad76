//! Classic NEE's table at brick resolution (`--nee-table brick`): for volumes whose
//! per-voxel table ([`super::nee`], 16 bytes per emitting voxel) does not fit in memory.
//! The generated 2048³ flare has up to 580 M emitting voxels (13 GiB of table), the 4096³
//! one, the paper's out-of-core experiment, eight times as many.
//!
//! **Distribution.** One alias entry per emitting brick `b`, weighted by its power
//! `Φ_b = Σ_{i∈b} Φ_i`, summed over its voxels in brick order
//! ([`brick_offset`](plume_volume::brick::brick_offset)). A sample draws `b` with `u`,
//! then voxel `i` of `b` by walking the same running sum to `u′ Φ_b`, where `u′` is the
//! part of `u` the alias choice did not use (uniform given `b`,
//! [`AliasTable::sample_with_residual`]). So
//!
//! ```text
//! P_i = P_b · Φ_i / Φ_b,
//! ```
//!
//! the per-voxel table's law (up to the rounding of the running sum). In a constant brick
//! every voxel has the same power and `i` is uniform: `P_i = P_b / 512`.
//!
//! **Sample and pdf agree bit for bit.** Both compute `P_i` by [`BrickEmitters::pmf_in`]
//! from the stored `P_b` and `Φ_b` and the voxel's own `Φ_i`, recomputed from its values
//! with the same power function (it is deterministic).
//!
//! **Cost.** 32 bytes per emitting brick (alias slot, brick-table cell, `Φ_b`), nothing per
//! voxel. A sample reads its brick's values and weighs up to 512 voxels; a pdf finds the
//! brick by binary search and weighs one voxel. From a brick cache, the brick a sample
//! reads is paged in like any other.

use std::sync::Arc;

use glam::IVec3;
use rayon::prelude::*;

use super::weigh::{cell_coords, weigh_brick};
use plume_core::error::{Error, Result};
use plume_core::sampling::alias::AliasTable;
use plume_volume::brick::{brick_local, Volume, BRICK};
use plume_volume::grid::LEAF_VOXELS;

/// `Φ_i` of a voxel from its density and source (`integrator::light_power`).
pub(crate) type Weigh = Arc<dyn Fn(f32, f32) -> f64 + Send + Sync>;

/// Emitting bricks and their power (module docs).
#[derive(Clone)]
pub(crate) struct BrickEmitters {
    /// Brick coordinate of table cell (0,0,0) and the table size in bricks.
    brick_lo: IVec3,
    dims: IVec3,
    /// Brick-table cell (x fastest) of each emitting brick, ascending.
    cells: Vec<u64>,
    /// `Φ_b` of each emitting brick.
    power: Vec<f64>,
    alias: AliasTable,
    /// The power function of the build, evaluated again when sampling.
    weigh: Weigh,
}

impl std::fmt::Debug for BrickEmitters {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BrickEmitters")
            .field("bricks", &self.cells.len())
            .field("total_power", &self.total_power())
            .finish_non_exhaustive()
    }
}

/// A voxel drawn from a brick: its index and its probability mass `P_i`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct BrickVoxel {
    /// Voxel index.
    pub voxel: IVec3,
    /// `P_i`.
    pub pmf: f64,
}

impl BrickEmitters {
    /// The emitting bricks of `volume` weighed by `weigh`, in parallel; `Ok(None)` when
    /// nothing emits.
    ///
    /// # Errors
    /// [`Error::Scene`] for a negative or non-finite voxel power, or a total that
    /// overflows.
    pub fn build(volume: &Volume, weigh: Weigh) -> Result<Option<BrickEmitters>> {
        let (brick_lo, dims) = volume.brick_range();
        let table_len = dims.x.max(0) as usize * dims.y.max(0) as usize * dims.z.max(0) as usize;
        let per_brick: Vec<Result<(u64, f64)>> = (0..table_len)
            .into_par_iter()
            .filter_map(|k| {
                let b = brick_lo + cell_coords(k, dims);
                let brick = volume.brick(b)?;
                let mut total = 0.0f64;
                match weigh_brick(volume, brick, b * BRICK, &*weigh, brick_local, |off, p| {
                    // A constant brick comes as one call for all its voxels
                    total += if off == LEAF_VOXELS { p * LEAF_VOXELS as f64 } else { p };
                    true
                }) {
                    Err(e) => Some(Err(e)),
                    Ok(()) => (total > 0.0).then_some(Ok((k as u64, total))),
                }
            })
            .collect();
        let mut cells = Vec::with_capacity(per_brick.len());
        let mut power = Vec::with_capacity(per_brick.len());
        for item in per_brick {
            let (cell, p) = item?;
            cells.push(cell);
            power.push(p);
        }
        if power.is_empty() {
            return Ok(None);
        }
        let Some(alias) = AliasTable::new(&power) else {
            return Err(Error::Scene("the total emitted power of the volume is not finite".into()));
        };
        Ok(Some(BrickEmitters { brick_lo, dims, cells, power, alias, weigh }))
    }

    /// `Σ Φ_b`: the emitted power per unit voxel volume.
    pub fn total_power(&self) -> f64 {
        self.power.iter().sum()
    }

    /// Number of emitting bricks.
    pub fn brick_count(&self) -> usize {
        self.cells.len()
    }

    /// Heap bytes: 32 per emitting brick.
    pub fn memory_bytes(&self) -> usize {
        self.alias.memory_bytes() + self.cells.len() * 8 + self.power.len() * 8
    }

    /// `P_i = P_b · Φ_i / Φ_b` of a voxel of power `p` in emitting brick `ordinal`; the
    /// voxel's share is `1/512` in a constant brick.
    #[inline]
    fn pmf_in(&self, ordinal: usize, p: f64, constant: bool) -> f64 {
        let share = if constant { 1.0 / LEAF_VOXELS as f64 } else { p / self.power[ordinal] };
        self.alias.pmf(ordinal) * share
    }

    /// Draw a voxel with `u ∈ [0, 1)` (module docs). `volume` must be the one the table
    /// was built from.
    pub fn sample(&self, volume: &Volume, u: f64) -> BrickVoxel {
        let (chosen, residual) = self.alias.sample_with_residual(u);
        let b = self.brick_lo + cell_coords(self.cells[chosen.index] as usize, self.dims);
        let origin = b * BRICK;
        let Some(brick) = volume.brick(b) else {
            unreachable!("invariant: an emitting brick of the table is a brick of its volume")
        };
        if Volume::brick_constant(brick).is_some() {
            let off = ((residual * LEAF_VOXELS as f64) as usize).min(LEAF_VOXELS - 1);
            return BrickVoxel {
                voxel: origin + brick_local(off),
                pmf: self.pmf_in(chosen.index, 0.0, true),
            };
        }
        // Walk the running sum of Φ_i to u′ Φ_b; the last emitting voxel takes what rounding
        // leaves over
        let target = residual * self.power[chosen.index];
        let (mut sum, mut last) = (0.0f64, None);
        let walked = weigh_brick(volume, brick, origin, &*self.weigh, brick_local, |off, p| {
            sum += p;
            last = Some((off, p));
            sum <= target
        });
        debug_assert!(walked.is_ok(), "the build weighed these voxels");
        let Some((off, p)) = last else {
            unreachable!("invariant: an emitting brick has a voxel of positive power")
        };
        BrickVoxel { voxel: origin + brick_local(off), pmf: self.pmf_in(chosen.index, p, false) }
    }

    /// `P_i` of voxel `ijk`: 0 where it emits nothing or lies outside the table.
    pub fn pmf(&self, volume: &Volume, ijk: IVec3) -> f64 {
        let b = ijk.div_euclid(IVec3::splat(BRICK));
        let r = b - self.brick_lo;
        if r.cmplt(IVec3::ZERO).any() || r.cmpge(self.dims).any() {
            return 0.0;
        }
        let cell = r.x as u64 + self.dims.x as u64 * (r.y as u64 + self.dims.y as u64 * r.z as u64);
        let Ok(ordinal) = self.cells.binary_search(&cell) else { return 0.0 };
        let Some(brick) = volume.brick(b) else { return 0.0 };
        if Volume::brick_constant(brick).is_some() {
            return self.pmf_in(ordinal, 0.0, true);
        }
        let l = ijk - b * BRICK;
        let v = volume.brick_voxel(brick, l);
        let p = (self.weigh)(v.density, v.source);
        if p > 0.0 && p.is_finite() {
            self.pmf_in(ordinal, p, false)
        } else {
            0.0
        }
    }
}
