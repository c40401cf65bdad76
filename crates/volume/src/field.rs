//! The [`Field`] trait and [`Segment`], the contract between volume data and estimators,
//! its records [`Bounds3`] and [`VoxelValues`], plus analytic fields ([`Constant`], [`Strip`]) for tests.
//!
//! A field is piecewise constant along any ray: it returns [`Segment`]s
//! `[t0, t1)` with one `density` and one emission `source` value each. Segments are
//! contiguous (`s[k].t1 == s[k+1].t0`), increasing, and cover exactly the ray's parameter
//! range clipped to the field's bounds. `t` is the distance along a unit-length world
//! direction, so segment lengths are world lengths (metres), also under non-uniform
//! voxel sizes and shear.

use std::ops::ControlFlow;

use glam::DVec3;

use plume_core::color::Rgb;

pub use crate::overlap::{ClassWeights, EmissionGroup, PieceCubics, ScatterClass};
pub use crate::values::{Bounds3, VoxelValues};

/// A piece of a ray over which density and emission source are constant.
///
/// `t0 < t1` (never empty), in world distance along the ray. Stored in `f64` because
/// optical depth accumulates over thousands of voxels (METHOD.md §10.2).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    /// Entry distance.
    pub t0: f64,
    /// Exit distance.
    pub t1: f64,
    /// Density ρ (unitless grid value; μ_t = σ_t ρ).
    pub density: f32,
    /// Emission source value: temperature in Kelvin after mapping and cutoff, or the
    /// emission grid's value. Zero means "emits nothing".
    pub source: f32,
    /// Albedo factor of the albedo grid (1 without one); the medium's albedo multiplies
    /// it. Meaningless, and 1, where `density` is 0.
    pub albedo: f32,
}

impl Segment {
    /// World length `t1 - t0`.
    #[inline]
    #[must_use]
    pub fn length(&self) -> f64 {
        self.t1 - self.t0
    }
}

/// One piece of a ray as the estimators read it: the field's values as functions of the
/// local distance `u = t − t0 ∈ [0, t1 − t0]` (world units).
///
/// Nearest-voxel reconstruction gives constant pieces ([`Segment`]); trilinear
/// reconstruction gives one polynomial piece per dual cell
/// ([`crate::trilinear::CubicSegment`], METHOD.md §12). Estimators take the
/// closed forms of §3–4 whenever [`Piece::constant`] says a piece is constant (always, and
/// at compile time, for [`Segment`]), and the polynomial forms otherwise.
///
/// `le(density, source)` is the medium's per-voxel emission density `L_e` (W m⁻³ sr⁻¹ per
/// channel). What a polynomial piece interpolates is *that*, voxel by voxel, so `L_e(u)`
/// is a cubic and its integral closed form (see `volume/trilinear/mod.rs`).
pub trait Piece: Copy + std::fmt::Debug {
    /// Entry distance.
    fn t0(&self) -> f64;
    /// Exit distance.
    fn t1(&self) -> f64;
    /// World length `t1 − t0`.
    #[inline]
    fn length(&self) -> f64 {
        self.t1() - self.t0()
    }
    /// The piece as one constant [`Segment`] when its values do not vary along it.
    fn constant(&self) -> Option<Segment>;
    /// Optical depth `∫₀ᵘ σ_t ρ ds` from the piece's start.
    fn optical_depth(&self, sigma_t: f64, u: f64) -> f64;
    /// [`Piece::optical_depth`] at several `u` of the same piece: what the expected-value
    /// estimator needs at the piece's end and at its one-point rule's point (a polynomial
    /// piece forms its density cubic once for both).
    #[inline]
    fn optical_depths<const N: usize>(&self, sigma_t: f64, u: [f64; N]) -> [f64; N] {
        u.map(|u| self.optical_depth(sigma_t, u))
    }
    /// The `u ∈ [0, length]` with `optical_depth(sigma_t, u) = od`, for
    /// `0 ≤ od < optical_depth(sigma_t, length)`: where a free path ends in this piece.
    fn free_path(&self, sigma_t: f64, od: f64) -> f64;
    /// Density ρ at `u`.
    fn density_at(&self, u: f64) -> f32;
    /// Emission source at `u` (reported with collisions; emission itself comes from
    /// [`Piece::emission_at`]).
    fn source_at(&self, u: f64) -> f32;
    /// Albedo factor at `u` (1 where density is 0).
    fn albedo_at(&self, u: f64) -> f32;
    /// Emission density `L_e(u)` per channel.
    fn emission_at(&self, le: &impl Fn(f32, f32) -> Rgb, u: f64) -> [f64; 3];
    /// `∫₀ᵘ L_e ds` per channel.
    fn emission_integral(&self, le: &impl Fn(f32, f32) -> Rgb, u: f64) -> [f64; 3];
    /// False when no emission can come from the piece (every source is 0).
    #[inline]
    fn may_emit(&self) -> bool {
        true
    }
    /// The piece's density and emission density from `offset` on, as cubics in
    /// `u − offset` (what a field of overlapping volumes sums: `volume::overlap`).
    fn cubics(&self, le: &impl Fn(f32, f32) -> Rgb, offset: f64) -> PieceCubics;
    /// Where several volumes overlap, the share of each scattering class in a collision at
    /// `u` (`volume::overlap`); `None` for one volume's piece, whose collisions scatter
    /// with its own medium.
    #[inline]
    fn class_weights(&self, _u: f64) -> Option<ClassWeights> {
        None
    }
    /// [`Piece::optical_depth`] and [`Piece::emission_integral`] over `[0, u]` together
    /// (a piece may share work between them; emission is 0 where [`Piece::may_emit`] is
    /// false).
    #[inline]
    fn integrals(&self, sigma_t: f64, le: &impl Fn(f32, f32) -> Rgb, u: f64) -> PieceIntegrals {
        let emission = if self.may_emit() { self.emission_integral(le, u) } else { [0.0; 3] };
        PieceIntegrals { optical_depth: self.optical_depth(sigma_t, u), emission }
    }
}

/// What [`Piece::integrals`] returns.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PieceIntegrals {
    /// `∫₀ᵘ σ_t ρ ds`.
    pub optical_depth: f64,
    /// `∫₀ᵘ L_e ds` per channel.
    pub emission: [f64; 3],
}

impl Piece for Segment {
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
        Some(*self)
    }
    #[inline]
    fn optical_depth(&self, sigma_t: f64, u: f64) -> f64 {
        sigma_t * f64::from(self.density) * u
    }
    #[inline]
    fn free_path(&self, sigma_t: f64, od: f64) -> f64 {
        (od / (sigma_t * f64::from(self.density))).clamp(0.0, self.length())
    }
    #[inline]
    fn density_at(&self, _u: f64) -> f32 {
        self.density
    }
    #[inline]
    fn source_at(&self, _u: f64) -> f32 {
        self.source
    }
    #[inline]
    fn albedo_at(&self, _u: f64) -> f32 {
        self.albedo
    }
    #[inline]
    fn emission_at(&self, le: &impl Fn(f32, f32) -> Rgb, _u: f64) -> [f64; 3] {
        le(self.density, self.source).to_f64()
    }
    #[inline]
    fn emission_integral(&self, le: &impl Fn(f32, f32) -> Rgb, u: f64) -> [f64; 3] {
        le(self.density, self.source).to_f64().map(|c| c * u)
    }
    #[inline]
    fn cubics(&self, le: &impl Fn(f32, f32) -> Rgb, _offset: f64) -> PieceCubics {
        let emits = self.source != 0.0;
        let e = if emits { le(self.density, self.source).to_f64() } else { [0.0; 3] };
        PieceCubics {
            density: [f64::from(self.density), 0.0, 0.0, 0.0],
            emission: e.map(|c| [c, 0.0, 0.0, 0.0]),
            emits,
        }
    }
}

/// What a field reconstructs at one point: [`Field::reconstruct`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointValues {
    /// Density ρ.
    pub density: f32,
    /// Emission source (temperature or grid value), reconstructed as the density is:
    /// [`Field::values_at`]'s `source`, bit for bit.
    pub source: f32,
    /// Emission density `L_e` per channel.
    pub emission: [f64; 3],
}

/// A ray in world space for [`Field::segments`]. `direction` must be unit length.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Origin, world space.
    pub origin: DVec3,
    /// Unit direction, world space.
    pub direction: DVec3,
}

impl Ray {
    /// Point at distance `t`.
    #[must_use]
    pub fn at(&self, t: f64) -> DVec3 {
        self.origin + self.direction * t
    }
}

/// A segment iterator that can say how much traversal work it did.
pub trait SegmentIter: Iterator {
    /// Cells the traversal stepped through so far (voxel steps plus skipped nodes for a
    /// [`crate::Volume`]; segments for analytic fields).
    fn voxel_steps(&self) -> u64;

    /// Hands the remaining pieces to `visit` by reference, in order, until it breaks:
    /// the same pieces as the iterator, without moving each one out (a trilinear piece is
    /// ~200 bytes; the walks override this with a loop that builds each piece once).
    fn visit<B>(&mut self, mut visit: impl FnMut(&Self::Item) -> ControlFlow<B>) -> ControlFlow<B>
    where
        Self: Sized,
    {
        for piece in self.by_ref() {
            visit(&piece)?;
        }
        ControlFlow::Continue(())
    }
}

/// Segments of analytic fields, precomputed.
#[derive(Debug)]
pub struct VecSegments {
    inner: std::vec::IntoIter<Segment>,
    taken: u64,
}

impl From<Vec<Segment>> for VecSegments {
    fn from(v: Vec<Segment>) -> Self {
        VecSegments { inner: v.into_iter(), taken: 0 }
    }
}

impl Iterator for VecSegments {
    type Item = Segment;
    fn next(&mut self) -> Option<Segment> {
        let s = self.inner.next();
        self.taken += u64::from(s.is_some());
        s
    }
}

impl SegmentIter for VecSegments {
    fn voxel_steps(&self) -> u64 {
        self.taken
    }
}

/// The rays through the corners of a grid of image cells, e.g. the pixel corners of a
/// tile: `(cells_x + 1) × (cells_y + 1)` rays, row by row. Every camera ray of the tile
/// lies between four of them.
#[derive(Clone, Debug, Default)]
pub struct RayGrid {
    /// Corner rays, x fastest.
    pub rays: Vec<Ray>,
    /// Cells across.
    pub cells_x: usize,
    /// Cells down.
    pub cells_y: usize,
}

impl RayGrid {
    /// Corner ray `(i, j)`, `i ≤ cells_x`, `j ≤ cells_y`.
    #[must_use]
    pub fn corner(&self, i: usize, j: usize) -> &Ray {
        &self.rays[j * (self.cells_x + 1) + i]
    }

    /// The ray at fractional corner coordinates `(u, v)`: origins and directions
    /// interpolated bilinearly in the cell around it (not normalized). For a pinhole
    /// camera this is the ray through the same image-plane point, bent only by the
    /// corner directions having been normalized (under 10⁻⁴ across a pixel).
    #[must_use]
    pub fn at(&self, u: f64, v: f64) -> Ray {
        let (i, j) = (
            (u.floor() as usize).min(self.cells_x.saturating_sub(1)),
            (v.floor() as usize).min(self.cells_y.saturating_sub(1)),
        );
        let (fu, fv) = (u - i as f64, v - j as f64);
        let lerp = |a: DVec3, b: DVec3, f: f64| a + (b - a) * f;
        let (r00, r10, r01, r11) = (
            self.corner(i, j),
            self.corner(i + 1, j),
            self.corner(i, j + 1),
            self.corner(i + 1, j + 1),
        );
        Ray {
            origin: lerp(lerp(r00.origin, r10.origin, fu), lerp(r01.origin, r11.origin, fu), fv),
            direction: lerp(
                lerp(r00.direction, r10.direction, fu),
                lerp(r01.direction, r11.direction, fu),
                fv,
            ),
        }
    }
}

/// A piecewise-constant scalar volume that can be traversed along rays.
pub trait Field: Sync {
    /// The pieces the field is made of along a ray: [`Segment`] for piecewise-constant
    /// fields.
    type Piece: Piece;

    /// Iterator type returned by [`Field::segments`].
    type Segments<'a>: SegmentIter<Item = Self::Piece>
    where
        Self: 'a;

    /// World-space axis-aligned bounds of everything that can be non-zero.
    fn world_bounds(&self) -> Bounds3;

    /// Segments of `ray` within `[t_min, t_max]`, clipped to the field's bounds, in order.
    /// An empty iterator when the ray misses.
    fn segments(&self, ray: &Ray, t_min: f64, t_max: f64) -> Self::Segments<'_>;

    /// Density and source at a world point (the voxel's values: nearest reconstruction).
    fn values_at(&self, p_world: DVec3) -> VoxelValues;

    /// One voxel's density and source, picked at random with the reconstruction's
    /// weights at `p_world` by the uniform `u`: `E_u[g(values_picked(p, u))]` is the
    /// reconstruction of `g` at `p` for any `g` of a voxel's values (stochastic filtering;
    /// `integrator::tracker::PointLookup`). Nearest: the voxel.
    fn values_picked(&self, p_world: DVec3, _u: f64) -> VoxelValues {
        self.values_at(p_world)
    }

    /// Whether a point value combines several voxels, so that [`Field::values_picked`]
    /// reads fewer than [`Field::values_at`] (trilinear: one of eight).
    fn picks_fewer(&self) -> bool {
        false
    }

    /// Density and emission density at a world point as the field reconstructs them
    /// along rays (for next-event estimation at a sampled point). `le` is the per-voxel
    /// emission density (see [`Piece`]).
    fn reconstruct(&self, p_world: DVec3, le: &impl Fn(f32, f32) -> Rgb) -> PointValues {
        let v = self.values_at(p_world);
        PointValues {
            density: v.density,
            source: v.source,
            emission: le(v.density, v.source).to_f64(),
        }
    }

    /// Optical depth `∫ σ_t ρ ds` along `ray` over `[0, t_max]`, stopped once it exceeds
    /// `od_stop`, and the traversal's voxel steps: a shadow ray's `τ = e^{−OD}`. By default
    /// the sum over [`Field::segments`]; a field may walk a lighter view of itself that
    /// reads density alone (trilinear: `volume::trilinear::density`).
    fn optical_depth(&self, sigma_t: f64, ray: &Ray, t_max: f64, od_stop: f64) -> (f64, u64) {
        optical_depth_along(self.segments(ray, 0.0, t_max), sigma_t, od_stop)
    }

    /// Albedo factor at a world point (the nearest voxel's; 1 without an albedo grid).
    fn albedo_at(&self, _p_world: DVec3) -> f32 {
        1.0
    }

    /// Rays through `grid` will be traced soon: a field paged from disk may start reading
    /// what they cross (`volume::prefetch`). A hint that never changes a result. Returns
    /// the bytes it asked for (0 by default: nothing).
    fn prefetch(&self, _grid: &RayGrid) -> u64 {
        0
    }

    /// The render will [`Field::prefetch`] ahead of its rays from now on (a field paged
    /// from disk may then stop reading ahead on its own). Nothing by default.
    fn expect_prefetch(&self) {}

    /// True when the field's data are paged from a file rather than held in memory.
    fn is_mapped(&self) -> bool {
        false
    }

    /// Bytes of data the field reads (held in memory or mapped).
    fn data_bytes(&self) -> usize {
        0
    }

    /// The voxels behind the field, for light sampling that reads them (classic NEE's
    /// brick table); `None` for an analytic field.
    fn voxels(&self) -> Option<&super::Volume> {
        None
    }

    /// The voxels of volume `i` of a field of several (`volume::overlap`), for light
    /// sampling that reads them; a field of one volume has only its own, `i = 0`.
    fn member_voxels(&self, i: usize) -> Option<&super::Volume> {
        if i == 0 {
            self.voxels()
        } else {
            None
        }
    }

    /// The scattering classes of a field of several volumes, which its pieces'
    /// [`Piece::class_weights`] index (`volume::overlap`); empty for one volume.
    fn scatter_classes(&self) -> &[ScatterClass] {
        &[]
    }

    /// The light groups of a field of several volumes whose emission is split between
    /// AOV layers, each a view in which only its volumes emit; empty for one volume.
    fn emission_groups(&self) -> &[EmissionGroup<Self>]
    where
        Self: Sized,
    {
        &[]
    }

    /// The field as camera rays see it: itself, or a field of several volumes without
    /// those hidden from the camera.
    fn camera_view(&self) -> &Self
    where
        Self: Sized,
    {
        self
    }
}

fn inside(p: DVec3, lo: DVec3, hi: DVec3) -> bool {
    p.cmpge(lo).all() && p.cmplt(hi).all()
}

/// Intersect a ray with an axis-aligned box; returns the parameter interval clipped to
/// `[t_min, t_max]`, or `None` if empty. Robust to zero (and −0.0) direction components.
/// `direction` need not be unit length: `t` is the ray parameter. The box is half-open,
/// `[lo, hi)`: a ray lying in the max face belongs to the cell beyond it, matching the
/// nearest-voxel lookup `⌊p + ½⌋`, and an empty interval (a ray grazing an edge) is none.
#[must_use]
pub fn clip_to_box(
    origin: DVec3,
    direction: DVec3,
    lo: DVec3,
    hi: DVec3,
    t_min: f64,
    t_max: f64,
) -> Option<(f64, f64)> {
    let (t0, t1) = slabs(origin, direction, lo, hi, t_min, t_max, false)?;
    (t0 < t1).then_some((t0, t1))
}

/// The slab method's interval of a ray in the box `[lo, hi]` clipped to `[t_min, t_max]`
/// (possibly empty, `t0 > t1`), or `None` where a ray parallel to an axis lies outside
/// the box's slab on it: outside `[lo, hi]` when `closed`, else outside `[lo, hi)`.
#[inline]
pub(crate) fn slabs(
    origin: DVec3,
    direction: DVec3,
    lo: DVec3,
    hi: DVec3,
    t_min: f64,
    t_max: f64,
    closed: bool,
) -> Option<(f64, f64)> {
    let mut t0 = t_min;
    let mut t1 = t_max;
    for a in 0..3 {
        let (o, d) = (origin[a], direction[a]);
        if d == 0.0 {
            if o < lo[a] || o > hi[a] || (!closed && o == hi[a]) {
                return None;
            }
            continue;
        }
        let inv = 1.0 / d;
        let (mut ta, mut tb) = ((lo[a] - o) * inv, (hi[a] - o) * inv);
        if ta > tb {
            std::mem::swap(&mut ta, &mut tb);
        }
        t0 = t0.max(ta);
        t1 = t1.min(tb);
    }
    Some((t0, t1))
}

/// Analytic test field: a constant box.
#[derive(Clone, Copy, Debug)]
pub struct Constant {
    /// Box minimum, world.
    pub lo: DVec3,
    /// Box maximum, world.
    pub hi: DVec3,
    /// Density inside.
    pub density: f32,
    /// Emission source inside.
    pub source: f32,
}

impl Field for Constant {
    type Piece = Segment;
    type Segments<'a> = VecSegments;

    fn world_bounds(&self) -> Bounds3 {
        Bounds3 { lo: self.lo, hi: self.hi }
    }

    fn segments(&self, ray: &Ray, t_min: f64, t_max: f64) -> Self::Segments<'_> {
        clip_to_box(ray.origin, ray.direction, self.lo, self.hi, t_min, t_max)
            .map(|(t0, t1)| Segment {
                t0,
                t1,
                density: self.density,
                source: self.source,
                albedo: 1.0,
            })
            .into_iter()
            .collect::<Vec<_>>()
            .into()
    }

    fn values_at(&self, p: DVec3) -> VoxelValues {
        if inside(p, self.lo, self.hi) {
            VoxelValues { density: self.density, source: self.source }
        } else {
            VoxelValues::ZERO
        }
    }
}

/// Analytic test field: a 1-D strip of cells along +x inside a box, each cell with its
/// own density and source (used for ramps, empty cells and random strips).
#[derive(Clone, Debug)]
pub struct Strip {
    /// Box minimum, world; cells start at `lo.x`.
    pub lo: DVec3,
    /// Box maximum, world.
    pub hi: DVec3,
    /// `(density, source)` per cell, cells of equal width along x.
    pub cells: Vec<(f32, f32)>,
}

impl Field for Strip {
    type Piece = Segment;
    type Segments<'a> = VecSegments;

    fn world_bounds(&self) -> Bounds3 {
        Bounds3 { lo: self.lo, hi: self.hi }
    }

    fn segments(&self, ray: &Ray, t_min: f64, t_max: f64) -> Self::Segments<'_> {
        let mut out = Vec::new();
        let Some((t0, t1)) = clip_to_box(ray.origin, ray.direction, self.lo, self.hi, t_min, t_max)
        else {
            return out.into();
        };
        let n = self.cells.len();
        let width = (self.hi.x - self.lo.x) / n as f64;
        let dx = ray.direction.x;
        // Cell boundaries crossed between t0 and t1, in t order.
        let mut cuts: Vec<f64> = Vec::new();
        if dx != 0.0 {
            for k in 1..n {
                let t = (self.lo.x + k as f64 * width - ray.origin.x) / dx;
                if t > t0 && t < t1 {
                    cuts.push(t);
                }
            }
        }
        cuts.sort_by(f64::total_cmp);
        let mut a = t0;
        for b in cuts.into_iter().chain(std::iter::once(t1)) {
            let mid = ray.at(0.5 * (a + b)).x;
            let cell =
                (((mid - self.lo.x) / width).floor() as isize).clamp(0, n as isize - 1) as usize;
            let (density, source) = self.cells[cell];
            out.push(Segment { t0: a, t1: b, density, source, albedo: 1.0 });
            a = b;
        }
        out.into()
    }

    fn values_at(&self, p: DVec3) -> VoxelValues {
        if !inside(p, self.lo, self.hi) {
            return VoxelValues::ZERO;
        }
        let n = self.cells.len();
        let width = (self.hi.x - self.lo.x) / n as f64;
        let (density, source) = self.cells[(((p.x - self.lo.x) / width) as usize).min(n - 1)];
        VoxelValues { density, source }
    }
}

/// `Σ σ_t ∫ ρ` over the pieces of `pieces`, stopped once past `od_stop`, and the walk's
/// voxel steps ([`Field::optical_depth`]).
pub fn optical_depth_along<I: SegmentIter<Item = P>, P: Piece>(
    mut pieces: I,
    sigma_t: f64,
    od_stop: f64,
) -> (f64, u64) {
    let mut od = 0.0;
    let _ = pieces.visit(|piece| {
        od += match piece.constant() {
            Some(seg) => sigma_t * f64::from(seg.density) * seg.length(),
            None => piece.optical_depth(sigma_t, piece.length()),
        };
        if od > od_stop {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    });
    (od, pieces.voxel_steps())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Between corner rays of a pinhole grid, `RayGrid::at` gives the ray through the
    /// image-plane point the camera would use, to within the bend of interpolating unit
    /// directions.
    #[test]
    fn ray_grid_interpolates_between_pinhole_corner_rays() {
        let eye = DVec3::new(1.0, -2.0, 3.0);
        let plane = |x: f64, y: f64| DVec3::new(0.3 * x - 1.0, 0.2 * y + 0.5, -1.0);
        let ray = |x: f64, y: f64| Ray { origin: eye, direction: plane(x, y).normalize() };
        let (cx, cy) = (4, 3);
        let rays = (0..=cy)
            .flat_map(|j| (0..=cx).map(move |i| (i, j)))
            .map(|(i, j)| ray(f64::from(i), f64::from(j)))
            .collect();
        let grid = RayGrid { rays, cells_x: cx as usize, cells_y: cy as usize };
        for (u, v) in [(0.0, 0.0), (4.0, 3.0), (1.25, 2.5), (3.9, 0.1)] {
            let r = grid.at(u, v);
            assert_eq!(r.origin, eye);
            let want = plane(u, v).normalize();
            // Directions are interpolated unnormalized: same line, within the cell's curvature
            assert!(r.direction.normalize().dot(want) > 1.0 - 1e-4, "({u}, {v})");
        }
        assert_eq!(grid.at(2.0, 1.0).direction, grid.corner(2, 1).direction);
    }
}
