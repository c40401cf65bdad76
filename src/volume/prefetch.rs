//! Read-ahead for mapped volumes: which value blocks a bundle of rays will need, asked
//! of the OS before the rays are traced.
//!
//! A volume larger than memory is paged from its cache file on demand (`storage`), and
//! a page fault stalls the render thread for one random read. The render loop renders
//! tiles in order when data are out of core (`render::SampleOrder::TileMajor`) and, a few
//! tiles ahead of the workers, hands each tile's camera rays to [`Volume::read_ahead`]:
//!
//! - the rays are walked through the *brick table* only (a 3-D DDA over 8³ cells in the
//!   shifted index space `q = (p + ½)/8`, where brick `b` spans voxels `8b … 8b+7`,
//!   i.e. `[8b − ½, 8b + 7½]`), touching no voxel values;
//! - the dense value blocks of every brick crossed (all channels) and the bricks'
//!   level-0 pyramid nodes are collected, sorted, merged into runs, and passed to
//!   `madvise(MADV_WILLNEED)`, which queues the reads and returns.
//!
//! Camera rays decide most of what a tile reads; scattered rays still fault on demand.
//! Prefetching is a hint: it reads nothing the render uses and never changes a result.

use glam::{DAffine3, DVec3, IVec3};

use super::brick::{Brick, Slot, Volume, BRICK};
use super::field::{clip_to_box, Ray};

/// Blocks closer than this (in blocks of 2 KiB) are read as one run: the gap costs less
/// than another request.
const MERGE_GAP_BLOCKS: usize = 16;

/// Cells of a brick table (`dims` cells from brick `brick_lo`, x fastest) crossed by
/// `ray` within `[t_min, t_max]`, in order along the ray.
pub(crate) fn cells_along(index_from_world: &DAffine3, brick_lo: IVec3, dims: IVec3, ray: &Ray, t_min: f64, t_max: f64, mut visit: impl FnMut(usize)) {
    if dims.cmple(IVec3::ZERO).any() {
        return;
    }
    let scale = 1.0 / f64::from(BRICK);
    let o = (index_from_world.transform_point3(ray.origin) + 0.5) * scale - brick_lo.as_dvec3();
    let d = index_from_world.transform_vector3(ray.direction) * scale;
    let Some((t0, t1)) = clip_to_box(o, d, DVec3::ZERO, dims.as_dvec3(), t_min, t_max) else { return };
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
        visit(cell.x as usize + dims.x as usize * (cell.y as usize + dims.y as usize * cell.z as usize));
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
    /// Ask the OS to read ahead what `rays` will touch: the value blocks of the bricks
    /// they cross and those bricks' level-0 pyramid nodes. Nothing for an in-core volume.
    /// See the module docs.
    pub fn read_ahead(&self, rays: &[Ray]) {
        if !self.is_mapped() {
            return;
        }
        let mut blocks: Vec<usize> = Vec::new();
        let mut cells: Vec<usize> = Vec::new();
        for ray in rays {
            cells_along(&self.index_from_world, self.brick_lo, self.dims, ray, 0.0, f64::INFINITY, |cell| {
                let Some(brick) = self.table.get(cell).and_then(|&i| self.bricks.get(i as usize)) else { return };
                cells.push(cell);
                let Brick { density, source, albedo } = *brick;
                for slot in [density, source, albedo] {
                    if let Slot::Dense(block) = slot.get() {
                        blocks.push(block as usize);
                    }
                }
            });
        }
        let block = BRICK_VALUES;
        self.values.will_need(runs(&mut blocks, MERGE_GAP_BLOCKS).into_iter().map(|r| r.start * block..r.end * block));
        if let Some(level) = self.pyramid.levels.first() {
            level.nodes.will_need(runs(&mut cells, 64).into_iter());
        }
    }
}

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
            DAffine3::from_mat3_translation(glam::DMat3::from_cols_array(&[1.0, 0.2, 0.0, 0.0, 1.0, 0.3, 0.1, 0.0, 0.9]), DVec3::new(3.0, -2.0, 1.0)),
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
            let (lo, hi) = ((brick_lo * BRICK).as_dvec3() - 0.5, ((brick_lo + dims) * BRICK).as_dvec3() - 0.5);
            for _ in 0..300 {
                let a = lo + (hi - lo) * DVec3::new(next(), next(), next()) * 1.6 - (hi - lo) * 0.3;
                let b = lo + (hi - lo) * DVec3::new(next(), next(), next());
                let (ia, ib) = (w.transform_point3(a), w.transform_point3(b));
                let ray = Ray { origin: ia, direction: ib - ia };
                let mut walked = Vec::new();
                cells_along(&index_from_world, brick_lo, dims, &ray, 0.0, f64::INFINITY, |c| walked.push(c));
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
                        let cell = q.x as usize + dims.x as usize * (q.y as usize + dims.y as usize * q.z as usize);
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
