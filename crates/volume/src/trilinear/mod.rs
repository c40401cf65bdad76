//! Trilinear reconstruction with exact regular tracking (METHOD.md §12).
//!
//! **Convention.** OpenVDB's `BoxSampler`: for index-space `p`, `i = ⌊p⌋`, `f = p − i`,
//! the value is `Σ_{c∈{0,1}³} v_{i+c} Π_k (c_k f_k + (1 − c_k)(1 − f_k))`. Voxel centres stay
//! at integer indices; voxels outside the volume (and inactive ones) are 0.
//!
//! **Dual cells.** The unit of traversal is the *dual cell* `[i, i+1]³` between 8 voxel
//! centres. Along a ray each `f_k` is linear in the local distance `u`, so density is a
//! cubic on each dual cell ([`poly`]), expanded in `u` directly (never in world `t`).
//!
//! **Integrals.** Along a piece, `∫₀ᵘ v(f0 + d s) ds = Σ_c v_c W_c(u)` with the integrated
//! trilinear weights `W_c` ([`poly::integrated_weights`]: 2-point Gauss–Legendre, exact
//! for the cubic weights), so one set of 8 weights gives the optical depth and all three
//! emission channels of a piece. Free paths solve the quartic `∫₀ᵘ ρ` from the density
//! cubic ([`poly::cubic_along`]), formed only in the piece where the path ends.
//!
//! **What is interpolated.** Density ρ, and the *per-voxel emission density*
//! `L_e,i = le(ρ_i, s_i)` in every convention: `L_e(u)` is then a cubic per channel and the
//! line estimator's integral is closed form. This is also what Cycles 5.0.1 renders: it
//! looks OpenVDB grids up by stochastic one-tap sampling (one corner voxel drawn with
//! probability `w_c`), whose expected value is `Σ w_c le(ρ_c, s_c)`, not the blackbody of an
//! interpolated temperature, which is darker at a fire's edges (the blackbody is convex in
//! T, and inactive voxels pull an interpolated T down). `scripts/compare-cycles.sh` checks
//! the match (docs/cycles.md, "Extinction, scattering, reconstruction").
//!
//! **Skipping.** A dual cell in brick `b` reads voxels of bricks `b + {0,1}³`, so the
//! dual pyramid's level-0 node `b` is the union of the volume pyramid's level-0 nodes
//! `b + {0,1}³`, and coarser nodes are unions of their children: a node that is uniform
//! there is constant over every dual cell beneath it, and is crossed as one piece.
//!
//! **Shadow rays.** Optical depth alone needs only density: [`density`] walks the same
//! dual cells reading one value per corner, with the same sum per piece.
//!
//! **Memory.** No second copy of the voxels: corners are read from the volume's bricks;
//! the dual pyramid is one more pyramid (a few bytes per brick).

pub mod density;
pub mod dual;
pub mod field;
pub mod piece;
pub mod poly;
pub mod window;

pub use field::{PointCorners, Trilinear};
pub use piece::CubicSegment;
