//! Majorants for null-collision tracking (METHOD.md §13): a coarse grid holding bounds
//! on the density and the emission source over everything a point of a cell can read.
//! Built from the volume's pyramid alone: no voxel is read (a cache may be tens of GB).
//!
//! **Cells.** The cells lie between voxel centres, like the trilinear walk's dual cells
//! (`volume::trilinear::dual`): on pyramid level `k`, with edge `e = 8·2^k` voxels, cell
//! `c` spans index space `[o + e c, o + e (c + 1)]` per axis, `o = 8(brick_lo − 1)`. A
//! point `p` there reads voxels `⌊p⌋` and `⌊p⌋ + 1` (trilinear) or `⌊p + ½⌋` (nearest):
//! all within `o + e c … o + e (c + 1) + 1`, i.e. in bricks `2^k c − 1 … 2^k (c + 1) − 1`
//! (relative to `brick_lo`), which lie in the level's nodes `c − 1` and `c`. So a cell's
//! bound is the union of nodes `c − 1 + {0,1}³`: on level 0 the 8 bricks a dual brick
//! reads (exactly the dual pyramid's node), for both reconstructions; the grid has one
//! more cell per axis than the level has nodes.
//!
//! *Why these cells:* cells that were the bricks, `[8b − ½, 8b + 7½]`, would need the one
//! voxel of reach beyond them, so each would take the maximum over the 27 bricks around: a
//! looser majorant and more null collisions (measured in docs/BENCHMARKS.md, "Tracking:
//! null collisions after scattering").
//!
//! **Level.** A table of more than [`MAX_CELLS`] cells (volumes beyond about 1024³
//! voxels, e.g. a 4096³ cache) takes the first coarser pyramid level that fits: looser
//! bounds (more null collisions) but a grid of at most 16 MiB, where the finest level
//! would hold one 8-byte cell per brick (1 GiB at 4096³).
//!
//! **Motion.** A point reads the field at `p' = p − t·v(p)` (motion blur: a displacement
//! of at most `D` voxels on every index axis), so its bound is the maximum over the cells
//! within `D` voxels of it: cells `c − R … c + R`, `R = ⌈D/e⌉`. The grid is the union
//! above under a separable box maximum of radius `R`, padded by `R` cells on every side,
//! so displaced lookups from outside the volume's table are bounded too.
//!
//! [`MajorantGrid::segments`] walks a ray through the cells (Amanatides–Woo in index
//! space; the ray parameter `t` is the world ray's) and yields `(t0, t1, bounds)`, merging
//! neighbours with equal bounds. The invariant tested in `tests/null_tracking.rs`: every
//! displaced lookup along a ray is at most its segment's density bound.

use glam::{DAffine3, DVec3, IVec3};

use super::brick::{Volume, BRICK};
use super::field::{clip_to_box, Ray};
use super::trilinear::dual::dual_union;

/// Bounds over a majorant cell.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CellBounds {
    /// Largest density any point of the cell can read.
    pub density: f32,
    /// Largest emission source any point of the cell can read (0: no emission there).
    pub source: f32,
}

/// Most cells a majorant grid holds before it moves to a coarser pyramid level (16 MiB).
pub const MAX_CELLS: i64 = 1 << 21;

/// The majorant grid of a volume for a displacement bound.
#[derive(Clone, Debug)]
pub struct MajorantGrid {
    index_from_world: DAffine3,
    /// Index-space corner of cell (0, 0, 0).
    origin: DVec3,
    /// Cell edge in voxels (8 on the brick level, `8·2^k` on level `k`).
    edge: i32,
    dims: IVec3,
    cells: Vec<CellBounds>,
}

/// A stretch of a ray with one majorant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MajorantSegment {
    /// Start (ray parameter).
    pub t0: f64,
    /// End (ray parameter).
    pub t1: f64,
    /// Bounds over the stretch.
    pub bounds: CellBounds,
}

/// Separable running maximum of radius `r` along axis `axis` of a `dims` grid.
fn max_filter(cells: &[CellBounds], dims: IVec3, axis: usize, r: i32) -> Vec<CellBounds> {
    let d = dims.to_array();
    let stride = [1usize, d[0] as usize, (d[0] * d[1]) as usize][axis];
    let n = d[axis];
    let mut out = cells.to_vec();
    for (i, o) in out.iter_mut().enumerate() {
        let coord = (i / stride) as i32 % n;
        let base = i - coord as usize * stride;
        let mut m = CellBounds::default();
        for k in (coord - r).max(0)..=(coord + r).min(n - 1) {
            let c = cells[base + k as usize * stride];
            m.density = m.density.max(c.density);
            m.source = m.source.max(c.source);
        }
        *o = m;
    }
    out
}

impl MajorantGrid {
    /// The grid of `volume` for displacements of at most `displacement` index units
    /// (voxels) on every axis (0 without motion).
    ///
    /// # Panics
    /// If `displacement` is negative or not finite.
    #[must_use]
    pub fn new(volume: &Volume, displacement: f64) -> MajorantGrid {
        MajorantGrid::with_max_cells(volume, displacement, MAX_CELLS)
    }

    /// [`MajorantGrid::new`] on the finest pyramid level of at most `max_cells` nodes (the
    /// coarsest level when none is that small).
    ///
    /// # Panics
    /// If `displacement` is negative or not finite.
    #[must_use]
    pub fn with_max_cells(volume: &Volume, displacement: f64, max_cells: i64) -> MajorantGrid {
        assert!(
            displacement.is_finite() && displacement >= 0.0,
            "displacement {displacement} must be finite and ≥ 0"
        );
        let levels = volume.pyramid_levels();
        let count = |d: IVec3| i64::from(d.x + 1) * i64::from(d.y + 1) * i64::from(d.z + 1);
        let k = levels
            .iter()
            .position(|l| count(l.dims) <= max_cells)
            .unwrap_or(levels.len().saturating_sub(1));
        let level = levels.get(k);
        let edge = BRICK << k;
        let r = (displacement / f64::from(edge)).ceil() as i32;
        // One more cell than the level has nodes: dual cell c reads nodes c − 1 and c
        let vd = level.map_or(IVec3::ZERO, |l| l.dims);
        let nd = if level.is_some() { vd + 1 } else { IVec3::ZERO };
        let dims = nd + 2 * r;
        let mut cells = vec![CellBounds::default(); (dims.x * dims.y * dims.z).max(0) as usize];
        if let Some(level) = level {
            for z in 0..nd.z {
                for y in 0..nd.y {
                    for x in 0..nd.x {
                        // The union of the level's nodes c − 1 + {0,1}³ (the dual pyramid's
                        // node on level 0; a superset of it on coarser levels)
                        let c = IVec3::new(x, y, z);
                        let n = dual_union(level, c);
                        let g = c + r;
                        cells[(g.x + dims.x * (g.y + dims.y * g.z)) as usize] =
                            CellBounds { density: n.density_max, source: n.source_max };
                    }
                }
            }
        }
        for axis in 0..3 {
            cells = max_filter(&cells, dims, axis, r);
        }
        // Cell c (before the padding) spans [8(brick_lo − 1) + e c, 8(brick_lo − 1) + e (c + 1)]
        let origin = ((volume.brick_lo - 1) * BRICK - r * edge).as_dvec3();
        MajorantGrid { index_from_world: volume.index_from_world(), origin, edge, dims, cells }
    }

    /// Cell edge in voxels.
    #[must_use]
    pub fn cell_edge_voxels(&self) -> i32 {
        self.edge
    }

    /// About how many voxels `ray` crosses per unit of its parameter: the L1 norm of its
    /// direction in index space (each unit of `|d_x|` crosses one voxel face along x).
    #[must_use]
    pub fn voxel_crossings_per_length(&self, ray: &Ray) -> f64 {
        let d = self.index_from_world.transform_vector3(ray.direction);
        d.x.abs() + d.y.abs() + d.z.abs()
    }

    /// Bytes held.
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        self.cells.len() * std::mem::size_of::<CellBounds>()
    }

    /// The stretches of `ray` within `[t_min, t_max]` with their bounds, in order and
    /// without gaps inside the grid; nothing outside it (where nothing can be read).
    pub fn segments(
        &self,
        ray: &Ray,
        t_min: f64,
        t_max: f64,
    ) -> impl Iterator<Item = MajorantSegment> + '_ {
        let o = self.index_from_world.transform_point3(ray.origin);
        let d = self.index_from_world.transform_vector3(ray.direction);
        let size = f64::from(self.edge);
        let hi = self.origin + self.dims.as_dvec3() * size;
        let range = if self.cells.is_empty() {
            None
        } else {
            clip_to_box(o, d, self.origin, hi, t_min, t_max)
        };
        let mut state = range.map(|(t0, t1)| {
            // The cell at the entry point (nudged inside), then per-axis crossings
            let p = o + d * t0;
            let cell =
                ((p - self.origin) / size).floor().as_ivec3().clamp(IVec3::ZERO, self.dims - 1);
            let step = IVec3::new(sign(d.x), sign(d.y), sign(d.z));
            let next_face = |axis: usize| {
                let c = f64::from(cell[axis] + i32::from(step[axis] > 0));
                let face = self.origin[axis] + c * size;
                if d[axis] == 0.0 {
                    f64::INFINITY
                } else {
                    (face - o[axis]) / d[axis]
                }
            };
            let t_next = DVec3::new(next_face(0), next_face(1), next_face(2));
            let t_delta = DVec3::new(size / d.x.abs(), size / d.y.abs(), size / d.z.abs());
            Walk { cell, step, t_next, t_delta, t: t0, t_end: t1 }
        });
        std::iter::from_fn(move || {
            let w = state.as_mut()?;
            if w.t >= w.t_end {
                return None;
            }
            let bounds = self.get(w.cell);
            let t0 = w.t;
            // Advance while the bounds stay the same (merged stretches)
            loop {
                let axis = if w.t_next.x <= w.t_next.y && w.t_next.x <= w.t_next.z {
                    0
                } else if w.t_next.y <= w.t_next.z {
                    1
                } else {
                    2
                };
                let exit = w.t_next[axis].min(w.t_end);
                w.t = exit;
                if exit >= w.t_end {
                    break;
                }
                w.cell[axis] += w.step[axis];
                w.t_next[axis] += w.t_delta[axis];
                if w.cell[axis] < 0 || w.cell[axis] >= self.dims[axis] {
                    w.t = w.t_end;
                    break;
                }
                if self.get(w.cell) != bounds {
                    break;
                }
            }
            Some(MajorantSegment { t0, t1: w.t, bounds })
        })
    }

    fn get(&self, c: IVec3) -> CellBounds {
        self.cells[(c.x + self.dims.x * (c.y + self.dims.y * c.z)) as usize]
    }
}

struct Walk {
    cell: IVec3,
    step: IVec3,
    t_next: DVec3,
    t_delta: DVec3,
    t: f64,
    t_end: f64,
}

fn sign(v: f64) -> i32 {
    if v > 0.0 {
        1
    } else if v < 0.0 {
        -1
    } else {
        0
    }
}
