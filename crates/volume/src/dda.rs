//! Hierarchical 3-D DDA over a lattice of cells in a [`Volume`]'s index space: turns a
//! world ray into ordered, gap-free pieces.
//!
//! Traversal runs in index space, `o' = A⁻¹(x − b)`, `d' = A⁻¹ω`, sharing the parameter
//! `t` with the world ray, so crossings are world distances even under non-uniform scale
//! or shear (METHOD.md §1).
//!
//! **One walker, two lattices** ([`Cells`]). Cell `k` spans `[k − S, k + 1 − S]` along
//! each axis, for a lattice shift `S`:
//! - `nearest::NearestVoxels`, `S = ½`: cell `k` is voxel `k`, `[k−½, k+½]`; a cell yields one
//!   constant [`Segment`] (nearest reconstruction, `nearest::VolumeSegments`);
//! - the dual cells of trilinear reconstruction (`volume::trilinear`), `S = 0`: cell `i`
//!   is `[i, i+1]`, between the voxel centres `i … i+1`, and yields a cubic piece.
//!
//! The dual walk is the voxel walk on the lattice shifted by ½ (`o' − ½` has the dual
//! cells where `o'` has the voxels), so the same code serves both; `S` is a constant of
//! the lattice type, and the walker is monomorphized for each, so the nearest walk does
//! exactly the arithmetic of a walk written for voxels alone.
//!
//! Cells are grouped in 8³ bricks on a table with a min/max pyramid. On entering a brick
//! the DDA asks the pyramid for the largest node around the current cell that is
//! *uniform* (constant in every channel, zero included); such a node is crossed as one
//! piece. Otherwise the brick is dense: the lattice fetches its data once
//! ([`Cells::dense`]) and the DDA steps cell by cell (Amanatides & Woo 1987) until it
//! leaves the brick.
//!
//! Robustness (METHOD.md §10.9):
//! - A zero direction component (`d == 0.0`, also `-0.0`) never steps on that axis; we
//!   never form `1/d` for it.
//! - Every crossing `t` is computed afresh from an integer boundary, `(k + 1 − S − o)/d`
//!   or `(k − S − o)/d`, so there is no drift along long rays; the cell index is integer
//!   state, so a crossing that rounds to zero length still makes progress.
//! - A start exactly on a boundary takes the cell being entered.
//! - Adjacent pieces the lattice calls mergeable ([`Cells::merge`]: bit-identical constant
//!   values) are merged, so an empty region is one piece, and the last piece ends exactly
//!   at the clipped ray's end.

use std::ops::ControlFlow;

use glam::{DAffine3, DVec3, IVec3};

use super::brick::{Volume, BRICK};
use super::field::{clip_to_box, Bounds3, Piece, Ray, SegmentIter};
use super::pyramid::{Level, NodeBounds};

/// The table of 8³-cell bricks a lattice is grouped in, with its min/max pyramid.
#[derive(Clone, Copy, Debug)]
pub struct CellTable<'t> {
    /// Brick coordinate (first cell / 8) of table entry (0,0,0).
    pub brick_lo: IVec3,
    /// Table size in bricks.
    pub dims: IVec3,
    /// Pyramid levels over the table, finest (one node per table entry) first. A uniform
    /// node is constant over every cell beneath it.
    pub levels: &'t [Level],
}

/// A box of cells `lo .. hi` (`hi` exclusive): where a lattice's rays are clipped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CellBox {
    /// First cell.
    pub lo: IVec3,
    /// One past the last cell.
    pub hi: IVec3,
}

/// A ray in index space: `p(t) = o + d t`, `t` the world ray's parameter.
#[derive(Clone, Copy, Debug)]
pub struct IndexLine {
    /// Origin, index space.
    pub o: DVec3,
    /// Direction, index units per world unit.
    pub d: DVec3,
}

/// A lattice of cells the hierarchical DDA walks ([`CellWalk`]): cell `k` spans
/// `[k − SHIFT, k + 1 − SHIFT]` per axis in index space; what a cell and a uniform node
/// yield; when two adjacent pieces merge. See the module docs.
pub trait Cells: Copy {
    /// Lattice shift `S`: ½ for voxels, 0 for dual cells.
    const SHIFT: f64;
    /// What the walk yields.
    type Piece: Piece;
    /// A dense brick's data handles, fetched once when the walk enters the brick. A walk
    /// keeps one, made by `Default` when it first enters a dense brick and refilled in
    /// place at every later one ([`Cells::dense`]).
    type Dense: Copy + Default;
    /// What one cell holds, read before the walk steps past it.
    type Cell: Copy;

    /// The volume whose index space the cells live in.
    fn volume(&self) -> &Volume;
    /// The brick table and pyramid over the cells.
    fn table(&self) -> CellTable<'_>;
    /// The cells rays are clipped to (inside the table).
    fn cell_box(&self) -> CellBox;
    /// Fills `dense` with the data handles of table brick `brick` (brick coordinate), in
    /// place: a dual brick's are some 500 bytes, which returning them by value would copy
    /// twice per brick entered, a visible share of a linear render's profile. False when the brick has no data (then it is
    /// crossed as empty, and `dense` holds anything).
    fn dense(&self, brick: IVec3, dense: &mut Self::Dense) -> bool;
    /// The piece of `line` over `[t0, t1]` inside cell `ijk` of the dense brick whose
    /// first cell is `origin`. `dense` may remember what the previous cell read (the walk
    /// steps to a neighbour each time).
    fn dense_piece(
        &self,
        dense: &mut Self::Dense,
        origin: IVec3,
        ijk: IVec3,
        t0: f64,
        t1: f64,
        line: &IndexLine,
    ) -> Self::Piece;
    /// True when local cell `l` of the dense brick is known to be [`Cells::empty`] without
    /// reading it (trilinear's empty blocks, `volume::trilinear::dual`). The walk then
    /// steps through the run of such cells without asking for their pieces, gives the
    /// run as one empty piece (what their pieces would have merged into), and tells
    /// `dense` with [`Cells::after_empty`]. None by default.
    #[inline]
    fn known_empty(_dense: &Self::Dense, _l: IVec3) -> bool {
        false
    }
    /// `dense` after a run of [`Cells::known_empty`] cells ending with local cell `l`: what
    /// [`Cells::dense_piece`] would have left there.
    #[inline]
    fn after_empty(_dense: &mut Self::Dense, _l: IVec3) {}
    /// The cell every cell beneath a uniform pyramid node is.
    fn uniform(node: &NodeBounds) -> Self::Cell;
    /// An empty cell (density, source 0; albedo 1).
    fn empty() -> Self::Cell;
    /// The piece of `line` over `[t0, t1]` inside `cell` (a uniform node or empty space).
    fn piece(&self, cell: Self::Cell, t0: f64, t1: f64, line: &IndexLine) -> Self::Piece;
    /// Extend `into` by `next` (adjacent, `into.t1 == next.t0`) when both are constant
    /// with bit-identical values; false (and nothing changed) otherwise.
    fn merge(into: &mut Self::Piece, next: &Self::Piece) -> bool;
    /// False when `piece` can never merge (then the walk hands it on at once).
    fn mergeable(piece: &Self::Piece) -> bool;
}

/// A uniform pyramid node found by the walk.
#[derive(Clone, Copy, Debug)]
struct UniformNode {
    /// First cell.
    lo: IVec3,
    /// Edge in cells.
    size: i32,
    bounds: NodeBounds,
}

/// Cell containing coordinate `p` along an axis moving in direction `d`, for lattice
/// shift `shift`; on a boundary, the cell being entered.
#[inline]
fn cell_of(p: f64, d: f64, shift: f64) -> i32 {
    let x = p + shift;
    let c = if d < 0.0 { x.ceil() - 1.0 } else { x.floor() };
    c as i32 // saturating
}

/// One step of the cell DDA inside a dense brick ([`CellWalk`]'s fields): moves `ijk`
/// across the nearest exit face (every axis whose face is crossed at that same `t`),
/// updates those axes' `t_next` from the integer index, and returns the exit parameter of
/// the cell it left.
#[inline(always)]
fn step_cell(
    ijk: &mut IVec3,
    t_next: &mut DVec3,
    step: IVec3,
    face: DVec3,
    o: DVec3,
    inv_d: DVec3,
) -> f64 {
    let t_exit = t_next.x.min(t_next.y).min(t_next.z);
    for a in 0..3 {
        if t_next[a] == t_exit {
            ijk[a] += step[a];
            t_next[a] = (f64::from(ijk[a]) + face[a] - o[a]) * inv_d[a];
        }
    }
    t_exit
}

/// True when cell `ijk` lies outside the dense brick whose first cell is `origin`.
#[inline(always)]
fn outside_brick(ijk: IVec3, origin: IVec3) -> bool {
    let l = ijk - origin;
    (l.x as u32 | l.y as u32 | l.z as u32) >= BRICK as u32
}

/// Iterator over the pieces of one ray through a lattice of cells. See the module docs.
#[derive(Debug)]
pub struct CellWalk<C: Cells> {
    cells: C,
    o: DVec3,
    d: DVec3,
    inv_d: DVec3,
    /// Per axis: `+1`/`−1` cell step, 0 for a zero component.
    step: IVec3,
    /// Per axis: offset of the exit face from the cell's index (`1 − S` or `−S`).
    face: DVec3,
    /// Per axis: parameter of the current cell's exit face (+∞ for a zero component);
    /// valid while stepping through a dense brick.
    t_next: DVec3,
    t: f64,
    t_end: f64,
    ijk: IVec3,
    done: bool,
    /// First cell of the dense brick being stepped through (`None`: not in one).
    origin: Option<IVec3>,
    /// The data handles of that brick (or of the last one the walk was in).
    dense: Option<C::Dense>,
    pending: Option<C::Piece>,
    raw_steps: u64,
}

impl<C: Cells> CellWalk<C> {
    /// The pieces of `ray` within `[t_min, t_max]`, clipped to the lattice's cell box.
    pub fn new(cells: C, ray: &Ray, t_min: f64, t_max: f64) -> Self {
        let volume = cells.volume();
        let o = volume.index_from_world.transform_point3(ray.origin);
        let d = volume.index_from_world.transform_vector3(ray.direction);
        let inv_d = DVec3::new(
            if d.x != 0.0 { 1.0 / d.x } else { 0.0 },
            if d.y != 0.0 { 1.0 / d.y } else { 0.0 },
            if d.z != 0.0 { 1.0 / d.z } else { 0.0 },
        );
        let step = IVec3::new(
            (d.x > 0.0) as i32 - (d.x < 0.0) as i32,
            (d.y > 0.0) as i32 - (d.y < 0.0) as i32,
            (d.z > 0.0) as i32 - (d.z < 0.0) as i32,
        );
        let face = DVec3::select(
            step.cmpgt(IVec3::ZERO),
            DVec3::splat(1.0 - C::SHIFT),
            DVec3::select(step.cmplt(IVec3::ZERO), DVec3::splat(-C::SHIFT), DVec3::ZERO),
        );
        let empty = volume.is_empty();
        let mut it = CellWalk {
            cells,
            o,
            d,
            inv_d,
            step,
            face,
            t_next: DVec3::INFINITY,
            t: 0.0,
            t_end: 0.0,
            ijk: IVec3::ZERO,
            done: true,
            origin: None,
            dense: None,
            pending: None,
            raw_steps: 0,
        };
        if empty || d == DVec3::ZERO {
            return it;
        }
        let CellBox { lo, hi } = it.cells.cell_box();
        if let Some((t0, t1)) =
            clip_to_box(o, d, lo.as_dvec3() - C::SHIFT, hi.as_dvec3() - C::SHIFT, t_min, t_max)
        {
            it.t = t0;
            it.t_end = t1;
            it.done = false;
            let p = o + d * t0;
            it.ijk = IVec3::new(
                cell_of(p.x, d.x, C::SHIFT),
                cell_of(p.y, d.y, C::SHIFT),
                cell_of(p.z, d.z, C::SHIFT),
            )
            .clamp(lo, hi - 1);
        }
        it
    }

    /// Raw (unmerged) pieces produced so far: cell steps plus skipped nodes.
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

    /// Parameter at which the ray leaves the current cell `ijk` on axis `a` (+∞ if it
    /// never does). Computed from the integer index, so it never drifts.
    #[inline]
    fn face_crossing(&self, a: usize) -> f64 {
        if self.step[a] == 0 {
            f64::INFINITY
        } else {
            (f64::from(self.ijk[a]) + self.face[a] - self.o[a]) * self.inv_d[a]
        }
    }

    /// Leave the box of cells `[lo, lo + size)`: returns the exit parameter and moves
    /// `ijk` to the cell entered there.
    fn exit_box(&mut self, lo: IVec3, size: i32) -> f64 {
        let mut ta = [f64::INFINITY; 3];
        for (a, t) in ta.iter_mut().enumerate() {
            if self.d[a] > 0.0 {
                *t = self.crossing(a, f64::from(lo[a] + size) - C::SHIFT);
            } else if self.d[a] < 0.0 {
                *t = self.crossing(a, f64::from(lo[a]) - C::SHIFT);
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
                cell_of(p[a], self.d[a], C::SHIFT).clamp(lo[a], lo[a] + size - 1)
            };
        }
        t_exit
    }

    /// The coarsest uniform pyramid node around table brick `rel` (table-relative). A
    /// uniform node's children are uniform with the same values, so a non-uniform brick
    /// settles it in one lookup; otherwise search from the top for the coarsest uniform
    /// level.
    #[inline]
    fn uniform_node(table: &CellTable<'_>, rel: IVec3) -> Option<UniformNode> {
        let levels = table.levels;
        if !levels[0].get(rel).is_uniform() {
            return None;
        }
        for (k, level) in levels.iter().enumerate().rev() {
            let nc = rel >> (k as i32);
            let node = level.get(nc);
            if node.is_uniform() {
                return Some(UniformNode {
                    lo: (table.brick_lo + (nc << (k as i32))) * BRICK,
                    size: BRICK << k,
                    bounds: *node,
                });
            }
        }
        None
    }

    /// Next raw piece, possibly of zero length (then `None` is not returned; the caller
    /// loops). Returns `None` only at the end.
    fn step_raw(&mut self) -> Option<C::Piece> {
        while !self.done {
            if self.t >= self.t_end {
                self.done = true;
                return None;
            }
            let t0 = self.t;
            let (t_exit, cell);
            if let (Some(origin), Some(dense)) = (self.origin, self.dense.as_mut()) {
                if C::known_empty(dense, self.ijk - origin) {
                    if let Some(piece) = self.empty_run(origin) {
                        return Some(piece);
                    }
                    continue;
                }
                // Step one cell of a dense brick; its piece is built from the brick's data
                // before the walk may leave the brick
                let ijk = self.ijk;
                let t1 = step_cell(
                    &mut self.ijk,
                    &mut self.t_next,
                    self.step,
                    self.face,
                    self.o,
                    self.inv_d,
                )
                .min(self.t_end);
                let leaves = outside_brick(self.ijk, origin);
                if t1 > t0 {
                    let piece = self.cells.dense_piece(
                        dense,
                        origin,
                        ijk,
                        t0,
                        t1,
                        &IndexLine { o: self.o, d: self.d },
                    );
                    if leaves {
                        self.origin = None;
                    }
                    self.t = t1;
                    self.raw_steps += 1;
                    return Some(piece);
                }
                if leaves {
                    self.origin = None;
                }
                continue;
            } else {
                let table = self.cells.table();
                let bc = IVec3::new(
                    self.ijk.x.div_euclid(BRICK),
                    self.ijk.y.div_euclid(BRICK),
                    self.ijk.z.div_euclid(BRICK),
                );
                let rel = bc - table.brick_lo;
                if rel.cmplt(IVec3::ZERO).any() || rel.cmpge(table.dims).any() {
                    // Left the table (only by rounding before t_end): the rest is empty.
                    self.done = true;
                    self.raw_steps += 1;
                    return Some(self.cells.piece(C::empty(), t0, self.t_end, &self.line()));
                }
                match Self::uniform_node(&table, rel) {
                    Some(node) => {
                        // Cross a constant (often empty) node in one step
                        cell = C::uniform(&node.bounds);
                        t_exit = self.exit_box(node.lo, node.size);
                    }
                    None => {
                        if self.cells.dense(bc, self.dense.get_or_insert_with(C::Dense::default)) {
                            self.origin = Some(bc * BRICK);
                            self.t_next = DVec3::new(
                                self.face_crossing(0),
                                self.face_crossing(1),
                                self.face_crossing(2),
                            );
                            continue;
                        }
                        // A non-uniform node without a brick: only a damaged cache file says
                        // so (its checksums fail the render); cross it as empty.
                        cell = C::empty();
                        t_exit = self.exit_box(bc * BRICK, BRICK);
                    }
                }
            }
            let t1 = t_exit.min(self.t_end);
            if t1 > t0 {
                self.t = t1;
                self.raw_steps += 1;
                return Some(self.cells.piece(cell, t0, t1, &self.line()));
            }
        }
        None
    }

    /// From the current cell, [`Cells::known_empty`], through the run of such cells of the
    /// dense brick at `origin`: the same cell steps, crossings and step count as stepping
    /// them one piece at a time, and one empty piece over the run (`None` if it has no
    /// length), which merges with its neighbours as theirs would have.
    fn empty_run(&mut self, origin: IVec3) -> Option<C::Piece> {
        let t0 = self.t;
        let mut last = self.ijk - origin;
        loop {
            let t1 = step_cell(
                &mut self.ijk,
                &mut self.t_next,
                self.step,
                self.face,
                self.o,
                self.inv_d,
            )
            .min(self.t_end);
            if t1 > self.t {
                self.t = t1;
                self.raw_steps += 1;
            }
            let leaves = outside_brick(self.ijk, origin);
            let l = self.ijk - origin;
            let Some(dense) = self.dense.as_mut() else { break };
            if leaves || self.t >= self.t_end || !C::known_empty(dense, l) {
                C::after_empty(dense, last);
                if leaves {
                    self.origin = None;
                }
                break;
            }
            last = l;
        }
        (self.t > t0).then(|| self.cells.piece(C::empty(), t0, self.t, &self.line()))
    }

    #[inline]
    fn line(&self) -> IndexLine {
        IndexLine { o: self.o, d: self.d }
    }
}

impl<C: Cells> Iterator for CellWalk<C> {
    type Item = C::Piece;

    fn next(&mut self) -> Option<C::Piece> {
        // A piece that can merge with nothing waits for nothing (no copy through `pending`)
        if let Some(p) = self.pending.take_if(|p| !C::mergeable(p)) {
            return Some(p);
        }
        loop {
            let raw = self.step_raw();
            match (self.pending.take(), raw) {
                (None, None) => return None,
                (Some(p), None) => return Some(p),
                (None, Some(s)) if !C::mergeable(&s) => return Some(s),
                (None, Some(s)) => self.pending = Some(s),
                (Some(mut p), Some(s)) => {
                    if C::merge(&mut p, &s) {
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

impl<C: Cells> SegmentIter for CellWalk<C> {
    fn voxel_steps(&self) -> u64 {
        self.raw_steps
    }

    /// The iterator's merging (a mergeable piece waits for its neighbour), with each raw
    /// piece built once and handed on by reference. Small pieces (a nearest [`Segment`],
    /// 24 bytes) go through the iterator, which measured faster for them.
    fn visit<B>(&mut self, mut visit: impl FnMut(&C::Piece) -> ControlFlow<B>) -> ControlFlow<B> {
        if std::mem::size_of::<C::Piece>() <= 32 {
            for piece in self.by_ref() {
                visit(&piece)?;
            }
            return ControlFlow::Continue(());
        }
        let mut pending = self.pending.take();
        loop {
            // Read in place: a piece moves only when it waits to merge
            let next = self.step_raw();
            let Some(raw) = next.as_ref() else { break };
            if !C::mergeable(raw) {
                if let Some(p) = pending.take() {
                    visit(&p)?;
                }
                visit(raw)?;
                continue;
            }
            let merged = pending.as_mut().is_some_and(|p| C::merge(p, raw));
            if !merged {
                if let Some(p) = pending.replace(*raw) {
                    visit(&p)?;
                }
            }
        }
        match pending {
            Some(p) => visit(&p),
            None => ControlFlow::Continue(()),
        }
    }
}

/// World-space axis-aligned bounds of the index-space box `index` under
/// `world_from_index` (its 8 corners transformed).
pub fn world_box(world_from_index: &DAffine3, index: Bounds3) -> Bounds3 {
    let Bounds3 { lo, hi } = index;
    let mut wlo = DVec3::splat(f64::INFINITY);
    let mut whi = DVec3::splat(f64::NEG_INFINITY);
    for i in 0..8 {
        let c = DVec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        );
        let w = world_from_index.transform_point3(c);
        wlo = wlo.min(w);
        whi = whi.max(w);
    }
    Bounds3 { lo: wlo, hi: whi }
}
