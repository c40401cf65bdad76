//! The dual lattice of a [`Volume`] (METHOD.md §12): the cells the trilinear walk steps
//! through, their bricks and pyramid, and the [`CubicSegment`] each yields.
//!
//! **Cells.** Dual cell `i` is `[i, i+1]³` in index space; its 8 corners are the voxel
//! centres `i + c`, `c ∈ {0,1}³` (bit 0: +x, bit 1: +y, bit 2: +z), and trilinear
//! weights never reach beyond them. With lattice shift 0 (cell `i` spans `[i − 0, i + 1 − 0]`)
//! the walk of `volume::dda` steps through them as it steps through voxels (shift ½).
//!
//! **Bricks.** Dual brick `b` holds dual cells `8b … 8b+7` and reads voxels `8b … 8b+8`,
//! i.e. voxel bricks `b + {0,1}³`. The walk fetches those 8 brick records once when it
//! enters a dual brick ([`DualBricks`]); a missing brick reads as a constant record
//! (density and source 0, albedo 1), so a corner read is one slot read, no branch on
//! presence. The dual table spans bricks `brick_lo − 1 … brick_lo + dims − 1`: one more
//! layer on the low side, whose cells reach the volume's first voxels.
//!
//! **Empty cells.** Entering a dual brick also forms which of its 64 blocks of 2³ cells
//! may read a voxel that is not empty ([`dual_block_mask`], from the 8 voxel bricks'
//! [`BlockMasks`]). A cell in a clear block has 8 empty corners, and the walk steps
//! through a run of such cells without reading a corner or building a piece, giving one
//! empty piece for the run (`Cells::known_empty`; the pieces are what theirs merged into,
//! bit for bit). In a fire many dense cells lie in clear blocks. Shadow rays' density walk
//! (`density`) does not ask: it crosses few cells per dual brick, and forming the masks
//! costs it more than they save, where the full walk's free paths still gain (measured in
//! docs/BENCHMARKS.md, "Interpolation: trilinear vs nearest").
//!
//! **Clip box.** The union of the cells that can be non-zero: `[8·brick_lo − 1,
//! 8·(brick_lo + dims)]`, the nearest volume's index bounds grown by ½ voxel on every side
//! (a voxel's trilinear support is its centre ± 1).
//!
//! **Pyramid.** The level-0 node of dual brick `b` is the union of the volume's level-0
//! bounds at `b + {0,1}³` (missing = [`NodeBounds::ZERO`]): the bounds of every voxel any
//! of its cells reads, i.e. of its support dilated by one voxel toward +x, +y, +z. Coarser
//! levels are unions of children ([`Pyramid::from_base`]). A uniform node is therefore
//! exactly constant over all its dual cells, and is crossed as one constant piece. It is
//! built from the volume's pyramid alone: no voxel is read (a cache may be tens of GB).

use std::sync::atomic::{AtomicU64, Ordering};

use glam::{DVec3, IVec3};
use rayon::prelude::*;

use super::window::{corner_offset, window_index, window_slot, CORNER_STEP};
use super::CubicSegment;
use crate::brick::Volume;
use crate::dda::{CellBox, CellTable, Cells, IndexLine};
use crate::field::VoxelValues;
use crate::grid::LEAF_VOXELS;
use crate::layout::{brick_local, Brick, PackedSlot, Slot, BRICK};
use crate::pyramid::{Level, NodeBounds, Pyramid};

/// One channel of one voxel brick, decoded once when the walk enters a dual brick: its
/// 512 values, or a constant (also for a missing brick, and for a block a damaged cache
/// places past the value array: 0, as [`Volume::slot_value`] reads it).
#[derive(Clone, Copy, Debug)]
pub(super) struct Channel<'a> {
    block: Option<&'a [f32; LEAF_VOXELS]>,
    constant: f32,
}

impl<'a> Channel<'a> {
    pub(super) fn new(volume: &'a Volume, slot: PackedSlot) -> Channel<'a> {
        match slot.get() {
            Slot::Constant(v) => Channel { block: None, constant: v },
            Slot::Dense(block) => {
                let start = block as usize * LEAF_VOXELS;
                let block =
                    volume.values.get(start..start + LEAF_VOXELS).and_then(|v| v.try_into().ok());
                Channel { block, constant: 0.0 }
            }
        }
    }

    pub(super) const fn constant(v: f32) -> Channel<'static> {
        Channel { block: None, constant: v }
    }

    /// The value at brick-order offset `o` (`< 512`).
    #[inline]
    pub(super) fn at(&self, o: usize) -> f32 {
        match self.block {
            Some(values) => values[o & (LEAF_VOXELS - 1)],
            None => self.constant,
        }
    }
}

/// The channels of one voxel brick: density, source, albedo.
#[derive(Clone, Copy, Debug)]
struct BrickChannels<'a> {
    density: Channel<'a>,
    source: Channel<'a>,
    albedo: Channel<'a>,
}

/// What a missing voxel brick reads as: empty space.
const EMPTY_BRICK: BrickChannels<'static> = BrickChannels {
    density: Channel::constant(0.0),
    source: Channel::constant(0.0),
    albedo: Channel::constant(1.0),
};

/// `FACE[a][s]`: the corners on the low (`s = 0`) or high (`s = 1`) face along axis `a`.
/// Stepping forward along `a`, the new cell reads its high face and its low face is the
/// old high face (corner `c` of the new cell is corner `c ^ (1 << a)` of the old one);
/// stepping back, the other way round.
const FACE: [[[usize; 4]; 2]; 3] =
    [[[0, 2, 4, 6], [1, 3, 5, 7]], [[0, 1, 4, 5], [2, 3, 6, 7]], [[0, 1, 2, 3], [4, 5, 6, 7]]];

/// Per voxel brick of a volume, which of its 64 blocks of 2×2×2 voxels hold a voxel whose
/// density or source is not `+0.0` (bit `x + 4y + 16z` for the block of voxels `2x … 2x+1`,
/// …): where a bit is clear, every voxel of the block reads as empty, bit for bit (module
/// docs, "Empty cells").
///
/// A brick with two constant channels answers from its record. A dense one is read once,
/// when a walk first enters a dual brick that reads it, and its mask kept: 8 bytes per
/// brick, no voxel read up front (a cache may be tens of GB). 0 means "not known yet",
/// so a dense brick whose voxels all read as empty (the builder stores such a brick as
/// constant) is read again each time, never given a wrong mask; threads racing on a
/// brick store the same value.
#[derive(Debug, Default)]
pub struct BlockMasks {
    known: Box<[AtomicU64]>,
}

impl BlockMasks {
    /// Nothing known yet, for the bricks of `volume`.
    #[must_use]
    pub fn new(volume: &Volume) -> BlockMasks {
        BlockMasks { known: (0..volume.bricks.len()).map(|_| AtomicU64::new(0)).collect() }
    }

    /// Bytes held.
    #[must_use]
    pub fn bytes(&self) -> usize {
        std::mem::size_of_val(&*self.known)
    }

    /// The mask of brick number `index` of `volume`, record `brick`.
    #[inline]
    fn get(&self, volume: &Volume, index: u32, brick: &Brick) -> u64 {
        if let (Slot::Constant(d), Slot::Constant(s)) = (brick.density.get(), brick.source.get()) {
            return if (d.to_bits() | s.to_bits()) == 0 { 0 } else { u64::MAX };
        }
        let Some(known) = self.known.get(index as usize) else { return u64::MAX };
        match known.load(Ordering::Relaxed) {
            0 => {
                let mask = voxel_block_mask(volume, brick);
                known.store(mask, Ordering::Relaxed);
                mask
            }
            mask => mask,
        }
    }
}

/// [`BlockMasks`]' mask of a brick, from its voxels: the channels as the walk reads them
/// ([`Channel`]: a block past the value array reads 0).
#[cold]
#[inline(never)]
fn voxel_block_mask(volume: &Volume, brick: &Brick) -> u64 {
    let (density, source) =
        (Channel::new(volume, brick.density), Channel::new(volume, brick.source));
    let mut mask = 0u64;
    // Brick order is Morton order with a block's 3 bits lowest: offsets 8m … 8m+7 are
    // the voxels of block m, whose first voxel is at local `brick_local(8m)`
    for m in 0..LEAF_VOXELS / 8 {
        if (8 * m..8 * m + 8).any(|o| (density.at(o).to_bits() | source.at(o).to_bits()) != 0) {
            let b: IVec3 = brick_local(8 * m) >> 1;
            mask |= 1u64 << (b.x + 4 * b.y + 16 * b.z);
        }
    }
    mask
}

/// The dual cells of a volume as a lattice for the hierarchical DDA (shift 0), with the
/// dual pyramid built by `dual_pyramid`.
#[derive(Clone, Copy, Debug)]
pub struct DualCells<'a> {
    volume: &'a Volume,
    pyramid: &'a Pyramid,
    blocks: &'a BlockMasks,
}

impl<'a> DualCells<'a> {
    /// The dual cells of `volume`; `pyramid` must be [`dual_pyramid`]`(volume)` and
    /// `blocks` [`BlockMasks::new`]`(volume)`.
    #[must_use]
    pub fn new(volume: &'a Volume, pyramid: &'a Pyramid, blocks: &'a BlockMasks) -> Self {
        DualCells { volume, pyramid, blocks }
    }

    /// The dual block mask of a dual brick whose voxel bricks are `bricks`
    /// ([`Volume::brick_block`]).
    #[inline]
    fn block_mask(&self, bricks: &[Option<(u32, &Brick)>; 8]) -> u64 {
        dual_block_mask(
            bricks
                .map(|b| b.map_or(0, |(index, brick)| self.blocks.get(self.volume, index, brick))),
        )
    }

    /// The volume whose voxels the cells' corners are.
    pub(super) fn voxels(&self) -> &'a Volume {
        self.volume
    }
}

/// The channels of voxel bricks `b + {0,1}³` of dual brick `b`, decoded in corner order,
/// and the last cell read from them.
#[derive(Clone, Copy, Debug)]
pub struct DualBricks<'a> {
    bricks: [BrickChannels<'a>; 8],
    /// Local index of the last cell read (far away before the first) and its corners:
    /// the walk steps to a face neighbour, which shares 4 of them.
    last: IVec3,
    corners: [VoxelValues; 8],
    albedo: [f32; 8],
    /// Every voxel of the 8 bricks has albedo factor 1 (no albedo grid there): `albedo`
    /// then holds 1s and corner reads skip the channel (the same image, fewer instructions
    /// wherever a medium has no albedo grid).
    albedo_one: bool,
    /// Which blocks of 2³ cells may hold a cell with a corner that is not empty
    /// ([`dual_block_mask`]).
    blocks: u64,
}

/// [`DualBricks::last`] before any cell of the brick was read: no cell is its neighbour.
pub(super) const NO_CELL: IVec3 = IVec3::splat(-1000);

/// What a walk keeps of the last dual cell's corners ([`DualBricks`], and
/// `density::DensityBricks`): a cell's corners are read into it, or moved across from
/// the neighbour cell that shares them ([`step_corners`]).
pub(super) trait CornerRecord {
    /// The cell whose corners the record holds ([`NO_CELL`] for none).
    fn last(&self) -> IVec3;
    /// Marks the record as holding the corners of local cell `l`.
    fn set_last(&mut self, l: IVec3);
    /// Corner `to` takes what corner `from` holds.
    fn shift(&mut self, to: usize, from: usize);
    /// Reads corner `c` of the local cell whose [`window_index`] is `cell`.
    fn load(&mut self, cell: usize, c: usize);
}

/// Fills `record` with the corners of local cell `l`: only the 4 new ones when the walk
/// stepped across one face from the last cell (the other 4 move across: corner `c` of the
/// new cell is corner `c ^ (1 << a)` of the old one), all 8 otherwise; the record then
/// holds cell `l`.
#[inline]
pub(super) fn step_corners(record: &mut impl CornerRecord, l: IVec3) {
    let step = l - record.last();
    let face = match (step.x, step.y, step.z) {
        (s, 0, 0) if s.abs() == 1 => Some((0, s > 0)),
        (0, s, 0) if s.abs() == 1 => Some((1, s > 0)),
        (0, 0, s) if s.abs() == 1 => Some((2, s > 0)),
        _ => None,
    };
    // Corner `c` is at window index `cell + CORNER_STEP[c]`: one index per cell, not one
    // vector sum per corner
    let cell = window_index(l);
    match face {
        Some((a, forward)) => {
            let bit = 1 << a;
            for &c in &FACE[a][usize::from(!forward)] {
                record.shift(c, c ^ bit);
            }
            for &c in &FACE[a][usize::from(forward)] {
                record.load(cell, c);
            }
        }
        None => {
            for c in 0..8 {
                record.load(cell, c);
            }
        }
    }
    record.set_last(l);
}

/// Cell-local coordinates of the index-space line at `t` in dual cell `i` (shift 0: the
/// unshifted line), clamped to the cell against rounding.
#[inline]
pub(super) fn cell_local(line: &IndexLine, t: f64, i: IVec3) -> DVec3 {
    (line.o + line.d * t - i.as_dvec3()).clamp(DVec3::ZERO, DVec3::ONE)
}

impl Default for DualBricks<'_> {
    /// Empty space's records, no cell read.
    fn default() -> Self {
        DualBricks {
            bricks: [EMPTY_BRICK; 8],
            last: NO_CELL,
            corners: [VoxelValues::ZERO; 8],
            albedo: [1.0; 8],
            albedo_one: true,
            blocks: 0,
        }
    }
}

/// `X0`, `Y0`, `Z0`: the bits of a 4³ block mask (bit `x + 4y + 16z`) with `x`, `y` or
/// `z` = 0.
const X0: u64 = 0x1111_1111_1111_1111;
const Y0: u64 = 0x000f_000f_000f_000f;
const Z0: u64 = 0xffff;

/// The blocks of 2³ cells of a dual brick that may hold a cell with a non-empty corner,
/// from `voxel[k]`, the [`BlockMasks`] mask of voxel brick `b + k` (bit 0 of `k`: +x,
/// bit 1: +y, bit 2: +z; 0 for a missing brick).
///
/// Block `s` of the dual brick holds cells `2s … 2s+1`, whose corners are the voxels
/// `2s … 2s+2` of the 9³ it reads: voxel blocks `s` and `s + 1`, where block 4 along an
/// axis is block 0 of the next voxel brick. So its bit is the union of voxel blocks
/// `s + {0,1}³`: a dilation by one block toward +x, +y and +z across the 8 masks, one
/// axis at a time (a shift within a row or slab, and the next brick's first row or slab
/// moved in at the end).
#[must_use]
fn dual_block_mask(voxel: [u64; 8]) -> u64 {
    let along_x = |lo: u64, hi: u64| lo | ((lo >> 1) & !(X0 << 3)) | ((hi & X0) << 3);
    let along_y = |lo: u64, hi: u64| lo | ((lo >> 4) & !(Y0 << 12)) | ((hi & Y0) << 12);
    let x = [
        along_x(voxel[0], voxel[1]),
        along_x(voxel[2], voxel[3]),
        along_x(voxel[4], voxel[5]),
        along_x(voxel[6], voxel[7]),
    ];
    let (near, far) = (along_y(x[0], x[1]), along_y(x[2], x[3]));
    near | (near >> 16) | ((far & Z0) << 48)
}

/// The bit of local cell `l` (each coordinate `0..8`) in a [`dual_block_mask`].
#[inline]
fn block_bit(l: IVec3) -> u64 {
    1 << ((l.x >> 1) + 4 * (l.y >> 1) + 16 * (l.z >> 1))
}

impl CornerRecord for DualBricks<'_> {
    #[inline]
    fn last(&self) -> IVec3 {
        self.last
    }

    #[inline]
    fn set_last(&mut self, l: IVec3) {
        self.last = l;
    }

    #[inline]
    fn shift(&mut self, to: usize, from: usize) {
        self.corners[to] = self.corners[from];
        self.albedo[to] = self.albedo[from];
    }

    /// Reads corner `c` of local cell `l`: voxel `l + c` of the 9³ the dual brick reads,
    /// in voxel brick `(l + c) / 8` at local `(l + c) mod 8`.
    #[inline]
    fn load(&mut self, cell: usize, c: usize) {
        let (k, o, density) = self.load_values(cell, c);
        self.albedo[c] = if density > 0.0 { self.bricks[k].albedo.at(o) } else { 1.0 };
    }
}

impl DualBricks<'_> {
    /// Reads corner `c`'s density and source (not its albedo); returns its voxel brick,
    /// offset and density.
    #[inline]
    fn load_values(&mut self, cell: usize, c: usize) -> (usize, usize, f32) {
        let (k, o) = window_slot(cell + CORNER_STEP[c]);
        let brick = &self.bricks[k];
        let density = brick.density.at(o);
        self.corners[c] = VoxelValues { density, source: brick.source.at(o) };
        (k, o, density)
    }
}

/// A [`DualBricks`] whose albedo factors are all 1 ([`DualBricks::albedo_one`]), read as
/// such: its corners move and load without the albedo channel, which holds 1s.
struct ValuesOnly<'r, 'a>(&'r mut DualBricks<'a>);

impl CornerRecord for ValuesOnly<'_, '_> {
    #[inline]
    fn last(&self) -> IVec3 {
        self.0.last
    }

    #[inline]
    fn set_last(&mut self, l: IVec3) {
        self.0.last = l;
    }

    #[inline]
    fn shift(&mut self, to: usize, from: usize) {
        self.0.corners[to] = self.0.corners[from];
    }

    #[inline]
    fn load(&mut self, cell: usize, c: usize) {
        self.0.load_values(cell, c);
    }
}

/// A uniform node's or empty space's dual cell: every corner the same.
#[derive(Clone, Copy, Debug)]
pub struct DualCell {
    values: VoxelValues,
    /// 1 where the density is 0.
    albedo: f32,
}

impl DualCell {
    /// Every corner's density.
    pub(super) fn density(self) -> f32 {
        self.values.density
    }
}

impl<'a> Cells for DualCells<'a> {
    const SHIFT: f64 = 0.0;
    type Piece = CubicSegment;
    type Dense = DualBricks<'a>;
    type Cell = DualCell;

    #[inline]
    fn volume(&self) -> &Volume {
        self.volume
    }

    #[inline]
    fn table(&self) -> CellTable<'_> {
        CellTable {
            brick_lo: self.volume.brick_lo - 1,
            dims: self.volume.dims + 1,
            levels: &self.pyramid.levels,
        }
    }

    #[inline]
    fn cell_box(&self) -> CellBox {
        CellBox {
            lo: self.volume.brick_lo * BRICK - 1,
            hi: (self.volume.brick_lo + self.volume.dims) * BRICK,
        }
    }

    fn dense(&self, b: IVec3, dense: &mut DualBricks<'a>) -> bool {
        let mut any = false;
        let volume = self.volume;
        // A plain loop: as `array::from_fn` the per-corner closure may be left out of line,
        // an extra call and a copy of each record per dual brick entered, depending on how
        // unrelated code is inlined
        let bricks = volume.brick_block(b);
        // Albedo 1 everywhere (a missing brick reads as 1, and so does a constant slot of
        // 1.0 whatever its tag, as `Channel::new` decodes it): then the albedo channels are
        // never read, and not decoded either.
        let albedo_one = bricks.iter().all(|b| b.is_none_or(|(_, b)| matches!(b.albedo.get(), Slot::Constant(v) if v.to_bits() == 1.0f32.to_bits())));
        dense.blocks = self.block_mask(&bricks);
        for (record, brick) in dense.bricks.iter_mut().zip(bricks) {
            *record = match brick {
                Some((_, brick)) => {
                    any = true;
                    BrickChannels {
                        density: Channel::new(volume, brick.density),
                        source: Channel::new(volume, brick.source),
                        albedo: if albedo_one {
                            Channel::constant(1.0)
                        } else {
                            Channel::new(volume, brick.albedo)
                        },
                    }
                }
                None => EMPTY_BRICK,
            };
        }
        // No cell of this brick read yet: the first reads all 8 corners
        dense.last = NO_CELL;
        dense.albedo_one = albedo_one;
        if albedo_one {
            dense.albedo = [1.0; 8];
        }
        any
    }

    /// Reads the 8 corners, or only the 4 new ones when the walk stepped across one face
    /// (the other 4 are the previous cell's: 12 value reads instead of 24).
    #[inline]
    fn dense_piece(
        &self,
        dense: &mut DualBricks<'a>,
        origin: IVec3,
        i: IVec3,
        t0: f64,
        t1: f64,
        line: &IndexLine,
    ) -> CubicSegment {
        // Cells in empty blocks never come here ([`Cells::known_empty`])
        if dense.albedo_one {
            step_corners(&mut ValuesOnly(dense), i - origin);
        } else {
            step_corners(dense, i - origin);
        }
        CubicSegment::cell(t0, t1, cell_local(line, t0, i), line.d, dense.corners, dense.albedo)
    }

    /// A cell in a block of the dual brick whose voxels all read as empty (module docs,
    /// "Empty cells").
    #[inline]
    fn known_empty(dense: &DualBricks<'a>, l: IVec3) -> bool {
        dense.blocks & block_bit(l) == 0
    }

    /// Every corner of the last empty cell is empty (density and source +0, so albedo
    /// factor 1): what reading them would have left in the record.
    #[inline]
    fn after_empty(dense: &mut DualBricks<'a>, l: IVec3) {
        dense.corners = [VoxelValues::ZERO; 8];
        dense.albedo = [1.0; 8];
        dense.last = l;
    }

    #[inline]
    fn uniform(node: &NodeBounds) -> DualCell {
        DualCell {
            values: VoxelValues { density: node.density_max, source: node.source_max },
            albedo: node.uniform_albedo(),
        }
    }

    #[inline]
    fn empty() -> DualCell {
        DualCell { values: VoxelValues::ZERO, albedo: 1.0 }
    }

    #[inline]
    fn piece(&self, cell: DualCell, t0: f64, t1: f64, _line: &IndexLine) -> CubicSegment {
        CubicSegment::constant_piece(t0, t1, cell.values, cell.albedo)
    }

    #[inline]
    fn mergeable(piece: &CubicSegment) -> bool {
        piece.constant
    }

    #[inline]
    fn merge(into: &mut CubicSegment, next: &CubicSegment) -> bool {
        let same = into.constant
            && next.constant
            && into.corners[0].density.to_bits() == next.corners[0].density.to_bits()
            && into.corners[0].source.to_bits() == next.corners[0].source.to_bits()
            && into.albedo[0].to_bits() == next.albedo[0].to_bits();
        if same {
            into.t1 = next.t1;
        }
        same
    }
}

/// The union of `level`'s nodes `c − 1 + {0,1}³` (nodes outside it count as
/// [`NodeBounds::ZERO`]): what dual entry `c` of that level's table reads. On level 0 it is
/// the dual pyramid's node `c` ([`dual_pyramid`]); on a coarser level, a superset of it
/// (`volume::majorant`).
#[must_use]
pub fn dual_union(level: &Level, c: IVec3) -> NodeBounds {
    let at = |n: IVec3| {
        if n.cmpge(IVec3::ZERO).all() && n.cmplt(level.dims).all() {
            *level.get(n)
        } else {
            NodeBounds::ZERO
        }
    };
    let r = c - 1;
    (1..8).fold(at(r), |acc, i| acc.union(at(r + corner_offset(i))))
}

/// The dual pyramid of `volume` (see the module docs): level 0 over the dual table of
/// `dims + 1` bricks from `brick_lo − 1`, built in parallel from the volume's level 0.
#[must_use]
pub fn dual_pyramid(volume: &Volume) -> Pyramid {
    let dims = volume.dims;
    let Some(level0) = volume.pyramid.levels.first().filter(|_| dims.cmpgt(IVec3::ZERO).all())
    else {
        return Pyramid::default();
    };
    let nd = dims + 1;
    let slab = (nd.x * nd.y) as usize;
    let mut base = vec![NodeBounds::ZERO; slab * nd.z as usize];
    base.par_chunks_mut(slab).enumerate().for_each(|(z, nodes)| {
        for (k, node) in nodes.iter_mut().enumerate() {
            // Dual table entry c reads volume table entries c − 1 + {0,1}³
            *node = dual_union(
                level0,
                IVec3::new((k % nd.x as usize) as i32, (k / nd.x as usize) as i32, z as i32),
            );
        }
    });
    Pyramid::from_base(nd, base)
}

#[cfg(test)]
mod tests;
