//! Hierarchical 3-D DDA over a [`Volume`]: turns a world ray into ordered, gap-free
//! [`Segment`]s of constant density and source.
//!
//! Traversal runs in index space, `o' = A⁻¹(x − b)`, `d' = A⁻¹ω`, sharing the parameter
//! `t` with the world ray, so crossings are world distances even under non-uniform scale
//! or shear (METHOD.md §1). Voxel `k` spans `[k−½, k+½]` along each axis.
//!
//! On entering a brick the DDA asks the pyramid for the largest
//! node around the current voxel that is *uniform* (constant in both channels, zero
//! included); such a node is crossed as one segment. Otherwise the brick is dense and
//! the DDA steps voxel by voxel (Amanatides & Woo 1987) until it leaves the brick.
//!
//! Robustness (METHOD.md §10.9):
//! - A zero direction component (`d == 0.0`, also `-0.0`) never steps on that axis; we
//!   never form `1/d` for it.
//! - Every crossing `t` is computed afresh from an integer boundary, `(k ± ½ − o)/d`, so
//!   there is no drift along long rays; the voxel index is integer state, so a crossing
//!   that rounds to zero length still makes progress.
//! - A start exactly on a boundary takes the voxel being entered.
//! - Adjacent pieces with bit-identical values are merged, so an empty region is one
//!   segment, and the last segment ends exactly at the clipped ray's end.

use glam::{DVec3, IVec3};

use super::brick::{Brick, Volume, BRICK};
use super::field::{clip_to_box, Bounds3, Field, Ray, RayGrid, Segment, SegmentIter, VoxelValues};

/// Voxel containing coordinate `p` along an axis moving in direction `d`; on a boundary,
/// the voxel being entered.
#[inline]
fn cell_of(p: f64, d: f64) -> i32 {
    let x = p + 0.5;
    let c = if d < 0.0 { x.ceil() - 1.0 } else { x.floor() };
    c as i32 // saturating
}

/// Iterator over the segments of one ray through a [`Volume`]. See the module docs.
#[derive(Debug)]
pub struct VolumeSegments<'a> {
    volume: &'a Volume,
    o: DVec3,
    d: DVec3,
    inv_d: DVec3,
    /// Per axis: `+1`/`−1` voxel step, 0 for a zero component.
    step: IVec3,
    /// Per axis: offset of the exit face from the voxel centre (`±½`).
    face: DVec3,
    /// Per axis: parameter of the current voxel's exit face (+∞ for a zero component);
    /// valid while stepping through a dense brick.
    t_next: DVec3,
    t: f64,
    t_end: f64,
    ijk: IVec3,
    done: bool,
    /// Dense brick being stepped through, with its origin in voxels.
    brick: Option<(Brick, IVec3)>,
    pending: Option<Segment>,
    raw_steps: u64,
}

impl<'a> VolumeSegments<'a> {
    fn new(volume: &'a Volume, ray: &Ray, t_min: f64, t_max: f64) -> Self {
        let o = volume.index_from_world.transform_point3(ray.origin);
        let d = volume.index_from_world.transform_vector3(ray.direction);
        let inv_d = DVec3::new(if d.x != 0.0 { 1.0 / d.x } else { 0.0 }, if d.y != 0.0 { 1.0 / d.y } else { 0.0 }, if d.z != 0.0 { 1.0 / d.z } else { 0.0 });
        let step = IVec3::new((d.x > 0.0) as i32 - (d.x < 0.0) as i32, (d.y > 0.0) as i32 - (d.y < 0.0) as i32, (d.z > 0.0) as i32 - (d.z < 0.0) as i32);
        let mut it = VolumeSegments {
            volume,
            o,
            d,
            inv_d,
            step,
            face: step.as_dvec3() * 0.5,
            t_next: DVec3::INFINITY,
            t: 0.0,
            t_end: 0.0,
            ijk: IVec3::ZERO,
            done: true,
            brick: None,
            pending: None,
            raw_steps: 0,
        };
        if volume.is_empty() || d == DVec3::ZERO {
            return it;
        }
        let crate::volume::Bounds3 { lo, hi } = volume.index_bounds();
        if let Some((t0, t1)) = clip_to_box(o, d, lo, hi, t_min, t_max) {
            it.t = t0;
            it.t_end = t1;
            it.done = false;
            let p = o + d * t0;
            let vlo = volume.brick_lo * BRICK;
            let vhi = (volume.brick_lo + volume.dims) * BRICK - 1;
            it.ijk = IVec3::new(cell_of(p.x, d.x), cell_of(p.y, d.y), cell_of(p.z, d.z)).clamp(vlo, vhi);
        }
        it
    }

    /// Raw (unmerged) pieces produced so far: voxel steps plus skipped nodes.
    #[must_use]
    pub fn raw_steps(&self) -> u64 {
        self.raw_steps
    }

    /// Parameter at which the ray crosses boundary `b` (index units) on axis `a`, or +∞.
    #[inline]
    fn crossing(&self, a: usize, b: f64) -> f64 {
        if self.d[a] == 0.0 {
            f64::INFINITY
        } else {
            (b - self.o[a]) * self.inv_d[a]
        }
    }

    /// Parameter at which the ray leaves the current voxel `ijk` on axis `a` (+∞ if it
    /// never does). Computed from the integer index, so it never drifts.
    #[inline]
    fn face_crossing(&self, a: usize) -> f64 {
        if self.step[a] == 0 {
            f64::INFINITY
        } else {
            (f64::from(self.ijk[a]) + self.face[a] - self.o[a]) * self.inv_d[a]
        }
    }

    /// Leave the box of voxels `[lo, lo + size)`: returns the exit parameter and moves
    /// `ijk` to the voxel entered there.
    fn exit_box(&mut self, lo: IVec3, size: i32) -> f64 {
        let mut ta = [f64::INFINITY; 3];
        for (a, t) in ta.iter_mut().enumerate() {
            if self.d[a] > 0.0 {
                *t = self.crossing(a, f64::from(lo[a] + size) - 0.5);
            } else if self.d[a] < 0.0 {
                *t = self.crossing(a, f64::from(lo[a]) - 0.5);
            }
        }
        let t_exit = ta[0].min(ta[1]).min(ta[2]);
        if !t_exit.is_finite() {
            self.ijk = IVec3::MAX; // cannot happen for a non-zero direction; end the walk
            return self.t_end;
        }
        let p = self.o + self.d * t_exit;
        for a in 0..3 {
            self.ijk[a] = if ta[a] == t_exit {
                if self.d[a] > 0.0 {
                    lo[a] + size
                } else {
                    lo[a] - 1
                }
            } else {
                cell_of(p[a], self.d[a]).clamp(lo[a], lo[a] + size - 1)
            };
        }
        t_exit
    }

    /// Next raw piece, possibly of zero length (then `None` is not returned; the caller
    /// loops). Returns `None` only at the end.
    fn step_raw(&mut self) -> Option<Segment> {
        while !self.done {
            if self.t >= self.t_end {
                self.done = true;
                return None;
            }
            let t0 = self.t;
            let (t_exit, density, source, albedo);
            if let Some((brick, origin)) = self.brick {
                // Step one voxel of a dense brick
                let l = self.ijk - origin;
                density = self.volume.slot_value(brick.density, l.x, l.y, l.z);
                source = self.volume.slot_value(brick.source, l.x, l.y, l.z);
                albedo = if density > 0.0 { self.volume.slot_value(brick.albedo, l.x, l.y, l.z) } else { 1.0 };
                t_exit = self.t_next.x.min(self.t_next.y).min(self.t_next.z);
                for a in 0..3 {
                    if self.t_next[a] == t_exit {
                        self.ijk[a] += self.step[a];
                        self.t_next[a] = self.face_crossing(a);
                    }
                }
                let l = self.ijk - origin;
                if (l.x as u32 | l.y as u32 | l.z as u32) >= BRICK as u32 {
                    self.brick = None;
                }
            } else {
                let bc = IVec3::new(self.ijk.x.div_euclid(BRICK), self.ijk.y.div_euclid(BRICK), self.ijk.z.div_euclid(BRICK));
                if self.volume.cell(bc).is_none() {
                    // Left the table (only by rounding before t_end): the rest is empty.
                    self.done = true;
                    self.raw_steps += 1;
                    return Some(Segment { t0, t1: self.t_end, density: 0.0, source: 0.0, albedo: 1.0 });
                }
                let rel = bc - self.volume.brick_lo;
                let levels = &self.volume.pyramid.levels;
                // Coarsest uniform node around the voxel. A uniform node's children are
                // uniform with the same values, so a non-uniform brick settles it in one
                // lookup; otherwise search from the top for the coarsest uniform level.
                let mut uniform = None;
                if levels[0].get(rel).is_uniform() {
                    for (k, level) in levels.iter().enumerate().rev() {
                        let nc = rel >> (k as i32);
                        let node = level.get(nc);
                        if node.is_uniform() {
                            let lo = (self.volume.brick_lo + (nc << (k as i32))) * BRICK;
                            uniform = Some((lo, BRICK << k, node.density_max, node.source_max, node.uniform_albedo()));
                            break;
                        }
                    }
                }
                match uniform {
                    Some((lo, size, dv, sv, av)) => {
                        // Cross a constant (often empty) node in one step
                        density = dv;
                        source = sv;
                        albedo = av;
                        t_exit = self.exit_box(lo, size);
                    }
                    None => match self.volume.brick(bc) {
                        Some(&brick) => {
                            self.brick = Some((brick, bc * BRICK));
                            self.t_next = DVec3::new(self.face_crossing(0), self.face_crossing(1), self.face_crossing(2));
                            continue;
                        }
                        None => {
                            // A non-uniform node without a brick: only a damaged cache file
                            // says so (its checksums fail the render); cross it as empty.
                            (density, source, albedo) = (0.0, 0.0, 1.0);
                            t_exit = self.exit_box(bc * BRICK, BRICK);
                        }
                    },
                }
            }
            let t1 = t_exit.min(self.t_end);
            if t1 > t0 {
                self.t = t1;
                self.raw_steps += 1;
                return Some(Segment { t0, t1, density, source, albedo });
            }
        }
        None
    }
}

impl Iterator for VolumeSegments<'_> {
    type Item = Segment;

    fn next(&mut self) -> Option<Segment> {
        loop {
            let raw = self.step_raw();
            match (self.pending.take(), raw) {
                (None, None) => return None,
                (Some(p), None) => return Some(p),
                (None, Some(s)) => self.pending = Some(s),
                (Some(mut p), Some(s)) => {
                    if p.density.to_bits() == s.density.to_bits() && p.source.to_bits() == s.source.to_bits() && p.albedo.to_bits() == s.albedo.to_bits() {
                        p.t1 = s.t1;
                        self.pending = Some(p);
                    } else {
                        self.pending = Some(s);
                        return Some(p);
                    }
                }
            }
        }
    }
}

impl SegmentIter for VolumeSegments<'_> {
    fn voxel_steps(&self) -> u64 {
        self.raw_steps
    }
}

impl Field for Volume {
    type Piece = Segment;
    type Segments<'a> = VolumeSegments<'a>;

    fn world_bounds(&self) -> Bounds3 {
        let crate::volume::Bounds3 { lo, hi } = self.index_bounds();
        let mut wlo = DVec3::splat(f64::INFINITY);
        let mut whi = DVec3::splat(f64::NEG_INFINITY);
        for i in 0..8 {
            let c = DVec3::new(if i & 1 == 0 { lo.x } else { hi.x }, if i & 2 == 0 { lo.y } else { hi.y }, if i & 4 == 0 { lo.z } else { hi.z });
            let w = self.world_from_index.transform_point3(c);
            wlo = wlo.min(w);
            whi = whi.max(w);
        }
        Bounds3 { lo: wlo, hi: whi }
    }

    fn segments(&self, ray: &Ray, t_min: f64, t_max: f64) -> VolumeSegments<'_> {
        VolumeSegments::new(self, ray, t_min, t_max)
    }

    fn values_at(&self, p_world: DVec3) -> VoxelValues {
        self.lookup_world(p_world)
    }

    fn prefetch(&self, grid: &RayGrid) {
        self.read_ahead(grid);
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
}
