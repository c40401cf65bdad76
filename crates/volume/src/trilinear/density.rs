//! The dual lattice read for density alone: what a shadow ray's optical depth needs
//! ([`crate::Field::optical_depth`]).
//!
//! The walk is the one of [`super::dual`] (the same cells, dual pyramid, skipping and
//! merging), but each corner read is one value instead of three (density, source,
//! albedo) and each piece carries 8 densities instead of 8 voxels' three values: a
//! shadow ray never looks at emission or albedo. It does not skip empty blocks of cells
//! (`dual`, "Empty cells"): it crosses too few cells per dual brick for that to pay. The
//! optical depth of a piece is the same sum `σ_t Σ_c ρ_c W_c` as
//! [`super::CubicSegment`]'s, so transmittance is bit for bit what the full walk gives
//! wherever their pieces agree. They can differ by rounding only where
//! densities agree and sources or albedos do not: such a cell is a constant piece here
//! (`σ_t ρ Δ`) and a cubic one there, and such neighbouring constant pieces merge here.
//!
//! Shadow rays are a large share of a lit render, and this walk costs them far fewer
//! instructions than the full one (measured in docs/BENCHMARKS.md, "Interpolation: trilinear vs nearest").

use glam::{DVec3, IVec3};

use super::dual::{cell_local, step_corners, Channel, CornerRecord, DualCell, DualCells, NO_CELL};
use super::poly;
use super::window::{window_slot, CORNER_STEP};
use crate::brick::Volume;
use crate::dda::{CellBox, CellTable, Cells, IndexLine};
use crate::field::{Piece, Segment};
use crate::overlap::PieceCubics;
use crate::pyramid::NodeBounds;
use plume_core::color::Rgb;

/// A piece of a ray inside one dual cell, with its corners' densities only.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DensityPiece {
    /// Entry distance.
    pub t0: f64,
    /// Exit distance.
    pub t1: f64,
    /// Cell-local coordinates at `u = 0`, each in `[0, 1]`.
    pub f0: DVec3,
    /// Index-space direction per world unit (`df/du`).
    pub d: DVec3,
    /// Densities of the 8 corner voxels (corner `c`: bit 0 +x, bit 1 +y, bit 2 +z).
    pub density: [f32; 8],
    /// True when all 8 densities agree bit for bit: the piece is one [`Segment`].
    pub constant: bool,
}

impl DensityPiece {
    /// The density cubic along the piece (`[ρ, 0, 0, 0]` when constant).
    fn cubic(&self) -> [f64; 4] {
        if self.constant {
            return [f64::from(self.density[0]), 0.0, 0.0, 0.0];
        }
        poly::cubic_along(self.density.map(f64::from), self.f0, self.d)
    }
}

impl Piece for DensityPiece {
    #[inline]
    fn t0(&self) -> f64 {
        self.t0
    }

    #[inline]
    fn t1(&self) -> f64 {
        self.t1
    }

    #[inline]
    fn constant(&self) -> Option<Segment> {
        self.constant.then_some(Segment {
            t0: self.t0,
            t1: self.t1,
            density: self.density[0],
            source: 0.0,
            albedo: 1.0,
        })
    }

    /// `σ_t Σ_c ρ_c W_c(u)`, as [`super::CubicSegment`] computes it.
    #[inline]
    fn optical_depth(&self, sigma_t: f64, u: f64) -> f64 {
        match self.constant() {
            Some(seg) => seg.optical_depth(sigma_t, u),
            None => {
                sigma_t
                    * poly::dot(
                        &self.density.map(f64::from),
                        &poly::integrated_weights(self.f0, self.d, u),
                    )
            }
        }
    }

    fn free_path(&self, sigma_t: f64, od: f64) -> f64 {
        match self.constant() {
            Some(seg) => seg.free_path(sigma_t, od),
            None => poly::solve_integral(&self.cubic(), self.length(), od / sigma_t),
        }
    }

    fn density_at(&self, u: f64) -> f32 {
        poly::eval(&self.cubic(), u).max(0.0) as f32
    }

    /// The density cubic from `offset` on; no emission.
    fn cubics(&self, _le: &impl Fn(f32, f32) -> Rgb, offset: f64) -> PieceCubics {
        let density = if self.constant {
            [f64::from(self.density[0]), 0.0, 0.0, 0.0]
        } else {
            poly::cubic_along(self.density.map(f64::from), self.f0 + self.d * offset, self.d)
        };
        PieceCubics { density, emission: [[0.0; 4]; 3], emits: false }
    }

    /// No source is read: 0.
    fn source_at(&self, _u: f64) -> f32 {
        0.0
    }

    /// No albedo is read: 1.
    fn albedo_at(&self, _u: f64) -> f32 {
        1.0
    }

    fn emission_at(&self, _le: &impl Fn(f32, f32) -> Rgb, _u: f64) -> [f64; 3] {
        [0.0; 3]
    }

    fn emission_integral(&self, _le: &impl Fn(f32, f32) -> Rgb, _u: f64) -> [f64; 3] {
        [0.0; 3]
    }

    fn may_emit(&self) -> bool {
        false
    }
}

/// The density channels of voxel bricks `b + {0,1}³` of dual brick `b`, and the last
/// cell's corner densities (a face neighbour shares 4).
#[derive(Clone, Copy, Debug)]
pub struct DensityBricks<'a> {
    bricks: [Channel<'a>; 8],
    last: IVec3,
    density: [f32; 8],
}

impl Default for DensityBricks<'_> {
    /// Empty space, no cell read.
    fn default() -> Self {
        DensityBricks { bricks: [Channel::constant(0.0); 8], last: NO_CELL, density: [0.0; 8] }
    }
}

impl CornerRecord for DensityBricks<'_> {
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
        self.density[to] = self.density[from];
    }

    /// Reads the density of corner `c` of the local cell at window index `cell`.
    #[inline]
    fn load(&mut self, cell: usize, c: usize) {
        let (k, o) = window_slot(cell + CORNER_STEP[c]);
        self.density[c] = self.bricks[k].at(o);
    }
}

/// The dual cells of a volume, density only (see the module docs).
#[derive(Clone, Copy, Debug)]
pub struct DensityCells<'a> {
    cells: DualCells<'a>,
}

impl<'a> DensityCells<'a> {
    /// The density-only view of `cells`.
    #[must_use]
    pub fn new(cells: DualCells<'a>) -> Self {
        DensityCells { cells }
    }
}

impl<'a> Cells for DensityCells<'a> {
    const SHIFT: f64 = 0.0;
    type Piece = DensityPiece;
    type Dense = DensityBricks<'a>;
    type Cell = DualCell;

    #[inline]
    fn volume(&self) -> &Volume {
        self.cells.volume()
    }

    #[inline]
    fn table(&self) -> CellTable<'_> {
        self.cells.table()
    }

    #[inline]
    fn cell_box(&self) -> CellBox {
        self.cells.cell_box()
    }

    fn dense(&self, b: IVec3, dense: &mut DensityBricks<'a>) -> bool {
        let volume = self.cells.voxels();
        let mut any = false;
        for (channel, brick) in dense.bricks.iter_mut().zip(volume.brick_block(b)) {
            *channel = match brick {
                Some((_, brick)) => {
                    any = true;
                    Channel::new(volume, brick.density)
                }
                None => Channel::constant(0.0),
            };
        }
        dense.last = NO_CELL;
        any
    }

    /// Reads the 8 corner densities, or the 4 new ones after a step across one face.
    #[inline]
    fn dense_piece(
        &self,
        dense: &mut DensityBricks<'a>,
        origin: IVec3,
        i: IVec3,
        t0: f64,
        t1: f64,
        line: &IndexLine,
    ) -> DensityPiece {
        step_corners(dense, i - origin);
        let f0 = cell_local(line, t0, i);
        let first = dense.density[0].to_bits();
        let constant = dense.density.iter().all(|v| v.to_bits() == first);
        DensityPiece { t0, t1, f0, d: line.d, density: dense.density, constant }
    }

    #[inline]
    fn uniform(node: &NodeBounds) -> DualCell {
        <DualCells<'a> as Cells>::uniform(node)
    }

    #[inline]
    fn empty() -> DualCell {
        <DualCells<'a> as Cells>::empty()
    }

    #[inline]
    fn piece(&self, cell: DualCell, t0: f64, t1: f64, _line: &IndexLine) -> DensityPiece {
        DensityPiece {
            t0,
            t1,
            f0: DVec3::ZERO,
            d: DVec3::ZERO,
            density: [cell.density(); 8],
            constant: true,
        }
    }

    #[inline]
    fn mergeable(piece: &DensityPiece) -> bool {
        piece.constant
    }

    #[inline]
    fn merge(into: &mut DensityPiece, next: &DensityPiece) -> bool {
        let same = into.constant
            && next.constant
            && into.density[0].to_bits() == next.density[0].to_bits();
        if same {
            into.t1 = next.t1;
        }
        same
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A piece's free path and point density come from its density cubic, as a
    /// [`super::super::CubicSegment`]'s with the same densities do.
    #[test]
    fn a_density_piece_agrees_with_the_full_piece() {
        use crate::field::VoxelValues;
        let density = [0.3f32, 1.2, 0.0, 2.5, 0.7, 0.1, 1.9, 0.4];
        let (f0, d) = (DVec3::new(0.1, 0.8, 0.35), DVec3::new(0.6, -0.5, 0.3));
        let full = super::super::CubicSegment::cell(
            2.0,
            3.1,
            f0,
            d,
            density.map(|density| VoxelValues { density, source: 0.0 }),
            [1.0; 8],
        );
        let lean = DensityPiece { t0: 2.0, t1: 3.1, f0, d, density, constant: false };
        for u in [0.0, 0.3, 0.77, 1.1] {
            assert_eq!(
                lean.optical_depth(1.7, u).to_bits(),
                full.optical_depth(1.7, u).to_bits(),
                "u {u}"
            );
            assert_eq!(lean.density_at(u).to_bits(), full.density_at(u).to_bits(), "u {u}");
        }
        let od = 0.6 * full.optical_depth(1.7, 1.1);
        assert_eq!(lean.free_path(1.7, od).to_bits(), full.free_path(1.7, od).to_bits());
        assert_eq!((lean.source_at(0.5), lean.albedo_at(0.5), lean.may_emit()), (0.0, 1.0, false));
    }
}
