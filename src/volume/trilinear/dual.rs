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

use glam::{DVec3, IVec3};
use rayon::prelude::*;

use super::poly;
use super::CubicSegment;
use crate::volume::brick::{Brick, PackedSlot, Volume, BRICK};
use crate::volume::dda::{CellBox, CellTable, Cells, IndexLine};
use crate::volume::field::VoxelValues;
use crate::volume::pyramid::{NodeBounds, Pyramid};

/// Corner `c` of a dual cell as an offset: bit 0 → +x, bit 1 → +y, bit 2 → +z.
#[inline]
#[must_use]
pub(crate) const fn corner_offset(c: usize) -> IVec3 {
    IVec3::new((c & 1) as i32, ((c >> 1) & 1) as i32, ((c >> 2) & 1) as i32)
}

/// What a missing voxel brick reads as: empty space.
const EMPTY_BRICK: Brick = Brick { density: PackedSlot::constant(0.0), source: PackedSlot::constant(0.0), albedo: PackedSlot::constant(1.0) };

/// The dual cells of a volume as a lattice for the hierarchical DDA (shift 0), with the
/// dual pyramid built by [`dual_pyramid`].
#[derive(Clone, Copy, Debug)]
pub struct DualCells<'a> {
    volume: &'a Volume,
    pyramid: &'a Pyramid,
}

impl<'a> DualCells<'a> {
    /// The dual cells of `volume`; `pyramid` must be [`dual_pyramid`]`(volume)`.
    #[must_use]
    pub(crate) fn new(volume: &'a Volume, pyramid: &'a Pyramid) -> Self {
        DualCells { volume, pyramid }
    }
}

/// The brick records of voxel bricks `b + {0,1}³` of dual brick `b`, in corner order, and
/// the last cell read from them.
#[derive(Clone, Copy, Debug)]
pub struct DualBricks {
    bricks: [Brick; 8],
    /// Local index of the last cell read (far away before the first) and its corners:
    /// the walk steps to a face neighbour, which shares 4 of them.
    last: IVec3,
    corners: [VoxelValues; 8],
    albedo: [f32; 8],
}

/// One dual cell as the walk reads it: its index and its 8 corner voxels.
#[derive(Clone, Copy, Debug)]
pub struct DualCell {
    /// Cell index `i` (unused for a uniform node, whose corners all agree).
    i: IVec3,
    corners: [VoxelValues; 8],
    /// Albedo factor per corner, 1 where the corner's density is 0.
    albedo: [f32; 8],
}

impl DualCell {
    fn constant(values: VoxelValues, albedo: f32) -> DualCell {
        DualCell { i: IVec3::ZERO, corners: [values; 8], albedo: [albedo; 8] }
    }

    /// True when all corners agree bit for bit in density, source and albedo.
    #[inline]
    fn is_constant(&self) -> bool {
        let (c0, a0) = (self.corners[0], self.albedo[0]);
        self.corners
            .iter()
            .zip(&self.albedo)
            .all(|(c, a)| c.density.to_bits() == c0.density.to_bits() && c.source.to_bits() == c0.source.to_bits() && a.to_bits() == a0.to_bits())
    }
}

impl Cells for DualCells<'_> {
    const SHIFT: f64 = 0.0;
    type Piece = CubicSegment;
    type Dense = DualBricks;
    type Cell = DualCell;

    #[inline]
    fn volume(&self) -> &Volume {
        self.volume
    }

    #[inline]
    fn table(&self) -> CellTable<'_> {
        CellTable { brick_lo: self.volume.brick_lo - 1, dims: self.volume.dims + 1, levels: &self.pyramid.levels }
    }

    #[inline]
    fn cell_box(&self) -> CellBox {
        CellBox { lo: self.volume.brick_lo * BRICK - 1, hi: (self.volume.brick_lo + self.volume.dims) * BRICK }
    }

    fn dense(&self, b: IVec3) -> Option<DualBricks> {
        let mut any = false;
        let bricks = std::array::from_fn(|c| match self.volume.brick(b + corner_offset(c)) {
            Some(brick) => {
                any = true;
                *brick
            }
            None => EMPTY_BRICK,
        });
        any.then_some(DualBricks { bricks, last: IVec3::splat(-1000), corners: [VoxelValues::ZERO; 8], albedo: [1.0; 8] })
    }

    /// Reads the 8 corners, or only the 4 new ones when the walk stepped across one face
    /// (the other 4 are the previous cell's: 12 slot reads instead of 24).
    #[inline]
    fn read(&self, dense: &mut DualBricks, origin: IVec3, i: IVec3) -> DualCell {
        let l = i - origin;
        let step = l - dense.last;
        // Corners to read: all, or those on the far side of the face crossed along one axis
        let (keep, fresh): (Option<(usize, bool)>, u8) = match (step.x, step.y, step.z) {
            (s, 0, 0) if s.abs() == 1 => (Some((1, s > 0)), if s > 0 { 0b1010_1010 } else { 0b0101_0101 }),
            (0, s, 0) if s.abs() == 1 => (Some((2, s > 0)), if s > 0 { 0b1100_1100 } else { 0b0011_0011 }),
            (0, 0, s) if s.abs() == 1 => (Some((4, s > 0)), if s > 0 { 0b1111_0000 } else { 0b0000_1111 }),
            _ => (None, 0xff),
        };
        if let Some((bit, forward)) = keep {
            // Shared corner c of the new cell is corner c ± bit of the old one
            let (old_c, old_a) = (dense.corners, dense.albedo);
            for c in 0..8 {
                if fresh & (1 << c) == 0 {
                    let from = if forward { c | bit } else { c & !bit };
                    dense.corners[c] = old_c[from];
                    dense.albedo[c] = old_a[from];
                }
            }
        }
        for c in 0..8 {
            if fresh & (1 << c) == 0 {
                continue;
            }
            // Voxel l + c of the 9³ the dual brick reads: brick (l + c) / 8, local (l + c) mod 8
            let v = l + corner_offset(c);
            let brick = &dense.bricks[((v.x >> 3) | ((v.y >> 3) << 1) | ((v.z >> 3) << 2)) as usize];
            let (x, y, z) = (v.x & 7, v.y & 7, v.z & 7);
            let density = self.volume.slot_value(brick.density, x, y, z);
            dense.corners[c] = VoxelValues { density, source: self.volume.slot_value(brick.source, x, y, z) };
            dense.albedo[c] = if density > 0.0 { self.volume.slot_value(brick.albedo, x, y, z) } else { 1.0 };
        }
        dense.last = l;
        DualCell { i, corners: dense.corners, albedo: dense.albedo }
    }

    #[inline]
    fn uniform(node: &NodeBounds) -> DualCell {
        DualCell::constant(VoxelValues { density: node.density_max, source: node.source_max }, node.uniform_albedo())
    }

    #[inline]
    fn empty() -> DualCell {
        DualCell::constant(VoxelValues::ZERO, 1.0)
    }

    #[inline]
    fn piece(&self, cell: DualCell, t0: f64, t1: f64, line: &IndexLine) -> CubicSegment {
        if cell.is_constant() {
            return CubicSegment::constant_piece(t0, t1, cell.corners[0], cell.albedo[0]);
        }
        // Cell-local coordinates at the entry, from the unshifted index-space line
        let f0 = (line.o + line.d * t0 - cell.i.as_dvec3()).clamp(DVec3::ZERO, DVec3::ONE);
        let density = poly::cubic_along(cell.corners.map(|c| f64::from(c.density)), f0, line.d);
        CubicSegment { t0, t1, density, f0, d: line.d, corners: cell.corners, albedo: cell.albedo, constant: false }
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

/// The dual pyramid of `volume` (see the module docs): level 0 over the dual table of
/// `dims + 1` bricks from `brick_lo − 1`, built in parallel from the volume's level 0.
#[must_use]
pub(crate) fn dual_pyramid(volume: &Volume) -> Pyramid {
    let dims = volume.dims;
    let Some(level0) = volume.pyramid.levels.first().filter(|_| dims.cmpgt(IVec3::ZERO).all()) else {
        return Pyramid::default();
    };
    let nd = dims + 1;
    let slab = (nd.x * nd.y) as usize;
    let bounds_at = |rel: IVec3| if rel.cmpge(IVec3::ZERO).all() && rel.cmplt(dims).all() { *level0.get(rel) } else { NodeBounds::ZERO };
    let mut base = vec![NodeBounds::ZERO; slab * nd.z as usize];
    base.par_chunks_mut(slab).enumerate().for_each(|(z, nodes)| {
        for (k, node) in nodes.iter_mut().enumerate() {
            // Dual table entry r reads volume table entries r − 1 + {0,1}³
            let r = IVec3::new((k % nd.x as usize) as i32, (k / nd.x as usize) as i32, z as i32) - 1;
            *node = (1..8).fold(bounds_at(r), |acc, c| acc.union(bounds_at(r + corner_offset(c))));
        }
    });
    Pyramid::from_base(nd, base)
}
