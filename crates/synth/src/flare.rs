//! Procedural solar flares, generated brick by brick for volumes of any size.
//!
//! A dark, empty box above a "photosphere" plane, crossed by many thin, very hot
//! (10⁶–2·10⁷ K) plasma loops: a sheared flare arcade with hot knots near some loop tops,
//! under taller, fatter, cooler active-region loops (`flare/layout.rs`). Everything
//! else is empty. The data can be far larger than memory (≈ 32 GB of dense `f32` at
//! 4096³), so it is never built whole: [`Flare::fill_brick`] computes one 8³ brick as a
//! pure function of the parameters and the brick coordinate, and
//! [`Flare::bricks_in_slab`] lists the bricks of a z-slab that may be occupied, from the
//! loops' geometry alone. A writer streams slabs in parallel; [`Flare::to_float_grids`]
//! does the same in memory for small resolutions.
//!
//! # World placement and units
//! The domain is a cube of side [`FLARE_SIZE`] = 100 m, y up, voxel size
//! `100 m / resolution`; voxel `(i, j, k)`, `0 ≤ i, j, k < resolution`, is centred at
//! index `(i, j, k)` (OpenVDB) and at world `((i + ½)·h − 50 m, (j + ½)·h, (k + ½)·h − 50 m)`
//! with `h` the voxel size. The photosphere is the plane `y = 0 m` (index `j = −½`), the
//! box's floor. (Read 1 m as 1 Mm for the Sun: 100 Mm is an active region's field of
//! view.) The loops are fixed in world space, so every resolution samples the same flare,
//! except that tubes are never thinner than [`MIN_TUBE_RADIUS`] voxels (their density is
//! reduced in proportion, which keeps emission per unit length).
//!
//! - **Density**: unitless, `μ_t = σ_t·ρ` per metre (`--density-scale` = σ_t). Arcade loops
//!   hold 0.2–1.5 (knots up to ~7), active-region loops 0.01–0.06, both less where thin
//!   tubes are widened at low resolution. At σ_t = 1 every loop is optically thin (optical
//!   depth ≲ 0.3 across an arcade loop, ≲ 0.1 across an active-region loop); the arcade
//!   seen along its axis reaches a few.
//! - **Temperature**: Kelvin, in `[FOOT_TEMPERATURE, PEAK_TEMPERATURE]` = 10⁶–2·10⁷ K
//!   wherever density > 0, and 0 elsewhere. Where loops overlap, densities add and the
//!   temperature is their density-weighted mean.
//!
//! # Bricks and speed
//! Brick `b` holds voxels `8b … 8b + 7`; bricks are listed and filled only within
//! `[0, resolution)³` (voxels beyond it stay 0). A brick can be occupied only if its
//! voxel-centre box's bounding sphere (radius `3.5·√3`) comes within a tube's reach of the
//! tube's circle (the circle's distance function is 1-Lipschitz). [`Flare::fill_brick`]
//! applies that test to the loops listed in a coarse grid cell (≤ 64³ cells, built in
//! [`Flare::new`]); [`Flare::bricks_in_slab`] samples every loop's circle every few
//! voxels and applies it to the bricks near each sample.
//!
//! Inside a brick, a loop's distance is computed for every voxel (rows of 8 that the
//! compiler vectorises) against a reach bounded locally from the loop's along-arc profile
//! table (`flare/tube.rs`), and only voxels within reach pay for an `atan2` and a table
//! lookup. NOTE: this is what keeps the whole 4096³ dataset at minutes of CPU rather than
//! hours (`synth_flare_full_4096`), and listing all its 512 slabs at seconds.
//!
//! # Determinism
//! Same [`FlareParams`] ⇒ bit-identical values at any thread count and in any slab order:
//! a brick's values depend only on its coordinate, loops are added in index order, and
//! arithmetic is plain `f32`/`f64` without `mul_add`.

mod layout;
#[cfg(test)]
mod tests;
mod tube;

use std::sync::OnceLock;

use glam::{DAffine3, DVec3, IVec3};
use rayon::prelude::*;

use layout::{LayoutCounts, LoopSpec};
pub use layout::{FOOT_TEMPERATURE, PEAK_TEMPERATURE};
use plume_volume::grid::{FloatGrid, LEAF_DIM, LEAF_VOXELS};
pub use tube::MIN_TUBE_RADIUS;
use tube::{Accumulator, Tube};

/// Side of the flare's cube, metres (y from 0 up, x and z centred on 0).
pub const FLARE_SIZE: f64 = 100.0;
/// Largest accepted [`FlareParams::resolution`].
pub const MAX_FLARE_RESOLUTION: u32 = 1 << 16;
/// Bytes of dense `f32` data per occupied brick, density and temperature.
pub const BYTES_PER_BRICK: u64 = 2 * LEAF_VOXELS as u64 * 4;

/// Radius of the bounding sphere of a brick's voxel centres, voxels.
const BRICK_RADIUS: f64 = 3.5 * 1.732_050_807_568_877_2;
/// Slack on every conservative distance test, voxels: covers `f32` rounding in
/// [`Tube::accumulate`] (≲ 0.01 voxel even at 65536³).
const MARGIN: f64 = 1.0;
/// Most acceleration-grid cells per axis.
const MAX_GRID_CELLS: i32 = 64;
/// Arc samples per chunk in [`Flare::bricks_in_slab`] (chunks far from the slab are skipped).
const CHUNK: usize = 32;

/// Inputs of [`Flare::new`]. Build with struct-update syntax from [`Default`].
///
/// # Size
/// With the default loop counts (seed 1), the fraction of bricks that hold density falls
/// with resolution as the tubes get thicker in voxels relative to the bricks: 13.7 % at
/// 256³, 10.7 % at 512³, 8.3 % at 1024³, 5.87 % at 4096³ (7.88 M bricks, 32.3 GB =
/// 30.0 GiB of dense `f32`, density and temperature; [`Flare::bricks_in_slab`] lists
/// 6.23 %). Seeds 1–5 list 6.2–7.2 % at 4096³ (the active-region radii are normalised per
/// seed) and occupy 13.7–18.5 % at 256³; the tests hold seed 1 at 256³ to 11–16 %.
#[derive(Clone, Debug, PartialEq)]
pub struct FlareParams {
    /// Voxels per edge of the cube, 1 to [`MAX_FLARE_RESOLUTION`] (any value, not only
    /// multiples of 8). Default 256.
    pub resolution: u32,
    /// Seed of the loop layout. Default 1.
    pub seed: u64,
    /// Loops in the flare arcade. Default 200.
    pub arcade_loops: u32,
    /// Active-region loops over the arcade. Default 480.
    pub active_region_loops: u32,
    /// Fraction of arcade loops with a hot, dense knot near the top, in `[0, 1]`. Default 0.2.
    pub knot_fraction: f32,
}

impl Default for FlareParams {
    fn default() -> Self {
        FlareParams {
            resolution: 256,
            seed: 1,
            arcade_loops: 200,
            active_region_loops: 480,
            knot_fraction: 0.2,
        }
    }
}

/// A flare at one resolution: the loops in index space plus a grid of loop lists.
/// Cheap to share between threads (`Sync`); building it costs milliseconds.
#[derive(Debug)]
pub struct Flare {
    resolution: i32,
    brick_dims: IVec3,
    tubes: Vec<Tube>,
    grid: LoopGrid,
    estimated_bricks: OnceLock<u64>,
}

/// Coarse grid over the bricks: cell `c` covers bricks `c·cell_bricks …` and lists, in
/// ascending order, the tubes that may reach it.
#[derive(Debug)]
struct LoopGrid {
    cell_bricks: i32,
    cells: IVec3,
    /// `offsets[c] .. offsets[c + 1]` index `tubes` for cell `c` (x fastest).
    offsets: Vec<u32>,
    tubes: Vec<u32>,
}

impl Flare {
    /// Lays out the loops and builds the acceleration grid.
    ///
    /// # Panics
    /// If `resolution` is 0 or above [`MAX_FLARE_RESOLUTION`], or `knot_fraction` is not
    /// in `[0, 1]`.
    #[must_use]
    pub fn new(params: &FlareParams) -> Flare {
        assert!(
            (1..=MAX_FLARE_RESOLUTION).contains(&params.resolution),
            "flare resolution {} outside 1..={MAX_FLARE_RESOLUTION}",
            params.resolution
        );
        assert!(
            (0.0..=1.0).contains(&params.knot_fraction),
            "knot fraction {} outside [0, 1]",
            params.knot_fraction
        );
        let counts = LayoutCounts {
            arcade: params.arcade_loops,
            active_region: params.active_region_loops,
            knot_fraction: params.knot_fraction,
        };
        let specs: Vec<LoopSpec> = layout::loops(params.seed, counts);
        let tubes: Vec<Tube> =
            specs.iter().map(|spec| Tube::new(spec, f64::from(params.resolution))).collect();
        let resolution = params.resolution as i32;
        let brick_dims = IVec3::splat((resolution + LEAF_DIM - 1) / LEAF_DIM);
        let grid = LoopGrid::new(&tubes, resolution, brick_dims);
        Flare { resolution, brick_dims, tubes, grid, estimated_bricks: OnceLock::new() }
    }

    /// Affine index → world map, metres: uniform scale `FLARE_SIZE / resolution`, voxel
    /// `(i, j, k)` centred at index `(i, j, k)`; index `(−½, −½, −½)` maps to
    /// `(−50, 0, −50)` m and `resolution − ½` to `(50, 100, 50)` m.
    #[must_use]
    pub fn world_from_index(&self) -> DAffine3 {
        let voxel = FLARE_SIZE / f64::from(self.resolution);
        DAffine3::from_translation(DVec3::new(-0.5 * FLARE_SIZE, 0.0, -0.5 * FLARE_SIZE))
            * DAffine3::from_scale(DVec3::splat(voxel))
            * DAffine3::from_translation(DVec3::splat(0.5))
    }

    /// Bricks per axis, `⌈resolution / 8⌉`: brick coordinates run over `[0, brick_dims)`.
    #[must_use]
    pub fn brick_dims(&self) -> IVec3 {
        self.brick_dims
    }

    /// Bricks of z-slab `bz` that may hold density, sorted by `(y, x)`; empty for `bz`
    /// outside `[0, brick_dims.z)`.
    ///
    /// Conservative: every brick with a voxel of density > 0 is listed; a listed brick
    /// may be all zero (with the defaults 12 % of listed bricks at 256³, 6 % at 4096³).
    /// Costs no voxel evaluation: each loop's circle is sampled every few voxels and the
    /// bricks near each sample that pass the brick test of `fill_brick` (bounding sphere
    /// against the tube radius bounded locally) are marked in a bitmap of
    /// `brick_dims.x × brick_dims.y` bits.
    #[must_use]
    pub fn bricks_in_slab(&self, bz: i32) -> Vec<IVec3> {
        if !(0..self.brick_dims.z).contains(&bz) {
            return Vec::new();
        }
        let dims = self.brick_dims;
        let mut marked = vec![0u64; (dims.x as usize * dims.y as usize).div_ceil(64)];
        let (z_lo, z_hi) = (f64::from(8 * bz), f64::from(8 * bz + 7));
        for tube in &self.tubes {
            if tube.hi.z < z_lo - MARGIN || tube.lo.z > z_hi + MARGIN {
                continue;
            }
            self.mark_tube(tube, bz, &mut marked);
        }
        let mut bricks = Vec::new();
        for (word_index, &word) in marked.iter().enumerate() {
            let mut bits = word;
            while bits != 0 {
                let i = word_index * 64 + bits.trailing_zeros() as usize;
                bits &= bits - 1;
                bricks.push(IVec3::new(
                    (i % dims.x as usize) as i32,
                    (i / dims.x as usize) as i32,
                    bz,
                ));
            }
        }
        bricks
    }

    /// Marks the bricks of slab `bz` that `tube` may reach (see [`Flare::bricks_in_slab`]).
    fn mark_tube(&self, tube: &Tube, bz: i32, marked: &mut [u64]) {
        let dims = self.brick_dims;
        let reach = f64::from(tube.reach);
        // Samples every `step` voxels of arc: every point within reach of the circle is
        // within `ball` of a sample
        let step = (0.5 * (reach + BRICK_RADIUS)).max(2.0);
        let samples =
            (std::f64::consts::TAU * tube.circle_radius() / step).ceil().max(8.0) as usize;
        let angle_step = std::f64::consts::TAU / samples as f64;
        let step = angle_step * tube.circle_radius();
        let ball = reach + 0.5 * step + MARGIN;
        let (z_lo, z_hi) = (f64::from(8 * bz), f64::from(8 * bz + 7));
        let top = f64::from(self.resolution - 1);
        for chunk_start in (0..samples).step_by(CHUNK) {
            // Every sample of the chunk is within CHUNK/2 steps of arc of its middle
            let middle = tube.point((chunk_start + CHUNK / 2) as f64 * angle_step);
            let slack = ball + (CHUNK / 2) as f64 * step;
            if middle.z + slack < z_lo || middle.z - slack > z_hi || middle.y + slack < 0.0 {
                continue;
            }
            for sample in chunk_start..(chunk_start + CHUNK).min(samples) {
                let p = tube.point(sample as f64 * angle_step);
                if p.z + ball < z_lo || p.z - ball > z_hi || p.y + ball < 0.0 || p.y - ball > top {
                    continue;
                }
                // Bricks whose voxel-centre box [8b, 8b + 7] meets the ball's bounding box
                let range = |c: f64, n: i32| {
                    let lo = ((c - ball - 7.0) / 8.0).ceil().max(0.0) as i32;
                    let hi = ((c + ball) / 8.0).floor().min(f64::from(n - 1)) as i32;
                    lo..=hi
                };
                for by in range(p.y, dims.y) {
                    for bx in range(p.x, dims.x) {
                        let i = by as usize * dims.x as usize + bx as usize;
                        let (word, bit) = (i / 64, 1u64 << (i % 64));
                        if marked[word] & bit != 0 {
                            continue;
                        }
                        let centre = IVec3::new(bx, by, bz).as_dvec3() * 8.0 + 3.5;
                        if tube.may_reach_brick(centre, MARGIN) {
                            marked[word] |= bit;
                        }
                    }
                }
            }
        }
    }

    /// Fills brick `b`'s density (unitless) and temperature (Kelvin) in OpenVDB leaf order
    /// ([`leaf_offset`](plume_volume::grid::leaf_offset)); voxels outside `[0, resolution)³` are 0.
    /// Returns false, with both arrays all zero, when no voxel has density (always for `b`
    /// outside `[0, brick_dims)`). A pure function of the parameters and `b`.
    pub fn fill_brick(
        &self,
        b: IVec3,
        density: &mut [f32; 512],
        temperature: &mut [f32; 512],
    ) -> bool {
        density.fill(0.0);
        temperature.fill(0.0);
        if b.cmplt(IVec3::ZERO).any() || b.cmpge(self.brick_dims).any() {
            return false;
        }
        let origin = b * LEAF_DIM;
        let end = (IVec3::splat(self.resolution) - origin).min(IVec3::splat(LEAF_DIM));
        let centre = origin.as_dvec3() + 3.5;
        let mut acc =
            Accumulator { density: [0.0; LEAF_VOXELS], weighted_temperature: [0.0; LEAF_VOXELS] };
        let mut any = false;
        for &t in self.grid.tubes_near(b) {
            let tube = &self.tubes[t as usize];
            if tube.may_reach_brick(centre, MARGIN) {
                tube.accumulate(origin, end, &mut acc);
                any = true;
            }
        }
        if !any {
            return false;
        }
        let mut occupied = false;
        for i in 0..LEAF_VOXELS {
            let d = acc.density[i];
            if d > 0.0 {
                density[i] = d;
                temperature[i] =
                    (acc.weighted_temperature[i] / d).clamp(FOOT_TEMPERATURE, PEAK_TEMPERATURE);
                occupied = true;
            }
        }
        occupied
    }

    /// Estimated bytes of dense `f32` data, both channels: [`BYTES_PER_BRICK`] per brick
    /// listed by [`Flare::bricks_in_slab`] (so an upper estimate: 5–15 % of listed bricks
    /// are empty). Exact up to 64 slabs (512³); above, evenly spaced slabs are counted and
    /// scaled: 64 up to 4096³ (within a few per cent), then fewer as slabs get costlier,
    /// `64·(4096/resolution)²` but at least 8. Computed once, on first call: listing slabs
    /// takes seconds at the largest resolutions.
    #[must_use]
    pub fn estimated_bytes(&self) -> u64 {
        let bricks = *self.estimated_bricks.get_or_init(|| {
            let slabs = self.brick_dims.z as u64;
            let affordable =
                (64.0 * (4096.0 / f64::from(self.resolution)).powi(2)).clamp(8.0, 64.0) as u64;
            let sampled = slabs.min(affordable);
            let counted: u64 = (0..sampled)
                .into_par_iter()
                .map(|i| {
                    self.bricks_in_slab(((2 * i + 1) * slabs / (2 * sampled)) as i32).len() as u64
                })
                .sum();
            (counted * slabs + sampled / 2) / sampled
        });
        bricks * BYTES_PER_BRICK
    }

    /// In-memory `density` and `temperature` grids (same leaves, same transform,
    /// background 0), from the same bricks as [`Flare::fill_brick`]; leaves in (z, y, x)
    /// order of their bricks, all-zero bricks dropped. Slabs are filled in parallel on the
    /// current rayon pool; the result does not depend on the thread count.
    ///
    /// Needs about [`Flare::estimated_bytes`] of memory: for small resolutions only.
    #[must_use]
    pub fn to_float_grids(&self) -> (FloatGrid, FloatGrid) {
        let slabs: Vec<Vec<FilledBrick>> = (0..self.brick_dims.z)
            .into_par_iter()
            .map(|bz| {
                let mut filled = Vec::new();
                for b in self.bricks_in_slab(bz) {
                    let mut brick = FilledBrick {
                        origin: b * LEAF_DIM,
                        density: Box::new([0.0; 512]),
                        temperature: Box::new([0.0; 512]),
                    };
                    if self.fill_brick(b, &mut brick.density, &mut brick.temperature) {
                        filled.push(brick);
                    }
                }
                filled
            })
            .collect();
        let grid = |name: &str| FloatGrid {
            name: name.to_owned(),
            world_from_index: self.world_from_index(),
            background: 0.0,
            origins: Vec::new(),
            values: Vec::new(),
        };
        let (mut density, mut temperature) = (grid("density"), grid("temperature"));
        for brick in slabs.into_iter().flatten() {
            density.origins.push(brick.origin);
            density.values.extend_from_slice(&brick.density[..]);
            temperature.origins.push(brick.origin);
            temperature.values.extend_from_slice(&brick.temperature[..]);
        }
        (density, temperature)
    }
}

/// One non-empty brick of [`Flare::to_float_grids`].
struct FilledBrick {
    /// Voxel index of the brick's first voxel, `8b`.
    origin: IVec3,
    density: Box<[f32; LEAF_VOXELS]>,
    temperature: Box<[f32; LEAF_VOXELS]>,
}

impl LoopGrid {
    fn new(tubes: &[Tube], resolution: i32, brick_dims: IVec3) -> LoopGrid {
        let cell_bricks = (brick_dims.max_element() + MAX_GRID_CELLS - 1) / MAX_GRID_CELLS;
        let cells = (brick_dims + cell_bricks - 1) / cell_bricks;
        let cell_voxels = cell_bricks * LEAF_DIM;
        // (cell, tube) pairs, per tube in parallel; collected in tube order
        let per_tube: Vec<Vec<u32>> = tubes
            .par_iter()
            .map(|tube| {
                let to_cell = |v: f64| {
                    ((v / f64::from(cell_voxels)).floor() as i64)
                        .clamp(0, i64::from(cells.max_element() - 1)) as i32
                };
                let lo = IVec3::new(
                    to_cell(tube.lo.x - MARGIN),
                    to_cell(tube.lo.y - MARGIN),
                    to_cell(tube.lo.z - MARGIN),
                );
                let hi = IVec3::new(
                    to_cell(tube.hi.x + MARGIN),
                    to_cell(tube.hi.y + MARGIN),
                    to_cell(tube.hi.z + MARGIN),
                );
                let mut list = Vec::new();
                for z in lo.z..=hi.z.min(cells.z - 1) {
                    for y in lo.y..=hi.y.min(cells.y - 1) {
                        for x in lo.x..=hi.x.min(cells.x - 1) {
                            // Bounding sphere of the cell's voxel centres
                            let first = IVec3::new(x, y, z) * cell_voxels;
                            let last = ((IVec3::new(x, y, z) + 1) * cell_voxels)
                                .min(IVec3::splat(resolution))
                                - 1;
                            let (first, last) = (
                                first.as_dvec3(),
                                last.max(IVec3::new(x, y, z) * cell_voxels).as_dvec3(),
                            );
                            let radius = 0.5 * (last - first).length();
                            if tube.distance(0.5 * (first + last))
                                < f64::from(tube.reach) + radius + MARGIN
                            {
                                list.push(((z * cells.y + y) * cells.x + x) as u32);
                            }
                        }
                    }
                }
                list
            })
            .collect();
        let cell_count = (cells.x * cells.y * cells.z) as usize;
        let mut offsets = vec![0u32; cell_count + 1];
        for &c in per_tube.iter().flatten() {
            offsets[c as usize + 1] += 1;
        }
        for c in 0..cell_count {
            offsets[c + 1] += offsets[c];
        }
        let mut next = offsets.clone();
        let mut list = vec![0u32; offsets[cell_count] as usize];
        for (t, cells_of_tube) in per_tube.iter().enumerate() {
            for &c in cells_of_tube {
                list[next[c as usize] as usize] = t as u32;
                next[c as usize] += 1;
            }
        }
        LoopGrid { cell_bricks, cells, offsets, tubes: list }
    }

    /// Tubes that may reach brick `b` (inside the brick range), ascending.
    fn tubes_near(&self, b: IVec3) -> &[u32] {
        let c = (b / self.cell_bricks).min(self.cells - 1);
        let i = ((c.z * self.cells.y + c.y) * self.cells.x + c.x) as usize;
        &self.tubes[self.offsets[i] as usize..self.offsets[i + 1] as usize]
    }
}
