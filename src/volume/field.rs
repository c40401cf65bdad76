//! The [`Field`] trait and [`Segment`], the contract between volume data and estimators,
//! plus analytic fields ([`Constant`], [`Strip`]) for tests.
//!
//! A field is piecewise constant along any ray: it returns [`Segment`]s
//! `[t0, t1)` with one `density` and one emission `source` value each. Segments are
//! contiguous (`s[k].t1 == s[k+1].t0`), increasing, and cover exactly the ray's parameter
//! range clipped to the field's bounds. `t` is the distance along a unit-length world
//! direction, so segment lengths are world lengths (metres), also under non-uniform
//! voxel sizes and shear.

use glam::DVec3;

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

/// A ray in world space for [`Field::segments`]. `direction` must be unit length.
#[derive(Clone, Copy, Debug)]
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
pub trait SegmentIter: Iterator<Item = Segment> {
    /// Cells the traversal stepped through so far (voxel steps plus skipped nodes for a
    /// [`crate::volume::Volume`]; segments for analytic fields).
    fn voxel_steps(&self) -> u64;
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

/// A piecewise-constant scalar volume that can be traversed along rays.
pub trait Field: Sync {
    /// Iterator type returned by [`Field::segments`].
    type Segments<'a>: SegmentIter
    where
        Self: 'a;

    /// World-space axis-aligned bounds `(min, max)` of everything that can be non-zero.
    fn world_bounds(&self) -> (DVec3, DVec3);

    /// Segments of `ray` within `[t_min, t_max]`, clipped to the field's bounds, in order.
    /// An empty iterator when the ray misses.
    fn segments(&self, ray: &Ray, t_min: f64, t_max: f64) -> Self::Segments<'_>;

    /// `(density, source)` at a world point (for next-event sampling of a chosen point).
    fn values_at(&self, p_world: DVec3) -> (f32, f32);

    /// `rays` will be traced soon: a field paged from disk may start reading what they
    /// cross (`volume::prefetch`). A hint that never changes a result; nothing by default.
    fn prefetch(&self, _rays: &[Ray]) {}

    /// True when the field's data are paged from a file rather than held in memory.
    fn is_mapped(&self) -> bool {
        false
    }

    /// Bytes of data the field reads (held in memory or mapped).
    fn data_bytes(&self) -> usize {
        0
    }
}

fn inside(p: DVec3, lo: DVec3, hi: DVec3) -> bool {
    p.cmpge(lo).all() && p.cmplt(hi).all()
}

/// Intersect a ray with an axis-aligned box; returns the parameter interval clipped to
/// `[t_min, t_max]`, or `None` if empty. Robust to zero (and −0.0) direction components.
/// `direction` need not be unit length: `t` is the ray parameter.
#[must_use]
pub fn clip_to_box(
    origin: DVec3,
    direction: DVec3,
    lo: DVec3,
    hi: DVec3,
    t_min: f64,
    t_max: f64,
) -> Option<(f64, f64)> {
    let mut t0 = t_min;
    let mut t1 = t_max;
    for a in 0..3 {
        let (o, d) = (origin[a], direction[a]);
        if d == 0.0 {
            // Half-open [lo, hi): a ray lying in the max face belongs to the cell beyond
            // it, matching the nearest-voxel lookup ⌊p + ½⌋.
            if o < lo[a] || o >= hi[a] {
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
    (t0 < t1).then_some((t0, t1))
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
    type Segments<'a> = VecSegments;

    fn world_bounds(&self) -> (DVec3, DVec3) {
        (self.lo, self.hi)
    }

    fn segments(&self, ray: &Ray, t_min: f64, t_max: f64) -> Self::Segments<'_> {
        clip_to_box(ray.origin, ray.direction, self.lo, self.hi, t_min, t_max)
            .map(|(t0, t1)| Segment { t0, t1, density: self.density, source: self.source, albedo: 1.0 })
            .into_iter()
            .collect::<Vec<_>>()
            .into()
    }

    fn values_at(&self, p: DVec3) -> (f32, f32) {
        if inside(p, self.lo, self.hi) { (self.density, self.source) } else { (0.0, 0.0) }
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
    type Segments<'a> = VecSegments;

    fn world_bounds(&self) -> (DVec3, DVec3) {
        (self.lo, self.hi)
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
            let cell = (((mid - self.lo.x) / width).floor() as isize).clamp(0, n as isize - 1) as usize;
            let (density, source) = self.cells[cell];
            out.push(Segment { t0: a, t1: b, density, source, albedo: 1.0 });
            a = b;
        }
        out.into()
    }

    fn values_at(&self, p: DVec3) -> (f32, f32) {
        if !inside(p, self.lo, self.hi) {
            return (0.0, 0.0);
        }
        let n = self.cells.len();
        let width = (self.hi.x - self.lo.x) / n as f64;
        self.cells[(((p.x - self.lo.x) / width) as usize).min(n - 1)]
    }
}
