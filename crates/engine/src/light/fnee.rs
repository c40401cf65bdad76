//! FNEE light sampling through the proxy grid ([`plume_volume::proxy`], METHOD.md §7): a
//! point `y` drawn from the cells in proportion to their power, the *direction* from the
//! shading point towards it, and that direction's density per unit solid angle.
//!
//! **Point density** (per unit world volume): `p_V(y) = P_j / V_j` for `y` in cell `j`;
//! [`ProxyGrid::sample_point`] draws `j ~ P`, then `y` uniformly in the cell.
//!
//! **Direction density** (per unit solid angle; the paper's Eq. 15 with `dV = t² dt dω`):
//!
//! ```text
//! p_σ(ω) = ∫₀^∞ p_V(x + tω) t² dt = Σ_{cells j on the ray} (P_j/V_j) (t_out³ − t_in³)/3,
//! ```
//!
//! the ray clipped at `t = 0`, each term evaluated as `(t_o − t_i)(t_o² + t_o t_i + t_i²)/3`
//! and accumulated in `f64`. `t` is world distance along the unit world direction `ω`;
//! the walk runs in index space (`o' = A⁻¹(x − b)`, `d' = A⁻¹ω`) where `t` is shared, so
//! non-uniform scale and shear are exact. [`ProxyGrid::sample_direction`] returns
//! `ω = (y − x)/|y − x|` and its pdf from the *same* [`ProxyGrid::direction_pdf`], so the
//! sampling and evaluation paths agree bit for bit (METHOD.md §10.8).
//!
//! **DDA robustness** follows `volume::dda`: integer cell state; every crossing is computed
//! afresh from an exact cell boundary (`origin + k·e` is a half-integer, exact in `f64`);
//! a zero direction component (`0.0` or `-0.0`) never steps and is never divided by; a start
//! exactly on a face takes the cell being entered. A cell found from a position (at the
//! start, or where the walk leaves an empty block) is checked against the crossing times
//! of its own faces, so a ray within rounding of a face it crosses later (index direction
//! components of `10⁻¹⁷` arise from axis-aligned world rays under rotations) is in the cell
//! before it.
//!
//! **Empty space.** The walk is clipped to the bounding box of the emitting cells and
//! crosses each block of 4³ cells without emission in one step (a one-byte-per-block
//! occupancy level); inside occupied blocks it steps cell by cell.

use glam::{DVec3, IVec3};

use plume_volume::field::clip_to_box;
use plume_volume::proxy::{ProxyGrid, BLOCK};

/// A point sampled from the proxy's point density `p_V`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProxyPoint {
    /// The point, world space (uniform in its cell).
    pub p_world: DVec3,
    /// Linear index of the cell, `x + dims.x (y + dims.y z)`.
    pub cell: usize,
    /// Probability of choosing that cell, `P_j` (unitless). The point's density per unit
    /// world volume is `pmf / cell_volume()`.
    pub pmf: f64,
}

/// A direction sampled by FNEE.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DirectionSample {
    /// Unit world direction from the shading point towards the sampled proxy point.
    pub direction: DVec3,
    /// `p_σ(direction)` per unit solid angle, bit-identical to
    /// [`ProxyGrid::direction_pdf`] for the same point and direction.
    pub pdf: f64,
}

/// A ray in the proxy's index space, as [`ProxySampling::direction_pdf`] walks its cells:
/// the cell a parameter `t` lies in and the crossings of cell faces, every crossing from
/// the exact face (`(boundary − o)/d`), so the walk never drifts.
struct ProxyLine {
    o: DVec3,
    d: DVec3,
    /// The same reciprocal as `clip_to_box`, so the last crossing equals its `t_end` bit
    /// for bit.
    inv_d: DVec3,
    origin: DVec3,
    edge: f64,
}

impl ProxyLine {
    fn new(proxy: &ProxyGrid, o: DVec3, d: DVec3) -> ProxyLine {
        let inv_d = DVec3::new(
            if d.x != 0.0 { 1.0 / d.x } else { 0.0 },
            if d.y != 0.0 { 1.0 / d.y } else { 0.0 },
            if d.z != 0.0 { 1.0 / d.z } else { 0.0 },
        );
        ProxyLine { o, d, inv_d, origin: proxy.origin, edge: f64::from(proxy.edge) }
    }

    /// Index-space coordinate of cell boundary `k` along axis `a`.
    #[inline]
    fn boundary(&self, a: usize, k: i32) -> f64 {
        self.origin[a] + f64::from(k) * self.edge
    }

    /// The cell along axis `a` at parameter `t`, from the position, then made consistent
    /// with the crossing times of its own faces: a point within rounding of a face whose
    /// crossing lies ahead is in the cell before it. On a face: the cell being entered.
    #[inline]
    fn cell_at(&self, a: usize, t: f64) -> i32 {
        let (o, d) = (self.o, self.d);
        let g = (o[a] + d[a] * t - self.origin[a]) / self.edge;
        let k = (if d[a] < 0.0 { g.ceil() - 1.0 } else { g.floor() }) as i32;
        let crossing = |k: i32| (self.boundary(a, k) - o[a]) * self.inv_d[a];
        if d[a] > 0.0 {
            if crossing(k) > t {
                return k - 1;
            } else if crossing(k + 1) <= t {
                return k + 1;
            }
        } else if d[a] < 0.0 {
            if crossing(k + 1) > t {
                return k + 1;
            } else if crossing(k) <= t {
                return k - 1;
            }
        }
        k
    }

    /// Crossing of the face ahead along axis `a` of a box whose cells run `lo..hi` on it.
    #[inline]
    fn face_ahead(&self, a: usize, lo: i32, hi: i32) -> f64 {
        let (o, d) = (self.o, self.d);
        if d[a] > 0.0 {
            (self.boundary(a, hi) - o[a]) * self.inv_d[a]
        } else if d[a] < 0.0 {
            (self.boundary(a, lo) - o[a]) * self.inv_d[a]
        } else {
            f64::INFINITY
        }
    }

    /// The crossings of the faces ahead of the box of cells `lo..hi`, per axis.
    #[inline]
    fn exits(&self, lo: IVec3, hi: IVec3) -> [f64; 3] {
        std::array::from_fn(|a| self.face_ahead(a, lo[a], hi[a]))
    }
}

/// `(t₁³ − t₀³)/3` in the form that keeps its relative accuracy for `t₁ ≈ t₀`.
#[inline]
fn shell(t0: f64, t1: f64) -> f64 {
    (t1 - t0) * (t1 * t1 + t1 * t0 + t0 * t0) * (1.0 / 3.0)
}

/// FNEE sampling on the proxy grid (the proxy's data is `plume_volume::proxy`; sampling
/// it is light sampling, so it lives here).
pub trait ProxySampling {
    /// Sample a cell `j ~ P` with `u_cell` and a point uniformly inside it with `u_pos`
    /// (all in `[0, 1)`). The point's density is `p_V = pmf / cell_volume()` per unit world
    /// volume.
    #[must_use]
    fn sample_point(&self, u_cell: f64, u_pos: [f64; 3]) -> ProxyPoint;

    /// Sample an FNEE direction from `x_world`: `y` from [`ProxyGrid::sample_point`], then
    /// `ω = (y − x)/|y − x|`; the pdf is [`ProxyGrid::direction_pdf`]`(x_world, ω)`, per unit
    /// solid angle.
    ///
    /// `None` when `y == x` or the pdf rounds to 0 (a grazing ray along a cell face); both
    /// are events of probability zero, so dropping them keeps the estimator unbiased.
    #[must_use]
    fn sample_direction(
        &self,
        x_world: DVec3,
        u_cell: f64,
        u_pos: [f64; 3],
    ) -> Option<DirectionSample> {
        let direction = self.sample_direction_only(x_world, u_cell, u_pos)?;
        let pdf = self.direction_pdf(x_world, direction);
        (pdf > 0.0).then_some(DirectionSample { direction, pdf })
    }

    /// The direction of [`ProxyGrid::sample_direction`] without its pdf, for callers that
    /// need `p_σ` only when the sample turns out to contribute (the pdf is then
    /// [`ProxyGrid::direction_pdf`] of the same arguments, bit for bit). `None` when the
    /// sampled point coincides with `x_world`.
    #[must_use]
    fn sample_direction_only(&self, x_world: DVec3, u_cell: f64, u_pos: [f64; 3]) -> Option<DVec3>;

    /// `p_σ(ω)`: density per unit solid angle with which [`ProxyGrid::sample_direction`]
    /// at `x_world` produces the unit world direction `w_world`. See the module docs.
    ///
    /// 0 when the ray `x + tω, t ≥ 0` meets no emitting cell, or for non-finite input.
    #[must_use]
    fn direction_pdf(&self, x_world: DVec3, w_world: DVec3) -> f64;
}

impl ProxySampling for ProxyGrid {
    fn sample_point(&self, u_cell: f64, u_pos: [f64; 3]) -> ProxyPoint {
        let s = self.alias.sample(u_cell);
        let cell = self.cells[s.index] as usize;
        let p_index = self.origin
            + (self.cell_coords(cell).as_dvec3() + DVec3::from(u_pos)) * f64::from(self.edge);
        ProxyPoint { p_world: self.world_from_index.transform_point3(p_index), cell, pmf: s.pmf }
    }

    fn sample_direction_only(&self, x_world: DVec3, u_cell: f64, u_pos: [f64; 3]) -> Option<DVec3> {
        let y = self.sample_point(u_cell, u_pos).p_world;
        let v = y - x_world;
        let length = v.length();
        (length > 0.0 && length.is_finite()).then(|| v / length)
    }

    fn direction_pdf(&self, x_world: DVec3, w_world: DVec3) -> f64 {
        debug_assert!(
            (w_world.length() - 1.0).abs() < 1e-6,
            "direction_pdf needs a unit direction, got {w_world}"
        );
        let o = self.index_from_world.transform_point3(x_world);
        let d = self.index_from_world.transform_vector3(w_world);
        if !o.is_finite() || !d.is_finite() || d == DVec3::ZERO {
            return 0.0;
        }
        let line = ProxyLine::new(self, o, d);
        let lo = DVec3::from_array(std::array::from_fn(|a| line.boundary(a, self.occupied_lo[a])));
        let hi = DVec3::from_array(std::array::from_fn(|a| line.boundary(a, self.occupied_hi[a])));
        let Some((t_start, t_end)) = clip_to_box(o, d, lo, hi, 0.0, f64::INFINITY) else {
            return 0.0;
        };
        let (occupied_lo, occupied_hi) = (self.occupied_lo, self.occupied_hi);
        let inside = |c: IVec3| c.cmpge(occupied_lo).all() && c.cmplt(occupied_hi).all();
        let mut c = IVec3::ZERO;
        for a in 0..3 {
            c[a] = line.cell_at(a, t_start).clamp(occupied_lo[a], occupied_hi[a] - 1);
        }
        let (nx, ny) = (self.dims.x as usize, self.dims.y as usize);
        let (bx, by) = (self.block_dims.x as usize, self.block_dims.y as usize);
        let mut t = t_start;
        let mut sum = 0.0f64;
        // The current cell's exits, kept from step to step: a step recomputes only the
        // axes it crossed (from the exact face, as every crossing is)
        let mut ta = line.exits(c, c + 1);
        loop {
            let b = c / BLOCK;
            if !self.block_occupied[b.x as usize + bx * (b.y as usize + by * b.z as usize)] {
                // Cross a block without emission in one step
                let (lo, hi) = (b * BLOCK, (b * BLOCK + BLOCK).min(self.dims));
                let tb = line.exits(lo, hi);
                let t_exit = tb[0].min(tb[1]).min(tb[2]);
                if t_exit >= t_end {
                    break;
                }
                t = t.max(t_exit);
                for a in 0..3 {
                    c[a] = if tb[a] == t_exit {
                        if d[a] > 0.0 {
                            hi[a]
                        } else {
                            lo[a] - 1
                        }
                    } else {
                        line.cell_at(a, t_exit).clamp(lo[a], hi[a] - 1)
                    };
                }
                if !inside(c) {
                    break;
                }
                ta = line.exits(c, c + 1);
                continue;
            }
            // Step one cell
            let t_exit = ta[0].min(ta[1]).min(ta[2]);
            let t1 = t_exit.min(t_end);
            if t1 > t {
                // Add this cell's share P_j (t₁³ − t₀³)/3 (divided by V_j once at the end)
                let pmf = self.cell_pmf[c.x as usize + nx * (c.y as usize + ny * c.z as usize)];
                if pmf != 0.0 {
                    sum += pmf * shell(t, t1);
                }
                t = t1;
            }
            if t_exit >= t_end {
                break;
            }
            for a in 0..3 {
                if ta[a] == t_exit {
                    c[a] += if d[a] > 0.0 { 1 } else { -1 };
                    ta[a] = line.face_ahead(a, c[a], c[a] + 1);
                }
            }
            if !inside(c) {
                break;
            }
        }
        sum / self.cell_volume
    }
}
