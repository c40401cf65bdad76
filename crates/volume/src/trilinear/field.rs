//! [`Trilinear`]: a [`Volume`] reconstructed trilinearly (OpenVDB's `BoxSampler`), as a
//! [`Field`] whose pieces are [`CubicSegment`]s, one per dual cell crossed.
//!
//! At index-space `p`, with `i = ⌊p⌋` and `f = p − i`, the value is
//! `Σ_{c∈{0,1}³} w_c v_{i+c}`, `w_c = Π_k (c_k f_k + (1 − c_k)(1 − f_k))`
//! ([`Trilinear::interpolate_index`]). Point queries ([`Field::values_at`],
//! [`Field::reconstruct`]) and the pieces of [`Field::segments`] interpolate the same
//! corners with the same weights, so a piece's density cubic at `u` is the point value at
//! `ray.at(t0 + u)` (to rounding). The support reaches ½ voxel beyond the nearest
//! volume's bounds on every side.

use glam::{DVec3, IVec3};

use super::density::DensityCells;
use super::dual::{dual_pyramid, BlockMasks, DualCells};
use super::poly;
use super::CubicSegment;
use crate::dda::{world_box, CellWalk};
use crate::field::{optical_depth_along, Bounds3, Field, PointValues, Ray, RayGrid, VoxelValues};
use crate::pyramid::{Level, Pyramid};
use crate::Volume;
use plume_core::color::Rgb;

/// A volume with trilinear reconstruction: the volume and its dual pyramid
/// (`volume::trilinear::dual`). The voxels are the volume's; nothing is copied.
#[derive(Debug)]
pub struct Trilinear {
    volume: Volume,
    dual: Pyramid,
    /// Which blocks of each brick are empty, learnt as walks go (`dual`, "Empty cells").
    blocks: BlockMasks,
}

/// The 8 voxels around an index-space point and their trilinear weights
/// ([`Trilinear::interpolate_index`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointCorners {
    /// Dual cell `i = ⌊p⌋`; corner `c` is voxel `i + c` (bit 0: +x, bit 1: +y, bit 2: +z).
    pub cell: IVec3,
    /// Density and source of the corner voxels (0 outside the volume's bricks).
    pub corners: [VoxelValues; 8],
    /// `w_c = Π_k (c_k f_k + (1 − c_k)(1 − f_k))`, `f = p − i`; they sum to 1.
    pub weights: [f64; 8],
}

impl PointCorners {
    /// `Σ w_c g(corner_c)`, in f64.
    #[inline]
    fn sum(&self, g: impl Fn(VoxelValues) -> f64) -> f64 {
        self.corners.iter().zip(&self.weights).map(|(&v, &w)| w * g(v)).sum()
    }

    /// Interpolated density ρ.
    #[must_use]
    pub fn density(&self) -> f64 {
        self.sum(|v| f64::from(v.density))
    }

    /// Interpolated emission source.
    #[must_use]
    pub fn source(&self) -> f64 {
        self.sum(|v| f64::from(v.source))
    }

    /// Interpolated per-voxel emission density `Σ w_c le(ρ_c, s_c)` per channel (what a
    /// piece interpolates, `volume::trilinear`). Corners without a source are skipped, as
    /// pieces skip them (`le` is 0 there: the contract of [`plume_engine::medium::Emission::le`]);
    /// null-tracked emission points ask for this at every point they score.
    #[must_use]
    #[inline]
    pub fn emission(&self, le: &impl Fn(f32, f32) -> Rgb) -> [f64; 3] {
        let mut out = [0.0; 3];
        for (&v, &w) in self.corners.iter().zip(&self.weights) {
            if w != 0.0 && v.source != 0.0 {
                let e = le(v.density, v.source).to_f64();
                for (o, e) in out.iter_mut().zip(e) {
                    *o += w * e;
                }
            }
        }
        out
    }
}

impl Trilinear {
    /// Trilinear reconstruction of `volume`; builds the dual pyramid (from the volume's
    /// pyramid only, in parallel; no voxel is read).
    #[must_use]
    pub fn new(volume: Volume) -> Trilinear {
        let dual = dual_pyramid(&volume);
        let blocks = BlockMasks::new(&volume);
        Trilinear { volume, dual, blocks }
    }

    /// The volume whose voxels are interpolated.
    #[must_use]
    pub fn volume(&self) -> &Volume {
        &self.volume
    }

    /// The volume back, dropping the dual pyramid.
    #[must_use]
    pub fn into_volume(self) -> Volume {
        self.volume
    }

    /// Bytes trilinear adds to the volume: the dual pyramid (all levels) and the block
    /// masks (8 bytes per brick).
    #[must_use]
    pub fn dual_bytes(&self) -> usize {
        self.dual.memory_bytes() + self.blocks.bytes()
    }

    /// Dual pyramid levels, finest first: level 0 has one node per dual brick, from brick
    /// `brick_lo − 1` of the volume's table (see `volume::trilinear::dual`).
    #[must_use]
    pub fn dual_pyramid_levels(&self) -> &[Level] {
        &self.dual.levels
    }

    /// Index-space box of everything that can be non-zero: the volume's
    /// [`Volume::index_bounds`] grown by ½ voxel on every side (empty volumes: unchanged).
    pub fn index_bounds(&self) -> Bounds3 {
        let b = self.volume.index_bounds();
        if self.volume.is_empty() {
            return b;
        }
        Bounds3 { lo: b.lo - 0.5, hi: b.hi + 0.5 }
    }

    /// The 8 voxels around index-space `p_index` and their weights (`BoxSampler`).
    #[must_use]
    pub fn interpolate_index(&self, p_index: DVec3) -> PointCorners {
        let floor = p_index.floor();
        let cell = floor.as_ivec3();
        let corners = self.volume.voxel_block(cell);
        PointCorners { cell, corners, weights: poly::weights(p_index - floor) }
    }

    /// [`Trilinear::interpolate_index`] at a world point.
    #[must_use]
    pub fn interpolate_world(&self, p_world: DVec3) -> PointCorners {
        self.interpolate_index(self.volume.index_from_world.transform_point3(p_world))
    }
}

impl Field for Trilinear {
    type Piece = CubicSegment;

    fn albedo_at(&self, p_world: DVec3) -> f32 {
        self.volume.albedo_at(p_world)
    }
    type Segments<'a> = CellWalk<DualCells<'a>>;

    fn world_bounds(&self) -> Bounds3 {
        world_box(&self.volume.world_from_index, self.index_bounds())
    }

    fn segments(&self, ray: &Ray, t_min: f64, t_max: f64) -> Self::Segments<'_> {
        CellWalk::new(DualCells::new(&self.volume, &self.dual, &self.blocks), ray, t_min, t_max)
    }

    /// The dual cells' walk reading density alone ([`DensityCells`]).
    fn optical_depth(&self, sigma_t: f64, ray: &Ray, t_max: f64, od_stop: f64) -> (f64, u64) {
        let cells = DensityCells::new(DualCells::new(&self.volume, &self.dual, &self.blocks));
        optical_depth_along(CellWalk::new(cells, ray, 0.0, t_max), sigma_t, od_stop)
    }

    /// Trilinearly interpolated density and source.
    fn values_at(&self, p_world: DVec3) -> VoxelValues {
        let it = self.interpolate_world(p_world);
        VoxelValues { density: it.density() as f32, source: it.source() as f32 }
    }

    fn picks_fewer(&self) -> bool {
        true
    }

    /// Corner `c` with probability `w_c = Π_k (c_k f_k + (1 − c_k)(1 − f_k))`: along each
    /// axis the upper voxel with probability `f_k`, `u` rescaled to a fresh uniform on the
    /// part it fell in after each choice.
    fn values_picked(&self, p_world: DVec3, u: f64) -> VoxelValues {
        let p = self.volume.index_from_world.transform_point3(p_world);
        let floor = p.floor();
        let f = p - floor;
        let mut cell = floor.as_ivec3();
        let mut u = u;
        for k in 0..3 {
            if u < f[k] {
                cell[k] += 1;
                u /= f[k];
            } else {
                u = (u - f[k]) / (1.0 - f[k]);
            }
        }
        self.volume.voxel(cell)
    }

    /// Interpolated density and source, and the interpolation of the corners'
    /// `le(ρ_c, s_c)`: one gather of the 8 corners for all three.
    #[inline(always)]
    fn reconstruct(&self, p_world: DVec3, le: &impl Fn(f32, f32) -> Rgb) -> PointValues {
        let it = self.interpolate_world(p_world);
        PointValues {
            density: it.density() as f32,
            source: it.source() as f32,
            emission: it.emission(le),
        }
    }

    fn prefetch(&self, grid: &RayGrid) -> u64 {
        self.volume.prefetch(grid)
    }

    fn expect_prefetch(&self) {
        self.volume.expect_prefetch();
    }

    fn is_mapped(&self) -> bool {
        self.volume.is_mapped()
    }

    fn data_bytes(&self) -> usize {
        self.volume.memory_bytes() + self.dual_bytes()
    }

    fn voxels(&self) -> Option<&Volume> {
        Some(&self.volume)
    }
}
