//! Nearest reconstruction: the voxels of a [`Volume`] as the DDA's lattice of cells
//! (shift ½: cell `k` is voxel `k`, `[k−½, k+½]`), each yielding one constant
//! [`Segment`], and the [`Field`] a volume is under nearest reconstruction.

use glam::{DVec3, IVec3};

use crate::brick::{Brick, Volume, BRICK};
use crate::dda::{world_box, CellBox, CellTable, CellWalk, Cells, IndexLine};
use crate::field::{Bounds3, Field, Ray, RayGrid, Segment, VoxelValues};
use crate::pyramid::NodeBounds;

/// The nearest-voxel walk over a [`Volume`]: constant [`Segment`]s.
pub type VolumeSegments<'a> = CellWalk<NearestVoxels<'a>>;

/// The voxels of a [`Volume`] as a lattice ([`Cells`], shift ½): nearest reconstruction,
/// one constant [`Segment`] per voxel or uniform node.
#[derive(Clone, Copy, Debug)]
pub struct NearestVoxels<'a> {
    volume: &'a Volume,
}

impl<'a> NearestVoxels<'a> {
    /// The voxels of `volume`.
    #[must_use]
    pub fn new(volume: &'a Volume) -> Self {
        NearestVoxels { volume }
    }
}

/// One voxel's values as the nearest walk reads them.
#[derive(Clone, Copy, Debug)]
pub struct VoxelCell {
    density: f32,
    source: f32,
    /// 1 where density is 0.
    albedo: f32,
}

impl Cells for NearestVoxels<'_> {
    const SHIFT: f64 = 0.5;
    type Piece = Segment;
    type Dense = Brick;
    type Cell = VoxelCell;

    #[inline]
    fn volume(&self) -> &Volume {
        self.volume
    }

    #[inline]
    fn table(&self) -> CellTable<'_> {
        CellTable {
            brick_lo: self.volume.brick_lo,
            dims: self.volume.dims,
            levels: &self.volume.pyramid.levels,
        }
    }

    #[inline]
    fn cell_box(&self) -> CellBox {
        CellBox {
            lo: self.volume.brick_lo * BRICK,
            hi: (self.volume.brick_lo + self.volume.dims) * BRICK,
        }
    }

    #[inline]
    fn dense(&self, brick: IVec3, dense: &mut Brick) -> bool {
        let Some(b) = self.volume.brick(brick) else { return false };
        *dense = *b;
        true
    }

    #[inline]
    fn dense_piece(
        &self,
        brick: &mut Brick,
        origin: IVec3,
        ijk: IVec3,
        t0: f64,
        t1: f64,
        _line: &IndexLine,
    ) -> Segment {
        let l = ijk - origin;
        let density = self.volume.slot_value(brick.density, l.x, l.y, l.z);
        let source = self.volume.slot_value(brick.source, l.x, l.y, l.z);
        let albedo =
            if density > 0.0 { self.volume.slot_value(brick.albedo, l.x, l.y, l.z) } else { 1.0 };
        Segment { t0, t1, density, source, albedo }
    }

    #[inline]
    fn uniform(node: &NodeBounds) -> VoxelCell {
        VoxelCell {
            density: node.density_max,
            source: node.source_max,
            albedo: node.uniform_albedo(),
        }
    }

    #[inline]
    fn empty() -> VoxelCell {
        VoxelCell { density: 0.0, source: 0.0, albedo: 1.0 }
    }

    #[inline]
    fn piece(&self, cell: VoxelCell, t0: f64, t1: f64, _line: &IndexLine) -> Segment {
        Segment { t0, t1, density: cell.density, source: cell.source, albedo: cell.albedo }
    }

    #[inline]
    fn mergeable(_: &Segment) -> bool {
        true
    }

    #[inline]
    fn merge(into: &mut Segment, next: &Segment) -> bool {
        let same = into.density.to_bits() == next.density.to_bits()
            && into.source.to_bits() == next.source.to_bits()
            && into.albedo.to_bits() == next.albedo.to_bits();
        if same {
            into.t1 = next.t1;
        }
        same
    }
}

impl Field for Volume {
    type Piece = Segment;
    type Segments<'a> = VolumeSegments<'a>;

    fn albedo_at(&self, p_world: DVec3) -> f32 {
        self.voxel_albedo(
            (self.index_from_world.transform_point3(p_world) + 0.5).floor().as_ivec3(),
        )
    }

    fn world_bounds(&self) -> Bounds3 {
        world_box(&self.world_from_index, self.index_bounds())
    }

    fn segments(&self, ray: &Ray, t_min: f64, t_max: f64) -> VolumeSegments<'_> {
        CellWalk::new(NearestVoxels::new(self), ray, t_min, t_max)
    }

    fn values_at(&self, p_world: DVec3) -> VoxelValues {
        self.lookup_world(p_world)
    }

    fn prefetch(&self, grid: &RayGrid) -> u64 {
        self.read_ahead(grid)
    }

    fn expect_prefetch(&self) {
        self.expect_read_ahead();
    }

    fn is_mapped(&self) -> bool {
        Volume::is_mapped(self)
    }

    fn data_bytes(&self) -> usize {
        self.memory_bytes()
    }

    fn voxels(&self) -> Option<&Volume> {
        Some(self)
    }
}
