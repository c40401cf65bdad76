//! Volume-measure next-event estimation (Villemin & Hery 2013; METHOD.md §6): sample a
//! point `y` in the emissive voxels with probability proportional to emitted power.
//!
//! **Distribution.** Every full-resolution voxel `i` with positive power
//! `Φ_i = V · Y(L_e(ρ_i, s_i))` (`V = |det A|` the voxel's world volume, `Y` the luminance
//! passed in as `power`) is an entry of an alias table with `P_i = Φ_i / ΣΦ`. A sample picks
//! `i ~ P`, then `y` uniformly in the voxel's box `[i − ½, i + ½]³` (index space), so
//!
//! ```text
//! p_V(y) = P_i / V     per unit world volume,      Σ_i p_V · V = 1.
//! ```
//!
//! [`EmitterDistribution::sample`] and [`EmitterDistribution::pdf`] read the same stored
//! `P_i` and divide by the same `V`, so they agree bit for bit for the same voxel.
//!
//! **Under trilinear reconstruction** (METHOD.md §12) the emission is
//! `L_e(y) = Σ_i L_e,i h(y − i)` with `h` the trilinear hat `Π_k max(0, 1 − |y_k − i_k|)`
//! (index space; `∫h = 1` voxel), so emission reaches one voxel beyond every emitting
//! voxel, where the box sample above would never go. The table stays the same; only
//! the point is drawn from the hat instead of the box: pick `i ~ P`, then
//! `y − i ~ h` (a tent per axis, inverted in closed form). Then
//!
//! ```text
//! p_V(y) = Σ_i P_i h(y − i) / V,
//! ```
//!
//! the trilinear interpolation of the per-voxel `P_i/V`: positive wherever `L_e(y)` is,
//! still normalized (`∫h = V` in world units), and with power-proportional `P_i` it is
//! proportional to the interpolated power itself. [`EmitterDistribution::pdf`]
//! evaluates exactly this sum (8 voxels around `y`), so `sample` and `pdf` agree. The
//! estimator `f τ L_e / (P_vol p_V |y − x|²)` is the integrator's business.
//!
//! **Layout and memory.** Entries are ordered brick by brick (brick-table order, x
//! fastest), and within a brick by OpenVDB's leaf offset. No per-voxel coordinates are
//! stored: each emitting brick keeps a 512-bit mask of its emitting voxels, its first
//! entry and its origin (80 bytes); a copy of the brick table maps brick coordinates to
//! emitting bricks (4 bytes per table cell, like the volume's own table).
//! - voxel → entry (for `pdf`): table lookup, then `first + popcount(mask below voxel)`;
//! - entry → voxel (for `sample`): binary search on `first`, then select the rank-th set bit.
//!
//! So an emissive voxel costs **16 bytes** (its alias slot) plus at most 80/512 bytes of
//! brick overhead, against ≥ 40 bytes for an explicit coordinate per entry plus a hash map
//! for the reverse lookup. A voxel→entry `HashMap` alone would cost ≈ 20 bytes per voxel.
//!
//! **Brick resolution** (`--nee-table brick`, `light/nee_bricks.rs`): for volumes whose
//! voxel table does not fit in memory, one entry per emitting brick (32 bytes) and the
//! voxel drawn from the brick's values when sampling. The same `P_i`, so everything above
//! (boxes, the hat, `pdf`) is shared; `sample` and `pdf` then read the volume.

use glam::{DAffine3, DVec3, IVec3};
use rayon::prelude::*;

use super::nee_bricks::BrickEmitters;
use super::power::LightPower;
use super::weigh::{cell_coords, weigh_brick};
use plume_core::error::{Error, Result};
use plume_core::sampling::alias::AliasTable;
use plume_scene::NeeTable;
use plume_volume::brick::{Volume, BRICK};
use plume_volume::grid::{leaf_offset, LEAF_VOXELS};
use plume_volume::Interpolation;

/// Marker for "no emitting brick here".
const NONE: u32 = u32::MAX;

/// A point sampled in an emissive voxel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VoxelSample {
    /// The point, world space, uniform in its voxel.
    pub p_world: DVec3,
    /// Density of `p_world` per unit world volume, `P_i / V`; bit-identical to
    /// [`EmitterDistribution::pdf_voxel`]`(voxel)`.
    pub pdf: f64,
    /// The sampled voxel's index. Evaluate `L_e` here rather than by a lookup at `p_world`,
    /// which can round into a neighbour on a face (METHOD.md §10.3).
    pub voxel: IVec3,
}

/// One brick with at least one emitting voxel: 80 bytes.
#[derive(Clone, Copy, Debug)]
struct EmitterBrick {
    /// Bit `leaf_offset(l)` set when local voxel `l` emits.
    mask: [u64; 8],
    /// Alias entry of the brick's first emitting voxel.
    first: u32,
    /// Index of the brick's voxel (0,0,0).
    origin: IVec3,
}

/// Per-brick result of the parallel pass.
struct BrickPower {
    table_cell: usize,
    origin: IVec3,
    mask: [u64; 8],
    weights: Vec<f64>,
}

/// Power-proportional distribution over the emissive voxels of a volume. See module docs.
#[derive(Clone, Debug)]
pub struct EmitterDistribution {
    world_from_index: DAffine3,
    index_from_world: DAffine3,
    /// How voxels are drawn: from one table entry each, or brick by brick.
    entries: Entries,
    voxel_volume: f64,
    total_power: f64,
    /// How the point is drawn around the voxel: its box, or the trilinear hat.
    interpolation: Interpolation,
}

/// The table's resolution ([`NeeTable`]).
#[derive(Clone, Debug)]
enum Entries {
    /// One alias entry per emitting voxel.
    Voxels(VoxelTable),
    /// One alias entry per emitting brick (`light::nee_bricks`).
    Bricks(BrickEmitters),
}

/// One alias entry per emitting voxel (module docs, "Layout and memory").
#[derive(Clone, Debug)]
struct VoxelTable {
    /// Brick coordinate of table cell (0,0,0) and the table size in bricks.
    brick_lo: IVec3,
    dims: IVec3,
    /// Emitting-brick ordinal per brick-table cell (x fastest), or [`NONE`].
    table: Vec<u32>,
    bricks: Vec<EmitterBrick>,
    alias: AliasTable,
}

/// Position of the `rank`-th set bit (0-based) of a 512-bit mask.
fn select(mask: &[u64; 8], mut rank: u32) -> usize {
    for (w, &word) in mask.iter().enumerate() {
        let count = word.count_ones();
        if rank < count {
            let mut word = word;
            for _ in 0..rank {
                word &= word - 1;
            }
            return w * 64 + word.trailing_zeros() as usize;
        }
        rank -= count;
    }
    unreachable!("invariant: rank < popcount(mask)")
}

/// Local voxel of leaf offset `off` (inverse of [`leaf_offset`]).
#[inline]
fn local_of(off: usize) -> IVec3 {
    IVec3::new((off >> 6) as i32, ((off >> 3) & 7) as i32, (off & 7) as i32)
}

impl EmitterDistribution {
    /// Build the distribution of `volume`'s emissive voxels, `power(density, source)`
    /// being the luminance `Y(L_e)` of the emission density. Called once per voxel with a
    /// non-zero source (once per constant brick), in parallel.
    ///
    /// Returns `Ok(None)` when nothing emits.
    ///
    /// # Errors
    /// [`Error::Scene`] when `power` returns a negative or non-finite value, when the total
    /// power overflows, or when more than `u32::MAX − 1` voxels emit.
    pub fn build(
        volume: &Volume,
        power: impl Fn(f32, f32) -> f64 + Sync,
    ) -> Result<Option<EmitterDistribution>> {
        let (brick_lo, dims) = volume.brick_range();
        let table_len = dims.x.max(0) as usize * dims.y.max(0) as usize * dims.z.max(0) as usize;
        // Power of every emitting voxel, brick by brick (order kept by collect)
        let per_brick: Vec<Result<BrickPower>> = (0..table_len)
            .into_par_iter()
            .filter_map(|k| {
                let b = brick_lo + cell_coords(k, dims);
                let brick = volume.brick(b)?;
                let origin = b * BRICK;
                let mut mask = [0u64; 8];
                let mut weights = Vec::new();
                let mut add = |off: usize, p: f64| {
                    mask[off >> 6] |= 1 << (off & 63);
                    weights.push(p);
                };
                let result = weigh_brick(volume, brick, origin, &power, local_of, |off, p| {
                    // A constant brick: every voxel has the power of one call
                    if off == LEAF_VOXELS {
                        (0..LEAF_VOXELS).for_each(|o| add(o, p));
                    } else {
                        add(off, p);
                    }
                    true
                });
                match result {
                    Err(e) => Some(Err(e)),
                    Ok(()) if weights.is_empty() => None,
                    Ok(()) => Some(Ok(BrickPower { table_cell: k, origin, mask, weights })),
                }
            })
            .collect();
        let mut table = vec![NONE; table_len];
        let mut bricks = Vec::new();
        let mut weights = Vec::new();
        for item in per_brick {
            let bp = item?;
            if weights.len() + bp.weights.len() >= u32::MAX as usize {
                return Err(Error::Scene(
                    "more than 2^32 - 1 emitting voxels; plume's NEE table cannot hold them".into(),
                ));
            }
            table[bp.table_cell] = bricks.len() as u32;
            bricks.push(EmitterBrick {
                mask: bp.mask,
                first: weights.len() as u32,
                origin: bp.origin,
            });
            weights.extend_from_slice(&bp.weights);
        }
        if weights.is_empty() {
            return Ok(None);
        }
        let voxel_volume = volume.voxel_volume();
        let total_power = voxel_volume * weights.iter().sum::<f64>();
        let Some(alias) = AliasTable::new(&weights) else {
            return Err(Error::Scene(format!(
                "total emitted power {total_power} of the volume is not finite"
            )));
        };
        Ok(Some(EmitterDistribution {
            world_from_index: volume.world_from_index(),
            index_from_world: volume.index_from_world(),
            entries: Entries::Voxels(VoxelTable { brick_lo, dims, table, bricks, alias }),
            voxel_volume,
            total_power,
            interpolation: Interpolation::Nearest,
        }))
    }

    /// The distribution of `volume`'s emissive voxels with one entry per emitting brick,
    /// weighed by `power` (`light::nee_bricks`): 32 bytes per emitting brick instead of
    /// 16 per emitting voxel. Returns `Ok(None)` when nothing emits.
    ///
    /// # Errors
    /// As [`EmitterDistribution::build`].
    pub fn build_bricks(
        volume: &Volume,
        power: impl Fn(f32, f32) -> f64 + Send + Sync + 'static,
    ) -> Result<Option<EmitterDistribution>> {
        let Some(bricks) = BrickEmitters::build(volume, std::sync::Arc::new(power))? else {
            return Ok(None);
        };
        let voxel_volume = volume.voxel_volume();
        Ok(Some(EmitterDistribution {
            world_from_index: volume.world_from_index(),
            index_from_world: volume.index_from_world(),
            total_power: voxel_volume * bricks.total_power(),
            entries: Entries::Bricks(bricks),
            voxel_volume,
            interpolation: Interpolation::Nearest,
        }))
    }

    /// Build the table `table` asks for (`NeeTable`).
    ///
    /// # Errors
    /// As [`EmitterDistribution::build`].
    pub fn build_as(
        volume: &Volume,
        power: LightPower,
        table: NeeTable,
    ) -> Result<Option<EmitterDistribution>> {
        match table {
            NeeTable::Voxel => EmitterDistribution::build(volume, move |d, s| power.power(d, s)),
            NeeTable::Brick => {
                EmitterDistribution::build_bricks(volume, move |d, s| power.power(d, s))
            }
        }
    }

    /// The same table for a volume reconstructed by `interpolation` (see module docs).
    #[must_use]
    pub fn for_interpolation(self, interpolation: Interpolation) -> EmitterDistribution {
        EmitterDistribution { interpolation, ..self }
    }

    /// Sample a voxel `i ~ P` with `u_voxel` and a point in it with `u_pos` (all in
    /// `[0, 1)`): uniformly in its box, or from the trilinear hat around it (module docs).
    /// The pdf is per unit world volume. `volume` is the one the table was built from
    /// (a brick table reads its voxels).
    #[must_use]
    pub fn sample(&self, volume: &Volume, u_voxel: f64, u_pos: [f64; 3]) -> VoxelSample {
        let (voxel, pmf) = match &self.entries {
            Entries::Voxels(t) => {
                let s = t.alias.sample(u_voxel);
                // Entry → brick (entries are grouped by brick, `first` increasing) → set bit
                let ordinal = t.bricks.partition_point(|b| b.first as usize <= s.index) - 1;
                let brick = &t.bricks[ordinal];
                let off = select(&brick.mask, (s.index - brick.first as usize) as u32);
                (brick.origin + local_of(off), s.pmf)
            }
            Entries::Bricks(b) => {
                let s = b.sample(volume, u_voxel);
                (s.voxel, s.pmf)
            }
        };
        match self.interpolation {
            Interpolation::Nearest => {
                let p_index = (voxel.as_dvec3() - 0.5) + DVec3::from(u_pos);
                VoxelSample {
                    p_world: self.world_from_index.transform_point3(p_index),
                    pdf: pmf / self.voxel_volume,
                    voxel,
                }
            }
            Interpolation::Linear => {
                let p_index = voxel.as_dvec3() + DVec3::from(u_pos.map(sample_tent));
                let p_world = self.world_from_index.transform_point3(p_index);
                VoxelSample { p_world, pdf: self.pdf_hat(volume, p_index), voxel }
            }
        }
    }

    /// `Σ_i h(p − i) P_i / V` over the 8 voxels around index-space `p` (module docs).
    fn pdf_hat(&self, volume: &Volume, p: DVec3) -> f64 {
        let i = p.floor();
        let f = p - i;
        let i = i.as_ivec3();
        let mut sum = 0.0;
        for c in 0..8 {
            let corner = IVec3::new(c & 1, (c >> 1) & 1, (c >> 2) & 1);
            let w = (0..3).map(|k| if corner[k] == 1 { f[k] } else { 1.0 - f[k] }).product::<f64>();
            if w > 0.0 {
                sum += w * self.pdf_voxel(volume, i + corner);
            }
        }
        sum
    }

    /// Density per unit world volume of sampling a point in voxel `ijk` (0 where the voxel
    /// emits nothing).
    #[must_use]
    pub fn pdf_voxel(&self, volume: &Volume, ijk: IVec3) -> f64 {
        let pmf = match &self.entries {
            Entries::Voxels(t) => t.pmf(ijk),
            Entries::Bricks(b) => b.pmf(volume, ijk),
        };
        pmf / self.voxel_volume
    }

    /// Density per unit world volume of sampling `p_world`: [`Self::pdf_voxel`] of the voxel
    /// `⌊p_index + ½⌋` containing it, or under trilinear reconstruction the hat-weighted
    /// sum over the 8 voxels around it (0 outside the emissive voxels' support or for
    /// non-finite input).
    #[must_use]
    pub fn pdf(&self, volume: &Volume, p_world: DVec3) -> f64 {
        let p = self.index_from_world.transform_point3(p_world);
        if !p.is_finite() || p.abs().max_element() > f64::from(i32::MAX - 2 * BRICK) {
            return 0.0;
        }
        match self.interpolation {
            Interpolation::Nearest => self.pdf_voxel(volume, (p + 0.5).floor().as_ivec3()),
            Interpolation::Linear => self.pdf_hat(volume, p),
        }
    }

    /// `ΣΦ_i = V Σ Y(L_e)`: the volume's emitted luminance power, for choosing between
    /// lights (same quantity as the proxy grid's `total_power`).
    #[must_use]
    pub fn total_power(&self) -> f64 {
        self.total_power
    }

    /// Number of alias entries: emitting voxels, or emitting bricks of a brick table.
    #[must_use]
    pub fn entry_count(&self) -> usize {
        match &self.entries {
            Entries::Voxels(t) => t.alias.len(),
            Entries::Bricks(b) => b.brick_count(),
        }
    }

    /// Heap bytes: 16 per emissive voxel, 80 per emitting brick and 4 per brick-table
    /// cell; or 32 per emitting brick for a brick table.
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        match &self.entries {
            Entries::Voxels(t) => {
                t.alias.memory_bytes()
                    + t.bricks.len() * std::mem::size_of::<EmitterBrick>()
                    + t.table.len() * 4
            }
            Entries::Bricks(b) => b.memory_bytes(),
        }
    }
}

impl VoxelTable {
    /// `P_i` of voxel `ijk` (0 where it emits nothing).
    fn pmf(&self, ijk: IVec3) -> f64 {
        let b = ijk.div_euclid(IVec3::splat(BRICK));
        let r = b - self.brick_lo;
        if r.cmplt(IVec3::ZERO).any() || r.cmpge(self.dims).any() {
            return 0.0;
        }
        let cell = r.x as usize
            + self.dims.x as usize * (r.y as usize + self.dims.y as usize * r.z as usize);
        let ordinal = self.table[cell];
        if ordinal == NONE {
            return 0.0;
        }
        let brick = &self.bricks[ordinal as usize];
        let l = ijk - b * BRICK;
        let off = leaf_offset(l.x, l.y, l.z);
        let (word, bit) = (off >> 6, off & 63);
        if brick.mask[word] >> bit & 1 == 0 {
            return 0.0;
        }
        let below: u32 = brick.mask[..word].iter().map(|w| w.count_ones()).sum::<u32>()
            + (brick.mask[word] & ((1u64 << bit) - 1)).count_ones();
        self.alias.pmf(brick.first as usize + below as usize)
    }
}

/// Offset in `(−1, 1)` with the tent density `1 − |x|`, from `u ∈ [0, 1)` (inverse CDF).
#[inline]
fn sample_tent(u: f64) -> f64 {
    if u < 0.5 {
        (2.0 * u).sqrt() - 1.0
    } else {
        1.0 - (2.0 - 2.0 * u).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The tent's inverse CDF: quantiles land where `∫_{−1}^x (1 − |s|) ds = u`.
    #[test]
    fn tent_inverts_its_cdf() {
        let cdf = |x: f64| {
            if x < 0.0 {
                0.5 * (1.0 + x) * (1.0 + x)
            } else {
                1.0 - 0.5 * (1.0 - x) * (1.0 - x)
            }
        };
        for k in 0..=100 {
            let u = f64::from(k) / 100.0 * 0.999_999;
            let x = sample_tent(u);
            assert!((-1.0..1.0).contains(&x));
            assert!((cdf(x) - u).abs() < 1e-12, "u {u} x {x}");
        }
    }

    #[test]
    fn select_inverts_rank() {
        let mask = [0x8000_0000_0000_0001, 0, 0b1010, 0, 0, 0, 0, 1 << 63];
        let positions: Vec<usize> = (0..5).map(|r| select(&mask, r)).collect();
        assert_eq!(positions, vec![0, 63, 129, 131, 511]);
        for off in [0usize, 77, 511] {
            assert_eq!(leaf_offset(local_of(off).x, local_of(off).y, local_of(off).z), off);
        }
        assert_eq!(std::mem::size_of::<EmitterBrick>(), 80);
    }
}
