//! Building a [`Volume`](super::Volume)'s brick table from 8³ blocks: the input clean-up
//! policy (NaN, ±inf and negative values to 0, counted; −0 to +0), constant-brick
//! compression, per-brick bounds for the pyramid, and the table's box. One
//! [`BrickTableBuilder`] serves the in-core build (values in a `Vec`) and the streaming
//! cache writer (values in the file), so both hold the same data for the same input.

use glam::{DAffine3, IVec3};

use super::pyramid::NodeBounds;
use crate::grid::{leaf_offset, LEAF_VOXELS};
use crate::layout::{
    brick_offset, Brick, BuildReport, PackedSlot, Slot, BRICK, MAX_TABLE_ENTRIES, NO_BRICK,
};
use plume_core::error::{Error, Result};

/// Brick-order offset ([`brick_offset`]) of each leaf-order offset ([`leaf_offset`]).
pub static LEAF_TO_BRICK: [u16; LEAF_VOXELS] = {
    let mut table = [0u16; LEAF_VOXELS];
    let mut i = 0;
    while i < LEAF_VOXELS {
        let (x, y, z) = ((i >> 6) as i32 & 7, (i >> 3) as i32 & 7, i as i32 & 7);
        table[leaf_offset(x, y, z)] = brick_offset(x, y, z) as u16;
        i += 1;
    }
    table
};

/// Where built value blocks go: the heap ([`Vec`]) or a cache file being written.
pub trait BlockSink {
    /// Append one block of 512 values (brick order); returns its block index.
    ///
    /// # Errors
    /// An I/O error of the sink, or more than `u32::MAX` blocks.
    fn append(&mut self, block: &[f32; LEAF_VOXELS]) -> Result<u32>;

    /// The values appended so far (used once at the end, for albedo bounds).
    ///
    /// # Errors
    /// An I/O error reading them back.
    fn appended(&mut self) -> Result<&[f32]>;
}

impl BlockSink for Vec<f32> {
    fn append(&mut self, block: &[f32; LEAF_VOXELS]) -> Result<u32> {
        let index = u32::try_from(self.len() / LEAF_VOXELS)
            .map_err(|_| Error::Scene("the volume has more than 2³² dense bricks".into()))?;
        self.extend_from_slice(block);
        Ok(index)
    }

    fn appended(&mut self) -> Result<&[f32]> {
        Ok(self)
    }
}

/// A channel of the volume, as given to [`BrickTableBuilder::put`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Channel {
    /// Density ρ; NaN, ±inf and negative values become 0 (counted).
    Density,
    /// Emission source, already mapped (0 = emits nothing); invalid values become 0.
    Source,
    /// Albedo factor; clamped to `[0, 1]`, NaN becomes 1 (counted).
    Albedo,
}

/// Builds the brick table from 8³ blocks given channel by channel, in any order (grid
/// by grid and leaf by leaf when streaming). Shared by the in-core build and the cache
/// writer, so both store the same slots, bounds and clean-up counts for the same data.
#[derive(Debug)]
pub struct BrickTableBuilder {
    brick_lo: IVec3,
    dims: IVec3,
    table: Vec<u32>,
    bricks: Vec<Brick>,
    bounds: Vec<NodeBounds>,
    report: BuildReport,
}

/// What [`BrickTableBuilder::finish`] returns.
#[derive(Debug)]
pub struct BuiltTable {
    /// Brick coordinate of table cell (0,0,0).
    pub brick_lo: IVec3,
    /// Table size in bricks.
    pub dims: IVec3,
    /// Brick index per table cell, or `NO_BRICK`.
    pub table: Vec<u32>,
    /// Brick records.
    pub bricks: Vec<Brick>,
    /// The finest pyramid level's bounds, per brick.
    pub bounds: Vec<NodeBounds>,
    /// Clean-up counts.
    pub report: BuildReport,
}

impl BrickTableBuilder {
    /// A builder for bricks `brick_lo .. brick_lo + dims`.
    ///
    /// # Errors
    /// A table larger than [`MAX_TABLE_ENTRIES`] (`what` names the grid in the message).
    pub fn new(brick_lo: IVec3, dims: IVec3, what: &str) -> Result<BrickTableBuilder> {
        let entries = table_entries(dims.as_i64vec3(), what)?;
        Ok(BrickTableBuilder {
            brick_lo,
            dims,
            table: vec![NO_BRICK; entries],
            bricks: Vec::new(),
            bounds: Vec::new(),
            report: BuildReport::default(),
        })
    }

    /// Store channel `channel` of brick `b` from 512 raw values in OpenVDB leaf order,
    /// each passed through `map` (the source mapping; identity for other channels) and
    /// cleaned by the channel's rule; a uniform block becomes a constant slot.
    ///
    /// # Errors
    /// `b` outside the table, or the sink's error.
    pub fn put(
        &mut self,
        sink: &mut impl BlockSink,
        b: IVec3,
        channel: Channel,
        raw: &[f32],
        map: impl Fn(f32) -> f32,
    ) -> Result<()> {
        let mut block = [0.0f32; LEAF_VOXELS];
        let raw: &[f32; LEAF_VOXELS] = raw
            .try_into()
            .map_err(|_| Error::Scene(format!("a leaf of {} values, not 512", raw.len())))?;
        match channel {
            Channel::Density | Channel::Source => {
                // Branch-free clean-up in leaf order (vectorizable), counted once per
                // block, then the reorder
                let mut clean = [0.0f32; LEAF_VOXELS];
                let mut bad = 0u32;
                for (c, &v) in clean.iter_mut().zip(raw.iter()) {
                    let v = map(v);
                    let ok = v.is_finite() & (v >= 0.0);
                    bad += u32::from(!ok);
                    *c = if ok { v + 0.0 } else { 0.0 };
                }
                for (&v, &to) in clean.iter().zip(LEAF_TO_BRICK.iter()) {
                    block[usize::from(to)] = v;
                }
                let bad = u64::from(bad);
                if channel == Channel::Density {
                    self.report.density_clamped += bad;
                } else {
                    self.report.source_invalid += bad;
                }
            }
            Channel::Albedo => {
                for (&v, &to) in raw.iter().zip(LEAF_TO_BRICK.iter()) {
                    block[usize::from(to)] = self.clean(channel, map(v), 1);
                }
            }
        }
        self.put_block(sink, b, channel, &block)
    }

    /// Store channel `channel` of brick `b` as the constant `value` (already mapped,
    /// cleaned here), e.g. a voxelized active tile.
    ///
    /// # Errors
    /// `b` outside the table.
    pub fn put_constant(&mut self, b: IVec3, channel: Channel, value: f32) -> Result<()> {
        let v = self.clean(channel, value, LEAF_VOXELS as u64);
        let index = self.brick_index(b)?;
        self.set(index, channel, PackedSlot::constant(v), (v, v));
        Ok(())
    }

    /// `v` cleaned by `channel`'s rule, counting `n` voxels in the report if it changed.
    #[inline]
    fn clean(&mut self, channel: Channel, v: f32, n: u64) -> f32 {
        match channel {
            Channel::Density => clean_n(v, &mut self.report.density_clamped, n),
            Channel::Source => clean_n(v, &mut self.report.source_invalid, n),
            Channel::Albedo => clean_albedo_n(v, &mut self.report.albedo_clamped, n),
        }
    }

    /// Store an already cleaned block in brick order.
    fn put_block(
        &mut self,
        sink: &mut impl BlockSink,
        b: IVec3,
        channel: Channel,
        block: &[f32; LEAF_VOXELS],
    ) -> Result<()> {
        let index = self.brick_index(b)?;
        let first = block[0];
        let (slot, bounds) = if block.iter().all(|v| v.to_bits() == first.to_bits()) {
            (PackedSlot::constant(first), (first, first))
        } else {
            let lohi = block
                .iter()
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v)));
            (PackedSlot::dense(sink.append(block)?), lohi)
        };
        self.set(index, channel, slot, bounds);
        Ok(())
    }

    fn set(&mut self, index: usize, channel: Channel, slot: PackedSlot, (lo, hi): (f32, f32)) {
        let (brick, bounds) = (&mut self.bricks[index], &mut self.bounds[index]);
        match channel {
            Channel::Density => {
                brick.density = slot;
                (bounds.density_min, bounds.density_max) = (lo, hi);
            }
            Channel::Source => {
                brick.source = slot;
                (bounds.source_min, bounds.source_max) = (lo, hi);
            }
            // Albedo bounds depend on density; set in `finish`
            Channel::Albedo => brick.albedo = slot,
        }
    }

    /// Index of brick `b`, creating its record (all channels unset) on first use.
    fn brick_index(&mut self, b: IVec3) -> Result<usize> {
        let r = b - self.brick_lo;
        if r.cmplt(IVec3::ZERO).any() || r.cmpge(self.dims).any() {
            return Err(Error::Scene(format!(
                "leaf at voxel {} lies outside the grid's announced bounding box",
                b * BRICK
            )));
        }
        let cell = r.x as usize
            + self.dims.x as usize * (r.y as usize + self.dims.y as usize * r.z as usize);
        if self.table[cell] == NO_BRICK {
            self.table[cell] = self.bricks.len() as u32;
            self.bricks.push(Brick {
                density: PackedSlot::UNSET,
                source: PackedSlot::UNSET,
                albedo: PackedSlot::UNSET,
            });
            self.bounds.push(NodeBounds::ZERO);
        }
        Ok(self.table[cell] as usize)
    }

    /// Fill channels never given with the grids' backgrounds (cleaned; `None` for a channel
    /// without a grid: density and source 0, albedo 1) and compute albedo bounds.
    ///
    /// # Errors
    /// The sink's error reading values back (only with dense albedo bricks).
    pub fn finish(
        mut self,
        sink: &mut impl BlockSink,
        backgrounds: [Option<f32>; 3],
    ) -> Result<BuiltTable> {
        let density_bg = clean(backgrounds[0].unwrap_or(0.0), &mut 0);
        let source_bg = clean(backgrounds[1].unwrap_or(0.0), &mut 0);
        let albedo_bg = backgrounds[2].map_or(1.0, |a| clean_albedo(a, &mut 0));
        let mut dense_albedo = false;
        for (brick, bounds) in self.bricks.iter_mut().zip(&mut self.bounds) {
            if brick.density == PackedSlot::UNSET {
                brick.density = PackedSlot::constant(density_bg);
                (bounds.density_min, bounds.density_max) = (density_bg, density_bg);
            }
            if brick.source == PackedSlot::UNSET {
                brick.source = PackedSlot::constant(source_bg);
                (bounds.source_min, bounds.source_max) = (source_bg, source_bg);
            }
            if brick.albedo == PackedSlot::UNSET {
                brick.albedo = PackedSlot::constant(albedo_bg);
            }
            match brick.albedo.get() {
                Slot::Constant(a) => {
                    let a = if bounds.density_max > 0.0 { a } else { 1.0 };
                    (bounds.albedo_min, bounds.albedo_max) = (a, a);
                }
                Slot::Dense(_) => dense_albedo = true,
            }
        }
        if dense_albedo {
            let values = sink.appended()?;
            for (brick, bounds) in self.bricks.iter().zip(&mut self.bounds) {
                if matches!(brick.albedo.get(), Slot::Dense(_)) {
                    (bounds.albedo_min, bounds.albedo_max) = albedo_bounds(values, brick);
                }
            }
        }
        let (brick_lo, dims, table) = shrink_to_occupied(self.brick_lo, self.dims, self.table);
        Ok(BuiltTable {
            brick_lo,
            dims,
            table,
            bricks: self.bricks,
            bounds: self.bounds,
            report: self.report,
        })
    }
}

/// The table cut down to the bounding box of its bricks, so a volume's layout (and what
/// depends on it: pyramid levels, proxy cells) depends on its bricks only, not on the
/// box announced up front (a generator's whole domain, a header's bounds).
fn shrink_to_occupied(lo: IVec3, dims: IVec3, table: Vec<u32>) -> (IVec3, IVec3, Vec<u32>) {
    let (nx, ny) = (dims.x.max(0) as usize, dims.y.max(0) as usize);
    let (mut min, mut max) = (IVec3::MAX, IVec3::MIN);
    for (i, _) in table.iter().enumerate().filter(|(_, &b)| b != NO_BRICK) {
        let c = IVec3::new((i % nx) as i32, ((i / nx) % ny) as i32, (i / (nx * ny)) as i32);
        min = min.min(c);
        max = max.max(c);
    }
    if min.x > max.x {
        return (IVec3::ZERO, IVec3::ZERO, Vec::new());
    }
    if min == IVec3::ZERO && max == dims - 1 {
        return (lo, dims, table);
    }
    let new_dims = max - min + 1;
    let mut out =
        Vec::with_capacity(new_dims.x as usize * new_dims.y as usize * new_dims.z as usize);
    for z in min.z..=max.z {
        for y in min.y..=max.y {
            let row = (z as usize * ny + y as usize) * nx;
            out.extend_from_slice(&table[row + min.x as usize..=row + max.x as usize]);
        }
    }
    (lo + min, new_dims, out)
}

/// Check that two grids share one voxel grid (transforms equal to 1e-6 of the scale).
///
/// # Errors
/// [`Error::Scene`] naming both grids.
pub fn check_same_transform(
    (a_name, a): (&str, DAffine3),
    (b_name, b): (&str, DAffine3),
) -> Result<()> {
    let scale = a.matrix3.abs().to_cols_array().iter().fold(0.0f64, |m, v| m.max(*v));
    let close = a.matrix3.abs_diff_eq(b.matrix3, 1e-6 * scale.max(1e-30))
        && a.translation.abs_diff_eq(b.translation, 1e-6 * scale.max(1e-30));
    if close {
        Ok(())
    } else {
        Err(Error::Scene(format!("grids {a_name:?} and {b_name:?} have different transforms; plume needs them on one voxel grid")))
    }
}

/// Table size for bricks `lo ..= hi`, refused beyond [`MAX_TABLE_ENTRIES`].
///
/// # Errors
/// An empty or too large box (`what` names the grid).
pub fn table_dims(lo: IVec3, hi: IVec3, what: &str) -> Result<IVec3> {
    let d = (hi.as_i64vec3() - lo.as_i64vec3()) + 1;
    if d.cmple(glam::I64Vec3::ZERO).any() {
        return Err(Error::Scene(format!("grid {what:?} has an empty bounding box")));
    }
    table_entries(d, what)?;
    Ok(d.as_ivec3())
}

/// Table entries for `d` bricks, refused beyond [`MAX_TABLE_ENTRIES`].
fn table_entries(d: glam::I64Vec3, what: &str) -> Result<usize> {
    if d.cmplt(glam::I64Vec3::ZERO).any() {
        return Err(Error::Scene(format!("grid {what:?} has a negative bounding box")));
    }
    let entries = d.x as u64 * d.y as u64 * d.z as u64;
    if entries > MAX_TABLE_ENTRIES {
        return Err(Error::Scene(format!(
            "grid {what:?} spans {}x{}x{} bricks ({} voxels across); plume's brick table is limited to {} bricks",
            d.x,
            d.y,
            d.z,
            d.max_element() * 8,
            MAX_TABLE_ENTRIES
        )));
    }
    Ok(entries as usize)
}

/// Albedo bounds of a brick over its voxels with density > 0 (`(1, 1)` if none).
fn albedo_bounds(values: &[f32], b: &Brick) -> (f32, f32) {
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for i in 0..LEAF_VOXELS {
        let d = slot_at(values, b.density, i);
        if d > 0.0 {
            let a = slot_at(values, b.albedo, i);
            lo = lo.min(a);
            hi = hi.max(a);
        }
    }
    if lo > hi {
        (1.0, 1.0)
    } else {
        (lo, hi)
    }
}

/// Value `i` (brick order) of a slot; 0 for a block beyond the value array (only a
/// damaged cache file can say so, and its checksums fail the render).
#[inline]
pub fn slot_at(values: &[f32], slot: PackedSlot, i: usize) -> f32 {
    match slot.get() {
        Slot::Constant(v) => v,
        Slot::Dense(block) => values.get(block as usize * LEAF_VOXELS + i).copied().unwrap_or(0.0),
    }
}

/// NaN, ±inf and negative values become 0 and are counted; −0 becomes +0 (so bounds and
/// uniformity never depend on the order values are seen in).
#[inline]
pub fn clean(v: f32, count: &mut u64) -> f32 {
    clean_n(v, count, 1)
}

/// [`clean`] for a value standing for `n` voxels.
#[inline]
pub fn clean_n(v: f32, count: &mut u64, n: u64) -> f32 {
    if v.is_finite() && v >= 0.0 {
        v + 0.0
    } else {
        *count += n;
        0.0
    }
}

/// Albedo factor: clamped to `[0, 1]`, NaN → 1; changed values are counted.
#[inline]
pub fn clean_albedo(v: f32, count: &mut u64) -> f32 {
    clean_albedo_n(v, count, 1)
}

/// [`clean_albedo`] for a value standing for `n` voxels.
#[inline]
fn clean_albedo_n(v: f32, count: &mut u64, n: u64) -> f32 {
    if (0.0..=1.0).contains(&v) {
        v
    } else {
        *count += n;
        if v.is_nan() {
            1.0
        } else {
            v.clamp(0.0, 1.0)
        }
    }
}
