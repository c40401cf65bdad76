//! [`Volume`]: sparse 8³ bricks in index space holding two channels, density ρ and the
//! emission *source* (temperature in Kelvin or an emission grid value, already mapped so
//! that 0 means "emits nothing").
//!
//! Bricks sit on a dense brick table over the bounding box of all leaves (4 bytes per
//! 8³ voxels of the box, empty or not). A brick whose 512 values are all equal in a
//! channel stores that channel as one constant, so OpenVDB's voxelized active tiles and
//! flat regions cost 4 bytes instead of 2 KiB.
//!
//! Voxel `(i,j,k)` is centred at index `(i,j,k)` and constant over `[i-½, i+½]³`
//! (OpenVDB's convention, METHOD.md §1). The brick with origin `8b` spans
//! `[8b-½, 8b+7½]`.

use glam::{DAffine3, DVec3, IVec3};

use super::builder::slot_at;
pub use super::builder::{
    check_same_transform, table_dims, BlockSink, BrickTableBuilder, BuiltTable, Channel,
};
use super::pyramid::Pyramid;
use crate::grid::FloatGrid;
pub use crate::layout::{
    brick_local, brick_of, brick_offset, floor_div, Brick, BuildReport, PackedSlot, Slot, BRICK,
    MAX_TABLE_ENTRIES, NO_BRICK,
};
use crate::out_of_core::storage::Buffer;
use crate::trilinear::window::{corner_offset, window_index, window_slot, CORNER_STEP};
use crate::values::{Bounds3, VoxelValues};
use plume_core::error::{Error, Result};

/// A sparse brick volume in index space with its `world_from_index` transform.
///
/// Its arrays are [`Buffer`]s: on the heap when built from grids, or views of a mapped
/// brick cache file ([`crate::out_of_core`]); everything downstream reads them alike.
#[derive(Debug)]
pub struct Volume {
    /// Index space (voxel centres at integers) to world space.
    pub world_from_index: DAffine3,
    /// World space to index space.
    pub index_from_world: DAffine3,
    /// Brick coordinate (origin / 8) of table cell (0,0,0).
    pub brick_lo: IVec3,
    /// Table size in bricks.
    pub dims: IVec3,
    /// Brick index per table cell (x fastest), or [`NO_BRICK`].
    pub table: Buffer<u32>,
    /// The occupied bricks, in table order.
    pub bricks: Buffer<Brick>,
    /// Dense value blocks of all channels, 512 values each, in [`brick_offset`] order.
    pub values: Buffer<f32>,
    /// Min/max pyramid over the bricks (skipping, majorants).
    pub pyramid: Pyramid,
    /// Input clean-up counts.
    pub report: BuildReport,
    /// Read-ahead only (`volume::prefetch`): one bit per table cell, set where a brick
    /// is; built on first use.
    pub occupancy: std::sync::OnceLock<Vec<u64>>,
    /// Set by [`Volume::expect_read_ahead`]: the render reads ahead of its rays, and
    /// scattered segments read ahead of their lookups (`integrator::tracker`).
    pub reading_ahead: std::sync::atomic::AtomicBool,
}

impl Volume {
    /// Build a volume from a density grid and an optional source grid.
    ///
    /// `source_map` turns a raw source value (e.g. a temperature grid value) into the
    /// stored source (Kelvin after mapping, 0 below the emission cutoff); it must return
    /// 0 for "no emission". Both grids must share one transform.
    ///
    /// # Errors
    /// Incompatible transforms, an empty volume, or a bounding box too large for the brick
    /// table ([`MAX_TABLE_ENTRIES`]).
    pub fn build(
        density: &FloatGrid,
        source: Option<&FloatGrid>,
        source_map: impl Fn(f32) -> f32 + Sync,
    ) -> Result<Volume> {
        Volume::build_with_albedo(density, source, source_map, None)
    }

    /// [`Volume::build`] with an optional albedo grid: its values, clamped to `[0, 1]`
    /// (NaN → 1, counted), become a per-voxel albedo factor (1 outside its leaves).
    ///
    /// # Errors
    /// As [`Volume::build`].
    pub fn build_with_albedo(
        density: &FloatGrid,
        source: Option<&FloatGrid>,
        source_map: impl Fn(f32) -> f32 + Sync,
        albedo: Option<&FloatGrid>,
    ) -> Result<Volume> {
        for s in source.iter().chain(albedo.iter()) {
            check_same_transform(
                (&density.name, density.world_from_index),
                (&s.name, s.world_from_index),
            )?;
        }
        let index_from_world = density.world_from_index.inverse();
        if !index_from_world.is_finite() || density.world_from_index.matrix3.determinant() == 0.0 {
            return Err(Error::Scene(format!("grid {:?} has a singular transform", density.name)));
        }
        let grids = [Some(density), source, albedo];
        let (mut lo, mut hi) = (IVec3::MAX, IVec3::MIN);
        for o in grids.iter().flatten().flat_map(|g| &g.origins) {
            lo = lo.min(brick_of(*o));
            hi = hi.max(brick_of(*o));
        }
        if lo.x > hi.x {
            return Ok(Volume::empty(density.world_from_index, index_from_world));
        }
        let dims = table_dims(lo, hi, &density.name)?;
        let mut builder = BrickTableBuilder::new(lo, dims, &density.name)?;
        let mut values: Vec<f32> = Vec::new();
        for (channel, grid) in [
            (Channel::Density, Some(density)),
            (Channel::Source, source),
            (Channel::Albedo, albedo),
        ] {
            let Some(grid) = grid else { continue };
            let map = |v: f32| if channel == Channel::Source { source_map(v) } else { v };
            for (i, &o) in grid.origins.iter().enumerate() {
                builder.put(&mut values, brick_of(o), channel, grid.leaf_values(i), map)?;
            }
        }
        let backgrounds = [
            Some(density.background),
            Some(source.map_or(0.0, |s| source_map(s.background))),
            albedo.map(|a| a.background),
        ];
        let built = builder.finish(&mut values, backgrounds)?;
        Ok(Volume::from_table(density.world_from_index, built, Buffer::from_vec(values)))
    }

    /// Assemble a volume from a finished brick table and its value blocks (heap or mapped),
    /// building the pyramid from the per-brick bounds.
    #[must_use]
    pub fn from_table(
        world_from_index: DAffine3,
        built: BuiltTable,
        values: Buffer<f32>,
    ) -> Volume {
        let pyramid = Pyramid::from_brick_bounds(built.dims, &built.table, &built.bounds);
        Volume {
            world_from_index,
            index_from_world: world_from_index.inverse(),
            brick_lo: built.brick_lo,
            dims: built.dims,
            table: Buffer::from_vec(built.table),
            bricks: Buffer::from_vec(built.bricks),
            values,
            pyramid,
            report: built.report,
            occupancy: std::sync::OnceLock::new(),
            reading_ahead: std::sync::atomic::AtomicBool::new(false),
        }
    }

    /// Assemble a volume from parts read from a cache file ([`crate::out_of_core`]), which
    /// has checked that the arrays are consistent with `dims` and each other.
    // One argument per part of the volume, as the cache file stores them
    #[allow(clippy::too_many_arguments)]
    #[must_use]
    pub fn from_parts(
        world_from_index: DAffine3,
        brick_lo: IVec3,
        dims: IVec3,
        table: Buffer<u32>,
        bricks: Buffer<Brick>,
        values: Buffer<f32>,
        pyramid: Pyramid,
        report: BuildReport,
    ) -> Volume {
        Volume {
            world_from_index,
            index_from_world: world_from_index.inverse(),
            brick_lo,
            dims,
            table,
            bricks,
            values,
            pyramid,
            report,
            occupancy: std::sync::OnceLock::new(),
            reading_ahead: std::sync::atomic::AtomicBool::new(false),
        }
    }

    fn empty(world_from_index: DAffine3, index_from_world: DAffine3) -> Volume {
        Volume {
            world_from_index,
            index_from_world,
            brick_lo: IVec3::ZERO,
            dims: IVec3::ZERO,
            table: Buffer::default(),
            bricks: Buffer::default(),
            values: Buffer::default(),
            pyramid: Pyramid::default(),
            report: BuildReport::default(),
            occupancy: std::sync::OnceLock::new(),
            reading_ahead: std::sync::atomic::AtomicBool::new(false),
        }
    }

    /// True when the volume holds no bricks.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.bricks.is_empty()
    }

    /// Affine map from index to world space.
    #[must_use]
    pub fn world_from_index(&self) -> DAffine3 {
        self.world_from_index
    }

    /// Affine map from world to index space.
    #[must_use]
    pub fn index_from_world(&self) -> DAffine3 {
        self.index_from_world
    }

    /// The volume placed in the world by `world_from_file` (invertible), applied after
    /// the file's own transform: `world_from_index` becomes `world_from_file ·
    /// world_from_index`. Index space, and so every brick, value and pyramid node, stays
    /// as it is; what is built from world space (majorants, the FNEE proxy, the camera's
    /// framing) is built after.
    #[must_use]
    pub fn placed(mut self, world_from_file: DAffine3) -> Volume {
        self.world_from_index = world_from_file * self.world_from_index;
        self.index_from_world = self.world_from_index.inverse();
        self
    }

    /// Index-space box covered by the brick table: `[lo, hi]`, voxel faces included.
    pub fn index_bounds(&self) -> Bounds3 {
        let lo = (self.brick_lo * BRICK).as_dvec3() - 0.5;
        let hi = ((self.brick_lo + self.dims) * BRICK).as_dvec3() - 0.5;
        Bounds3 { lo, hi }
    }

    /// Number of stored bricks.
    #[must_use]
    pub fn brick_count(&self) -> usize {
        self.bricks.len()
    }

    /// Bricks stored with at least one dense channel.
    #[must_use]
    pub fn dense_brick_count(&self) -> usize {
        self.bricks
            .iter()
            .filter(|b| {
                matches!(b.density.get(), Slot::Dense(_))
                    || matches!(b.source.get(), Slot::Dense(_))
            })
            .count()
    }

    /// Bytes of bricks, table, values and pyramid, wherever they live (heap or mapped).
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        self.table.byte_len()
            + self.bricks.byte_len()
            + self.values.byte_len()
            + self.pyramid.memory_bytes()
    }

    /// Heap bytes held (0 for the arrays of a mapped cache file).
    #[must_use]
    pub fn heap_bytes(&self) -> usize {
        self.table.heap_bytes()
            + self.bricks.heap_bytes()
            + self.values.heap_bytes()
            + self.pyramid.heap_bytes()
    }

    /// True when the volume's arrays are mapped from a cache file.
    #[must_use]
    pub fn is_mapped(&self) -> bool {
        self.values.is_mapped() || self.bricks.is_mapped()
    }

    /// Table cell of brick coordinate `b`, or `None` outside the table.
    #[inline]
    pub fn cell(&self, b: IVec3) -> Option<usize> {
        let r = b - self.brick_lo;
        if r.cmplt(IVec3::ZERO).any() || r.cmpge(self.dims).any() {
            return None;
        }
        Some(
            r.x as usize
                + self.dims.x as usize * (r.y as usize + self.dims.y as usize * r.z as usize),
        )
    }

    /// The brick at brick coordinate `b`, if any.
    #[inline]
    pub fn brick(&self, b: IVec3) -> Option<&Brick> {
        let i = *self.table.get(self.cell(b)?)?;
        self.bricks.get(i as usize)
    }

    /// The bricks at `b + c`, `c ∈ {0,1}³` (bit 0: +x, bit 1: +y, bit 2: +z), each what
    /// [`Volume::brick`] gives with its number in the brick array: the voxel bricks a dual
    /// brick's cells read. The table cell
    /// of `b` and the range checks are worked out once per axis, not once per brick (the
    /// trilinear walk enters a dual brick every few cells it crosses).
    #[inline]
    pub fn brick_block(&self, b: IVec3) -> [Option<(u32, &Brick)>; 8] {
        let r = b - self.brick_lo;
        let dims = self.dims;
        // Whether offset 0 and offset 1 stay inside the table, per axis
        let inside = |v: i32, n: i32| [v >= 0 && v < n, v + 1 >= 0 && v + 1 < n];
        let (ix, iy, iz) = (inside(r.x, dims.x), inside(r.y, dims.y), inside(r.z, dims.z));
        let (sy, sz) = (dims.x as isize, dims.x as isize * dims.y as isize);
        let base = r.x as isize + sy * r.y as isize + sz * r.z as isize;
        std::array::from_fn(|c| {
            let (ox, oy, oz) = (c & 1, (c >> 1) & 1, c >> 2);
            if !(ix[ox] && iy[oy] && iz[oz]) {
                return None;
            }
            // In range: every coordinate of `r + offset` is inside the table
            let cell = (base + ox as isize + sy * oy as isize + sz * oz as isize) as usize;
            let index = *self.table.get(cell)?;
            Some((index, self.bricks.get(index as usize)?))
        })
    }

    /// Value of a slot at local voxel `(x,y,z)`.
    #[inline]
    pub fn slot_value(&self, slot: PackedSlot, x: i32, y: i32, z: i32) -> f32 {
        slot_at(&self.values, slot, brick_offset(x, y, z))
    }

    /// Density and source of voxel `ijk` (nearest-voxel lookup; 0 outside all bricks).
    pub fn voxel(&self, ijk: IVec3) -> VoxelValues {
        let b =
            IVec3::new(floor_div(ijk.x, BRICK), floor_div(ijk.y, BRICK), floor_div(ijk.z, BRICK));
        match self.brick(b) {
            None => VoxelValues::ZERO,
            Some(br) => {
                let l = ijk - b * BRICK;
                VoxelValues {
                    density: self.slot_value(br.density, l.x, l.y, l.z),
                    source: self.slot_value(br.source, l.x, l.y, l.z),
                }
            }
        }
    }

    /// Density and source of the 8 voxels `cell + c`, `c ∈ {0,1}³` (bit 0: +x, bit 1: +y,
    /// bit 2: +z), each what [`Volume::voxel`] gives: the corners of a trilinear lookup.
    ///
    /// Each brick the corners lie in is found once: one when all 8 lie in one brick (7
    /// cells in 8 along each axis), else 2, 4 or 8. A corner's brick and offset come from
    /// the table of the 9³ voxels a cell's corners can reach (`trilinear::dual`), not
    /// from interleaving its coordinates' bits: one load instead of the bit arithmetic
    /// (measured in docs/BENCHMARKS.md, "Interpolation: trilinear vs nearest").
    pub fn voxel_block(&self, cell: IVec3) -> [VoxelValues; 8] {
        let l = IVec3::new(
            cell.x.rem_euclid(BRICK),
            cell.y.rem_euclid(BRICK),
            cell.z.rem_euclid(BRICK),
        );
        let b = IVec3::new(
            floor_div(cell.x, BRICK),
            floor_div(cell.y, BRICK),
            floor_div(cell.z, BRICK),
        );
        let base = window_index(l);
        let edge = l.cmpeq(IVec3::splat(BRICK - 1)).bitmask() as usize;
        let read = |br: &Brick, o: usize| VoxelValues {
            density: slot_at(&self.values, br.density, o),
            source: slot_at(&self.values, br.source, o),
        };
        // Plain loops: as `array::from_fn` the per-corner closure may be left out of line,
        // depending on how unrelated code falls into codegen units
        if edge == 0 {
            let mut out = [VoxelValues::ZERO; 8];
            if let Some(br) = self.brick(b) {
                for (c, v) in out.iter_mut().enumerate() {
                    *v = read(br, window_slot(base + CORNER_STEP[c]).1);
                }
            }
            return out;
        }
        // On a brick edge along the axes in `edge`: the corners' bricks are `b + k` for
        // the `k` within those axes
        let mut bricks: [Option<&Brick>; 8] = [None; 8];
        for (k, brick) in bricks.iter_mut().enumerate() {
            if k & !edge == 0 {
                *brick = self.brick(b + corner_offset(k));
            }
        }
        let mut out = [VoxelValues::ZERO; 8];
        for (c, v) in out.iter_mut().enumerate() {
            let (k, o) = window_slot(base + CORNER_STEP[c]);
            *v = bricks[k].map_or(VoxelValues::ZERO, |br| read(br, o));
        }
        out
    }

    /// Albedo factor of voxel `ijk` (1 outside bricks or without an albedo grid).
    #[must_use]
    pub fn voxel_albedo(&self, ijk: IVec3) -> f32 {
        let b =
            IVec3::new(floor_div(ijk.x, BRICK), floor_div(ijk.y, BRICK), floor_div(ijk.z, BRICK));
        self.brick(b).map_or(1.0, |br| {
            let l = ijk - b * BRICK;
            self.slot_value(br.albedo, l.x, l.y, l.z)
        })
    }

    /// Density and source at an index-space point: the voxel `⌊p + ½⌋`.
    pub fn lookup_index(&self, p_index: DVec3) -> VoxelValues {
        self.voxel((p_index + 0.5).floor().as_ivec3())
    }

    /// Density and source at a world-space point.
    pub fn lookup_world(&self, p_world: DVec3) -> VoxelValues {
        self.lookup_index(self.index_from_world.transform_point3(p_world))
    }

    /// World-space volume of one voxel, `|det A|`.
    #[must_use]
    pub fn voxel_volume(&self) -> f64 {
        self.world_from_index.matrix3.determinant().abs()
    }
}

impl Volume {
    /// Pyramid levels, finest (one node per brick-table cell) first.
    #[must_use]
    pub fn pyramid_levels(&self) -> &[super::pyramid::Level] {
        &self.pyramid.levels
    }
}

/// Brick access for the light-sampling builders (`volume::proxy`, `light::nee`), which
/// must visit every voxel exactly once and sum power in a fixed order.
impl Volume {
    /// Brick coordinates (brick origin / 8) covered by the brick table: `lo .. lo + dims`.
    #[must_use]
    pub fn brick_range(&self) -> (IVec3, IVec3) {
        (self.brick_lo, self.dims)
    }

    /// Density and source of local voxel `l` (each component in `0..8`) of `brick`.
    #[inline]
    pub fn brick_voxel(&self, brick: &Brick, l: IVec3) -> VoxelValues {
        VoxelValues {
            density: self.slot_value(brick.density, l.x, l.y, l.z),
            source: self.slot_value(brick.source, l.x, l.y, l.z),
        }
    }

    /// The 512 values of a dense slot in brick order ([`brick_offset`]); `None` for a
    /// constant slot, or a block index outside the value array (a damaged cache).
    #[inline]
    pub fn slot_block(&self, slot: PackedSlot) -> Option<&[f32; 512]> {
        match slot.get() {
            Slot::Constant(_) => None,
            Slot::Dense(block) => {
                self.values.get(block as usize * 512..(block as usize + 1) * 512)?.try_into().ok()
            }
        }
    }

    /// `Some((density, source))` when both channels of `brick` are constant.
    #[inline]
    #[must_use]
    pub fn brick_constant(brick: &Brick) -> Option<(f32, f32)> {
        match (brick.density.get(), brick.source.get()) {
            (Slot::Constant(d), Slot::Constant(s)) => Some((d, s)),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::brick_offset;

    #[test]
    fn brick_local_inverts_brick_offset() {
        for i in 0..512 {
            let l = super::brick_local(i);
            assert_eq!(brick_offset(l.x, l.y, l.z), i);
        }
    }

    #[test]
    fn brick_offset_is_a_bijection_with_cache_line_blocks() {
        let mut seen = [false; 512];
        for x in 0..8 {
            for y in 0..8 {
                for z in 0..8 {
                    let o = brick_offset(x, y, z);
                    assert!(!seen[o]);
                    seen[o] = true;
                    // 16 floats per 64-byte line: a 2×2×4 block shares a line.
                    assert_eq!(o / 16, brick_offset(x & !1, y & !1, z & !3) / 16);
                }
            }
        }
    }
}
