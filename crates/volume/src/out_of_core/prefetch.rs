//! Read-ahead for mapped volumes: which value blocks a bundle of rays will need, asked
//! of the OS before the rays are traced.
//!
//! A volume larger than memory is paged from its cache file on demand (`storage`), and
//! a page fault stalls the render thread for one random read. The render loop renders
//! tiles in order when data are out of core (`render::SampleOrder::TileMajor`) and, a few
//! tiles ahead of the workers, hands the rays through each tile's pixel corners to
//! [`Volume::read_ahead`]:
//!
//! - the corner rays are subdivided until neighbours are at most ¾ of a brick apart where
//!   they leave the volume (samples are jittered over whole pixels, and a pixel may span
//!   several bricks);
//! - each is walked by a 3-D DDA over the brick table's 8³ cells, in the shifted index
//!   space `q = (p + ½)/8` (brick `b` spans voxels `8b … 8b+7`, i.e. `[8b − ½, 8b + 7½]`),
//!   testing a bitmap of occupied cells (one bit per cell, built on first use: sparse
//!   volumes are mostly empty cells, and the table would cost a cache miss per cell)
//!   and reading no voxel values;
//! - the dense value blocks of every brick crossed (all channels), each brick once, are
//!   sorted, merged into runs and passed to `madvise(MADV_WILLNEED)`, which queues the
//!   reads and returns.
//!
//! Before the first tile ([`Volume::expect_read_ahead`]) faults on the value blocks are
//! told to read only their own page: the kernel's read-around window (`read_ahead_kb`,
//! 8 MiB on the benchmark machine) otherwise reads megabytes per fault, twice the file
//! in all for a render that touches it once. The index arrays (table, bricks, pyramid:
//! a few per cent of the values, but the DDA reads the pyramid in every cell it crosses,
//! empty ones included) are asked for whole, in file order, instead.
//!
//! Scattered rays go anywhere in the volume. Each of their segments asks for its own
//! pages just before it is walked, all at once, so the disk serves them in parallel
//! instead of one fault at a time: a null-tracked segment for the bricks around the points
//! its walk will look up ([`Volume::read_ahead_points`], found by a recording walk in
//! `integrator::tracker`), a shadow ray for the bricks it crosses
//! ([`Volume::read_ahead_ray`]). Prefetching is a hint: it reads nothing the render uses
//! and never changes a result.

use glam::{DAffine3, DVec3, IVec3};

use crate::brick::{Brick, Slot, Volume, BRICK};
use crate::field::{clip_to_box, Bounds3, Field, Ray, RayGrid};

/// Blocks closer than this (in blocks of 2 KiB) are read as one run: the gap costs less
/// than another request.
const MERGE_GAP_BLOCKS: usize = 16;

/// Cells of a brick table (`dims` cells from brick `brick_lo`, x fastest) crossed by
/// `ray` within `[t_min, t_max]`, in order along the ray.
pub fn cells_along(
    index_from_world: &DAffine3,
    brick_lo: IVec3,
    dims: IVec3,
    ray: &Ray,
    t_min: f64,
    t_max: f64,
    mut visit: impl FnMut(usize),
) {
    if dims.cmple(IVec3::ZERO).any() {
        return;
    }
    let scale = 1.0 / f64::from(BRICK);
    let o = (index_from_world.transform_point3(ray.origin) + 0.5) * scale - brick_lo.as_dvec3();
    let d = index_from_world.transform_vector3(ray.direction) * scale;
    let Some((t0, t1)) = clip_to_box(o, d, DVec3::ZERO, dims.as_dvec3(), t_min, t_max) else {
        return;
    };
    let p = o + d * t0;
    let mut cell = p.floor().as_ivec3().clamp(IVec3::ZERO, dims - 1);
    let mut t_next = DVec3::INFINITY;
    let mut t_delta = DVec3::INFINITY;
    let mut step = IVec3::ZERO;
    for a in 0..3 {
        if d[a] > 0.0 {
            step[a] = 1;
            t_next[a] = (f64::from(cell[a] + 1) - o[a]) / d[a];
            t_delta[a] = 1.0 / d[a];
        } else if d[a] < 0.0 {
            step[a] = -1;
            t_next[a] = (f64::from(cell[a]) - o[a]) / d[a];
            t_delta[a] = -1.0 / d[a];
        }
    }
    // A ray crosses at most one cell per boundary plane it passes
    let max_cells = (dims.x + dims.y + dims.z) as usize + 3;
    for _ in 0..max_cells {
        visit(
            cell.x as usize
                + dims.x as usize * (cell.y as usize + dims.y as usize * cell.z as usize),
        );
        let a = if t_next.x <= t_next.y && t_next.x <= t_next.z {
            0
        } else if t_next.y <= t_next.z {
            1
        } else {
            2
        };
        if t_next[a] >= t1 {
            return;
        }
        cell[a] += step[a];
        if cell[a] < 0 || cell[a] >= dims[a] {
            return;
        }
        t_next[a] += t_delta[a];
    }
}

/// Sorted, deduplicated `items` merged into runs `[a, b)` whose gaps are under `gap`.
fn runs(items: &mut Vec<usize>, gap: usize) -> Vec<std::ops::Range<usize>> {
    items.sort_unstable();
    items.dedup();
    let mut out: Vec<std::ops::Range<usize>> = Vec::new();
    for &i in items.iter() {
        match out.last_mut() {
            Some(r) if i <= r.end + gap => r.end = i + 1,
            _ => out.push(i..i + 1),
        }
    }
    out
}

impl Volume {
    /// Ask the OS to read ahead what the rays through `grid` will touch: the value blocks
    /// of the bricks they cross. Nothing for an in-core volume. See the module docs.
    /// Returns the bytes asked for (the render bounds what it has asked for and not yet
    /// used: `render`, "read-ahead window").
    pub fn read_ahead(&self, grid: &RayGrid) -> u64 {
        if !self.is_mapped() || grid.cells_x == 0 || grid.cells_y == 0 {
            return 0;
        }
        let n = self.subdivision(grid);
        let occupied = self.occupied();
        let mut blocks: Vec<usize> = Vec::new();
        // Neighbouring sub-rays cross the same bricks: take each brick once
        let mut seen: std::collections::HashSet<usize, std::hash::BuildHasherDefault<CellHasher>> =
            std::collections::HashSet::default();
        for j in 0..=grid.cells_y * n {
            for i in 0..=grid.cells_x * n {
                let ray = grid.at(i as f64 / n as f64, j as f64 / n as f64);
                cells_along(
                    &self.index_from_world,
                    self.brick_lo,
                    self.dims,
                    &ray,
                    0.0,
                    f64::INFINITY,
                    |cell| {
                        if is_set(occupied, cell) && seen.insert(cell) {
                            self.push_blocks(self.brick_at_cell(cell), &mut blocks);
                        }
                    },
                );
            }
        }
        self.will_need_blocks(blocks)
    }

    /// One bit per table cell, set where a brick is (built on first use).
    fn occupied(&self) -> &[u64] {
        self.occupancy.get_or_init(|| {
            let mut bits = vec![0u64; self.table.len().div_ceil(64)];
            for (cell, &brick) in self.table.iter().enumerate() {
                if (brick as usize) < self.bricks.len() {
                    bits[cell / 64] |= 1 << (cell % 64);
                }
            }
            bits
        })
    }

    /// The brick at table cell `cell`, if any.
    fn brick_at_cell(&self, cell: usize) -> Option<&Brick> {
        self.table.get(cell).and_then(|&i| self.bricks.get(i as usize))
    }

    /// Add the dense value blocks of `brick` (all channels) to `blocks`.
    fn push_blocks(&self, brick: Option<&Brick>, blocks: &mut Vec<usize>) {
        let Some(&Brick { density, source, albedo }) = brick else { return };
        for slot in [density, source, albedo] {
            if let Slot::Dense(block) = slot.get() {
                blocks.push(block as usize);
            }
        }
    }

    /// Ask for `blocks`, sorted and merged into runs; returns the bytes of the runs.
    fn will_need_blocks(&self, mut blocks: Vec<usize>) -> u64 {
        let block = BRICK_VALUES;
        let runs = runs(&mut blocks, MERGE_GAP_BLOCKS);
        let values: usize = runs.iter().map(std::ops::Range::len).sum();
        self.values.will_need(runs.into_iter().map(|r| r.start * block..r.end * block));
        (values * block * std::mem::size_of::<f32>()) as u64
    }

    /// Ask the OS to read ahead the value blocks of the bricks `ray` crosses within
    /// `[0, t_max]` (an exact walk reads no others). Nothing for an in-core volume.
    pub fn read_ahead_ray(&self, ray: &Ray, t_max: f64) {
        if !self.is_mapped() {
            return;
        }
        let occupied = self.occupied();
        let mut blocks: Vec<usize> = Vec::new();
        cells_along(&self.index_from_world, self.brick_lo, self.dims, ray, 0.0, t_max, |cell| {
            if is_set(occupied, cell) {
                self.push_blocks(self.brick_at_cell(cell), &mut blocks);
            }
        });
        self.will_need_blocks(blocks);
    }

    /// Sub-rays per cell edge so that neighbouring walked rays are at most
    /// [`RAY_SPACING_VOXELS`] apart anywhere in the volume: judged at the grid's two
    /// extreme cells, at the parameter of the volume's farthest corner (a perspective
    /// frustum is widest there).
    fn subdivision(&self, grid: &RayGrid) -> usize {
        let Bounds3 { lo, hi } = self.world_bounds();
        let a = self.index_from_world.matrix3;
        let mut widest: f64 = 0.0;
        for (i, j) in [(0, 0), (grid.cells_x - 1, grid.cells_y - 1)] {
            let r = grid.corner(i, j);
            let far = (0..8)
                .map(|k| {
                    DVec3::new(
                        if k & 1 == 0 { lo.x } else { hi.x },
                        if k & 2 == 0 { lo.y } else { hi.y },
                        if k & 4 == 0 { lo.z } else { hi.z },
                    )
                })
                .map(|c| (c - r.origin).length())
                .fold(0.0, f64::max);
            let t_far = far / r.direction.length().max(f64::MIN_POSITIVE);
            for other in [grid.corner(i + 1, j), grid.corner(i, j + 1), grid.corner(i + 1, j + 1)] {
                let apart = (r.origin - other.origin) + (r.direction - other.direction) * t_far;
                widest = widest.max((a * apart).length());
            }
        }
        ((widest / RAY_SPACING_VOXELS).ceil() as usize).clamp(1, MAX_SUBDIVISION)
    }
}

/// Bit `cell` of an occupancy bitmap ([`Volume::occupied`]).
fn is_set(occupied: &[u64], cell: usize) -> bool {
    occupied.get(cell / 64).is_some_and(|w| w & (1 << (cell % 64)) != 0)
}

impl Volume {
    /// Ask the OS to read ahead the value blocks that lookups at world `points` will
    /// read: the bricks of the 8 voxels around each (the trilinear corners, among which is
    /// the nearest voxel), all channels, sorted and merged into runs. Nothing for an
    /// in-core volume. A hint, like [`Volume::read_ahead`].
    pub fn read_ahead_points(&self, points: &[DVec3]) {
        if !self.is_mapped() || points.is_empty() {
            return;
        }
        let mut blocks: Vec<usize> = Vec::with_capacity(points.len() * 3);
        for p in points {
            let Some(q) = self.voxel_below(*p) else { continue };
            let (lo, hi) =
                (q.div_euclid(IVec3::splat(BRICK)), (q + 1).div_euclid(IVec3::splat(BRICK)));
            for z in lo.z..=hi.z {
                for y in lo.y..=hi.y {
                    for x in lo.x..=hi.x {
                        self.push_blocks(self.brick(IVec3::new(x, y, z)), &mut blocks);
                    }
                }
            }
        }
        self.will_need_blocks(blocks);
    }

    /// The low corner of the dual cell holding world point `p` (the voxel whose centre is
    /// below `p` on every axis; a lookup at `p` reads it and its +1 neighbours), or `None`
    /// for a point too far out to index.
    fn voxel_below(&self, p: DVec3) -> Option<IVec3> {
        let q = self.index_from_world.transform_point3(p).floor();
        let limit = f64::from(i32::MAX - 2 * BRICK);
        (q.is_finite() && q.abs().max_element() < limit).then(|| q.as_ivec3())
    }

    /// Where in the cache file the values around world point `p` lie: the dense value
    /// blocks of the brick holding `p`'s voxel, by channel (density, source, albedo;
    /// `u32::MAX` for a constant channel, or outside). Sorting lookups by them reads the
    /// file in order (`integrator::deferred`).
    #[must_use]
    pub fn value_blocks_at(&self, p: DVec3) -> [u32; 3] {
        let brick = self.voxel_below(p).and_then(|q| self.brick(q.div_euclid(IVec3::splat(BRICK))));
        let Some(&Brick { density, source, albedo }) = brick else { return [u32::MAX; 3] };
        [density, source, albedo].map(|slot| match slot.get() {
            Slot::Dense(block) => block,
            Slot::Constant(_) => u32::MAX,
        })
    }

    /// Ask the OS to read value blocks `blocks` (all channels' blocks in that range of
    /// the file). Nothing for an in-core volume.
    pub fn read_ahead_blocks(&self, blocks: std::ops::Range<usize>) {
        if self.is_mapped() {
            self.values
                .will_need(std::iter::once(blocks.start * BRICK_VALUES..blocks.end * BRICK_VALUES));
        }
    }

    /// Whether the render reads ahead ([`Volume::expect_read_ahead`] was called on a
    /// mapped volume).
    #[must_use]
    pub fn reading_ahead(&self) -> bool {
        self.reading_ahead.load(std::sync::atomic::Ordering::Relaxed)
    }

    /// The render will [`Volume::read_ahead`] what it reads: faults on the value blocks
    /// stop pulling in the kernel's read-around window, and the index arrays are asked for
    /// whole. See the module docs.
    pub fn expect_read_ahead(&self) {
        if self.is_mapped() {
            self.reading_ahead.store(true, std::sync::atomic::Ordering::Relaxed);
            self.values.fault_pages_only();
            self.table.will_need(std::iter::once(0..self.table.len()));
            self.bricks.will_need(std::iter::once(0..self.bricks.len()));
            for level in &self.pyramid.levels {
                level.nodes.will_need(std::iter::once(0..level.nodes.len()));
            }
        }
    }
}

/// Largest distance, in voxels, between neighbouring rays walked for read-ahead: three
/// quarters of a brick, so a brick the frustum crosses is missed only when the frustum
/// crosses a corner of it (its pages are then read when a sample faults on them).
const RAY_SPACING_VOXELS: f64 = 6.0;

/// Hashes a table cell index with one multiplication (cells are already well spread).
#[derive(Default)]
struct CellHasher(u64);

impl std::hash::Hasher for CellHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
    }

    fn write_usize(&mut self, i: usize) {
        self.0 = (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    }
}
/// Most sub-rays per cell edge (a 16×16 tile then walks 257² rays).
const MAX_SUBDIVISION: usize = 16;

/// Values per dense block.
const BRICK_VALUES: usize = (BRICK * BRICK * BRICK) as usize;

#[cfg(test)]
mod tests {
    use super::*;

    /// The brick walk visits exactly the cells whose voxels the ray passes through, as a
    /// brute-force point sampling along the ray finds them.
    #[test]
    fn cells_along_matches_dense_point_sampling() {
        let dims = IVec3::new(7, 5, 6);
        let transforms = [
            DAffine3::IDENTITY,
            DAffine3::from_scale(DVec3::new(0.5, 2.0, 1.25)),
            DAffine3::from_mat3_translation(
                glam::DMat3::from_cols_array(&[1.0, 0.2, 0.0, 0.0, 1.0, 0.3, 0.1, 0.0, 0.9]),
                DVec3::new(3.0, -2.0, 1.0),
            ),
        ];
        let mut rng = 0x1234_5678_u64;
        let mut next = || {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            (rng >> 11) as f64 / (1u64 << 53) as f64
        };
        for w in transforms {
            let (brick_lo, index_from_world) = (IVec3::new(-1, 0, 2), w.inverse());
            let (lo, hi) =
                ((brick_lo * BRICK).as_dvec3() - 0.5, ((brick_lo + dims) * BRICK).as_dvec3() - 0.5);
            for _ in 0..300 {
                let a = lo + (hi - lo) * DVec3::new(next(), next(), next()) * 1.6 - (hi - lo) * 0.3;
                let b = lo + (hi - lo) * DVec3::new(next(), next(), next());
                let (ia, ib) = (w.transform_point3(a), w.transform_point3(b));
                let ray = Ray { origin: ia, direction: ib - ia };
                let mut walked = Vec::new();
                cells_along(&index_from_world, brick_lo, dims, &ray, 0.0, f64::INFINITY, |c| {
                    walked.push(c)
                });
                let mut unique = walked.clone();
                unique.dedup();
                assert_eq!(unique, walked, "no cell twice in a row");
                // Dense sampling of the index-space ray finds a subset of those cells
                let (o, d) = (a, b - a);
                for k in 0..20_000 {
                    let t = k as f64 * 0.001;
                    let p = o + d * t;
                    let q = ((p + 0.5) / f64::from(BRICK)).floor().as_ivec3() - brick_lo;
                    if q.cmpge(IVec3::ZERO).all() && q.cmplt(dims).all() {
                        let cell = q.x as usize
                            + dims.x as usize * (q.y as usize + dims.y as usize * q.z as usize);
                        assert!(walked.contains(&cell), "cell {q} at t={t} missed by the walk");
                    }
                }
            }
        }
    }

    #[test]
    fn runs_merge_close_items() {
        let mut items = vec![9, 1, 2, 2, 40, 3, 12];
        assert_eq!(runs(&mut items, 4), vec![1..4, 9..13, 40..41]);
        assert_eq!(runs(&mut Vec::new(), 4), Vec::<std::ops::Range<usize>>::new());
    }
}
