//! Polynomials along a ray in a dual cell (METHOD.md §12): the trilinear weights as
//! cubics in the local distance `u`, the quartic optical depth, and free paths by
//! safeguarded Newton in f64.

use glam::DVec3;

/// Coefficients `[a0, a1, a2, a3]` of `Σ_c v_c Π_k (c_k f_k(u) + (1 − c_k)(1 − f_k(u)))`
/// with `f(u) = f0 + d u`; corner `c` has bit 0 for +x, bit 1 for +y, bit 2 for +z.
///
/// Expanded in `u` by interpolating along x (linear), then y (quadratic), then z (cubic),
/// so no term is ever formed in world `t` (no cancellation far from the origin).
#[inline]
#[must_use]
pub fn cubic_along(v: [f64; 8], f0: DVec3, d: DVec3) -> [f64; 4] {
    // Along x: g(u) = v0 + (v1 − v0) f_x(u), linear, for each (y, z)
    let lin = |a: f64, b: f64| -> [f64; 2] {
        let diff = b - a;
        [a + diff * f0.x, diff * d.x]
    };
    let g = [lin(v[0], v[1]), lin(v[2], v[3]), lin(v[4], v[5]), lin(v[6], v[7])];
    // Along y: h(u) = g0 + (g1 − g0) f_y(u), quadratic, for each z
    let quad = |a: [f64; 2], b: [f64; 2]| -> [f64; 3] {
        let (e0, e1) = (b[0] - a[0], b[1] - a[1]);
        [a[0] + e0 * f0.y, a[1] + e0 * d.y + e1 * f0.y, e1 * d.y]
    };
    let h0 = quad(g[0], g[1]);
    let h1 = quad(g[2], g[3]);
    // Along z: cubic
    let (e0, e1, e2) = (h1[0] - h0[0], h1[1] - h0[1], h1[2] - h0[2]);
    [h0[0] + e0 * f0.z, h0[1] + e0 * d.z + e1 * f0.z, h0[2] + e1 * d.z + e2 * f0.z, e2 * d.z]
}

/// Abscissa of 2-point Gauss–Legendre on `[0, 1]`: `(1 − 1/√3)/2`.
const GAUSS: f64 = 0.211_324_865_405_187_1;

/// The 8 trilinear weights at cell-local `f`: `w_c = Π_k (c_k f_k + (1 − c_k)(1 − f_k))`
/// (corner bit 0 is +x, bit 1 +y, bit 2 +z).
#[inline]
#[must_use]
pub fn weights(f: DVec3) -> [f64; 8] {
    let (x, y, z) = ([1.0 - f.x, f.x], [1.0 - f.y, f.y], [1.0 - f.z, f.z]);
    let xy = [x[0] * y[0], x[1] * y[0], x[0] * y[1], x[1] * y[1]];
    std::array::from_fn(|c| xy[c & 3] * z[c >> 2])
}

/// The integrated trilinear weights `W_c(u) = ∫₀ᵘ w_c(f0 + d s) ds`, so that the integral
/// of any interpolated quantity along the piece is `Σ_c v_c W_c(u)`: one set of weights
/// serves density and every emission channel.
///
/// Each `w_c(f0 + d s)` is a cubic in `s`, and 2-point Gauss–Legendre is exact for cubics:
/// `W_c = u/2 (w_c(f(s₁)) + w_c(f(s₂)))`, `s₁,₂ = u (1 ∓ 1/√3)/2`. Every term is a product
/// of factors in `[0, 1]`, so nothing cancels (unlike differences of corner values).
#[inline]
#[must_use]
pub fn integrated_weights(f0: DVec3, d: DVec3, u: f64) -> [f64; 8] {
    let a = weights(f0 + d * (u * GAUSS));
    let b = weights(f0 + d * (u * (1.0 - GAUSS)));
    let half = 0.5 * u;
    std::array::from_fn(|c| half * (a[c] + b[c]))
}

/// `Σ_c v_c w_c`.
#[inline]
#[must_use]
pub fn dot(v: &[f64; 8], w: &[f64; 8]) -> f64 {
    v.iter().zip(w).fold(0.0, |acc, (a, b)| acc + a * b)
}

/// `Σ a_j uʲ` by Horner's rule.
#[inline]
#[must_use]
pub fn eval(a: &[f64; 4], u: f64) -> f64 {
    ((a[3] * u + a[2]) * u + a[1]) * u + a[0]
}

/// `∫₀ᵘ Σ_j a_j sʲ ds = a0 u + a1 u²/2 + a2 u³/3 + a3 u⁴/4`: the optical depth per unit
/// `σ_t` (or the emission integral of one channel), by Horner's rule.
#[inline]
#[must_use]
pub fn integral(a: &[f64; 4], u: f64) -> f64 {
    u * (a[0] + u * (a[1] * 0.5 + u * (a[2] * (1.0 / 3.0) + u * (a[3] * 0.25))))
}

/// Most iterations of [`solve_integral`]. Bisection alone reaches `10⁻¹²·len` in 40.
const MAX_ITERATIONS: u32 = 100;

/// Relative tolerance of [`solve_integral`] on `u`.
const TOLERANCE: f64 = 1e-12;

/// The `u ∈ [0, len]` with [`integral`]`(a, u) = target`: where a free path ends inside a
/// piece whose density is the cubic `a` (METHOD.md §12).
///
/// Meant for `0 ≤ target < I(len)` with `ρ = Σ a_j uʲ ≥ 0` on `[0, len]`, so that
/// `I(u) = ∫₀ᵘ ρ` is non-decreasing and the root exists. Safeguarded Newton in f64:
/// - the bracket `[lo, hi]` always has `I(lo) < target < I(hi)` (initially `[0, len]`)
///   and shrinks to every iterate, by the sign of `I(u) − target`;
/// - the first iterate is the root of the linear interpolant, `u = len · target / I(len)`
///   (exact when ρ is constant);
/// - a Newton step `u − (I(u) − target)/ρ(u)` is taken when `ρ(u) > 0`, it lands inside
///   the open bracket and it is less than half the previous step (Newton converging only
///   linearly, as from the far side of a root where ρ vanishes, bisects instead); a
///   bisection step otherwise, so a cubic that rounding makes dip slightly below 0 (a zero
///   corner face), or a density vanishing like `u³` at an entry corner, only costs a few
///   bisections;
/// - bisection splits the bracket at its geometric mean `√(lo·hi)` when it spans more than
///   a factor 16 (`lo > 0`), at its midpoint otherwise: a target many decades below
///   `I(len)` (root near 0, where `I ∝ u^{k+1}` if ρ vanishes to order k) takes
///   `O(log decades)` steps, not one per halving;
/// - it stops when a step would move `u` by at most `10⁻¹² u` (so also `≤ 10⁻¹²·len`, §12's
///   criterion, and a root near 0 is found to the same relative precision as one
///   mid-cell), and returns the bracket's midpoint after 100 iterations (when noise in
///   `I` exceeds the tolerance). A Newton step that small is taken even from the bracket's
///   edge (where the last iterate always is).
///
/// When `target/I(len)` underflows to 0 (below 2⁻¹⁰⁷⁴) it returns 0 at once.
///
/// Outside the preconditions it still returns a value in `[0, len]`, and never panics: 0
/// for `target ≤ 0` (or NaN, or `len ≤ 0`), `len` for `target ≥ I(len)` (as a constant
/// piece clamps its free path).
#[must_use]
pub fn solve_integral(a: &[f64; 4], len: f64, target: f64) -> f64 {
    solve(a, len, target).u
}

/// What [`solve`] found.
#[derive(Clone, Copy, Debug)]
struct Root {
    /// The root, in `[0, len]`.
    u: f64,
    /// Evaluations of `I(u) − target` it took (0 for the early returns).
    #[cfg_attr(not(test), allow(dead_code, reason = "measured by the tests"))]
    iterations: u32,
}

/// [`solve_integral`], counting its iterations.
fn solve(a: &[f64; 4], len: f64, target: f64) -> Root {
    let total = integral(a, len);
    // Written so that NaN (in target, len or a) takes the early returns
    if !(target > 0.0 && len > 0.0) {
        return Root { u: 0.0, iterations: 0 };
    }
    if target >= total || total.is_nan() {
        return Root { u: len, iterations: 0 };
    }
    let mut u = (len * (target / total)).min(len);
    if u == 0.0 {
        // target/I(len) underflowed: the path ends at the entry to far below 10⁻¹²·len
        return Root { u, iterations: 0 };
    }
    let (mut lo, mut hi) = (0.0f64, len);
    let mut last_step = len;
    for iterations in 1..=MAX_ITERATIONS {
        let g = integral(a, u) - target;
        if g < 0.0 {
            lo = u;
        } else if g > 0.0 {
            hi = u;
        } else {
            return Root { u, iterations };
        }
        let rho = eval(a, u);
        let step = -g / rho;
        if rho > 0.0 && step.abs() <= TOLERANCE * u {
            return Root { u: (u + step).max(lo).min(hi), iterations };
        }
        let newton = u + step;
        let next = if rho > 0.0 && newton > lo && newton < hi && step.abs() < 0.5 * last_step {
            newton
        } else if lo > 0.0 && hi > 16.0 * lo {
            lo.sqrt() * hi.sqrt()
        } else {
            0.5 * (lo + hi)
        };
        if (next - u).abs() <= TOLERANCE * next {
            return Root { u: next, iterations };
        }
        last_step = (next - u).abs();
        u = next;
    }
    Root { u: 0.5 * (lo + hi), iterations: MAX_ITERATIONS }
}

/// Linear interpolation `a + (b − a) t`, the form [`cubic_along`] expands (exact `a`
/// when `a == b`).
#[inline]
fn lerp(a: f64, b: f64, t: f64) -> f64 {
    a + (b - a) * t
}

/// The trilinear interpolant of the corner values `v` at cell-local coordinates `f`
/// (`f ∈ [0, 1]³`; corner bit 0 is +x, bit 1 +y, bit 2 +z): x, then y, then z, in the
/// order of [`cubic_along`], so `trilinear(v, f0)` is bit for bit `cubic_along(v, f0, d)[0]`,
/// and equal corners give exactly their value.
#[inline]
#[must_use]
pub fn trilinear(v: &[f64; 8], f: DVec3) -> f64 {
    let y0 = lerp(lerp(v[0], v[1], f.x), lerp(v[2], v[3], f.x), f.y);
    let y1 = lerp(lerp(v[4], v[5], f.x), lerp(v[6], v[7], f.x), f.y);
    lerp(y0, y1, f.z)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use plume_core::sampling::phase::sample_uniform_sphere;
    use plume_core::sampling::Sampler;

    /// A ray's piece in one dual cell: `f(u) = f0 + d u`, `u ∈ [0, len]`.
    pub struct CellRay {
        pub f0: DVec3,
        pub d: DVec3,
        pub len: f64,
    }

    /// Distance along `f0 + d u` to the boundary of `[0, 1]³` (`f0` inside).
    pub fn exit_length(f0: DVec3, d: DVec3) -> f64 {
        (0..3)
            .map(|k| match d[k] {
                x if x > 0.0 => (1.0 - f0[k]) / x,
                x if x < 0.0 => -f0[k] / x,
                _ => f64::INFINITY,
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// A random piece: a uniform direction over voxel sizes in `[0.3, 3]` per axis, from a
    /// point inside the cell or (half the time) on the face it enters through.
    pub fn random_ray(s: &mut Sampler) -> CellRay {
        let dir = sample_uniform_sphere([s.next_f64(), s.next_f64()]);
        let voxel = DVec3::new(
            0.3 + 2.7 * s.next_f64(),
            0.3 + 2.7 * s.next_f64(),
            0.3 + 2.7 * s.next_f64(),
        );
        let d = dir / voxel;
        let mut f0 = DVec3::new(s.next_f64(), s.next_f64(), s.next_f64());
        if s.next_f64() < 0.5 {
            let k = d.abs().max_position();
            f0[k] = if d[k] > 0.0 { 0.0 } else { 1.0 };
        }
        CellRay { f0, d, len: exit_length(f0, d) }
    }

    pub fn random_corners(s: &mut Sampler, lo: f64, hi: f64) -> [f64; 8] {
        std::array::from_fn(|_| lo + (hi - lo) * s.next_f64())
    }

    /// The cubic against the trilinear interpolant at 101 points of random pieces (and of
    /// the main diagonal), relative to the largest corner.
    /// `Σ_c v_c W_c(u)` (2-point Gauss–Legendre on the weights) is the integral of the
    /// cubic [`cubic_along`] gives, on random cells and rays, at the cell's exit and
    /// inside; the weights integrate to `u` and are 0 for corners a face ray never sees.
    #[test]
    fn integrated_weights_integrate_the_cubic() {
        let mut s = Sampler::new(0x7e6, 0, 0);
        let mut worst = 0.0f64;
        for _ in 0..2000 {
            let ray = random_ray(&mut s);
            let v = random_corners(&mut s, 0.0, 5.0);
            for u in [ray.len, ray.len * s.next_f64()] {
                let w = integrated_weights(ray.f0, ray.d, u);
                let exact = integral(&cubic_along(v, ray.f0, ray.d), u);
                worst = worst.max((dot(&v, &w) - exact).abs() / exact.abs().max(1e-300));
                assert!((w.iter().sum::<f64>() - u).abs() <= 1e-14 * u.max(1.0));
            }
        }
        println!("integrated weights against the cubic's integral: worst relative difference {worst:.2e}");
        assert!(worst <= 1e-12, "{worst}");
        // Along +x on the cell's low-y, low-z edge only corners 0 and 1 are read
        let w = integrated_weights(DVec3::ZERO, DVec3::X, 1.0);
        assert_eq!((w[0], w[1]), (0.5, 0.5));
        assert!(w[2..].iter().all(|&x| x == 0.0));
    }

    #[test]
    fn cubic_along_matches_trilinear() {
        let mut worst = 0.0f64;
        for k in 0..500 {
            let mut s = Sampler::new(0x7e1, k, 0);
            let v = random_corners(&mut s, -1.0, 2.0);
            let ray = if k == 0 {
                CellRay { f0: DVec3::ZERO, d: DVec3::ONE / 3f64.sqrt(), len: 3f64.sqrt() }
            } else {
                random_ray(&mut s)
            };
            let a = cubic_along(v, ray.f0, ray.d);
            let scale = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            assert_eq!(a[0].to_bits(), trilinear(&v, ray.f0).to_bits());
            for i in 0..=100 {
                let u = ray.len * f64::from(i) / 100.0;
                worst = worst.max((eval(&a, u) - trilinear(&v, ray.f0 + ray.d * u)).abs() / scale);
            }
        }
        println!("cubic_along vs trilinear: max error {worst:.2e} of the largest corner");
        assert!(worst <= 1e-12, "{worst}");
    }

    /// A density cubic on `[0, len]`.
    struct Case {
        name: &'static str,
        a: [f64; 4],
        len: f64,
    }

    /// Cubics whose density vanishes at an end (a zero face or corner), is zero along the
    /// ray, or dips below 0; scaled by 10⁻³⁰ and 10³⁰; targets from 0 to just below the
    /// total. The root stays in `[0, len]` and `I(u)` matches the target to 10⁻⁹ relative,
    /// plus the rounding floor of `I` (which matters only where a dipping cubic's terms
    /// cancel far above the target), in at most 50 iterations.
    #[test]
    fn solve_integral_is_robust() {
        let mut s = Sampler::new(0x7e2, 0, 0);
        let rest: [f64; 8] = random_corners(&mut s, 0.5, 2.0);
        let zero_low_x: [f64; 8] = std::array::from_fn(|c| if c & 1 == 0 { 0.0 } else { rest[c] });
        let only = |corner: usize| -> [f64; 8] {
            std::array::from_fn(|c| if c == corner { 1.0 } else { 0.0 })
        };
        let diagonal = DVec3::ONE / 3f64.sqrt();
        let cell = |name: &'static str, v: [f64; 8], f0: DVec3, d: DVec3| Case {
            name,
            a: cubic_along(v, f0, d),
            len: exit_length(f0, d).min(2.0),
        };
        let cases = [
            cell(
                "zero face at the entry",
                zero_low_x,
                DVec3::new(0.0, 0.3, 0.6),
                DVec3::new(0.8, 0.1, -0.3),
            ),
            cell(
                "zero face at the exit",
                zero_low_x,
                DVec3::new(1.0, 0.4, 0.2),
                DVec3::new(-0.9, 0.2, 0.3),
            ),
            cell(
                "along a zero face",
                zero_low_x,
                DVec3::new(0.0, 0.0, 0.5),
                DVec3::new(0.0, 1.0, 0.2),
            ),
            cell("u³ from an entry corner", only(7), DVec3::ZERO, diagonal),
            cell("(1 − u)³ to an exit corner", only(0), DVec3::ZERO, diagonal),
            cell("random corners", rest, DVec3::new(0.2, 0.0, 0.7), DVec3::new(0.3, 0.9, -0.2)),
            Case { name: "dips below 0", a: [-1e-14, 0.0, 3.0, 0.0], len: 1.0 },
        ];
        let (mut worst, mut most_iterations) = (0.0f64, 0);
        for Case { name, a, len } in cases {
            for scale in [1e-30, 1.0, 1e30] {
                let a = a.map(|x| x * scale);
                let total = integral(&a, len);
                let below_total =
                    if total > 0.0 { f64::from_bits(total.to_bits() - 1) } else { 0.0 };
                let targets = [
                    0.0,
                    1e-300,
                    total * 1e-15,
                    total * 1e-9,
                    total * 1e-3,
                    total * 0.5,
                    total * (1.0 - 1e-9),
                    total * (1.0 - 1e-15),
                    below_total,
                ];
                for target in targets {
                    let Root { u, iterations } = solve(&a, len, target);
                    assert!(
                        (0.0..=len).contains(&u),
                        "{name} ×{scale:e}, target {target:e}: u = {u} outside [0, {len}]"
                    );
                    most_iterations = most_iterations.max(iterations);
                    assert!(
                        iterations <= 50,
                        "{name} ×{scale:e}, target {target:e}: {iterations} iterations"
                    );
                    if target / total == 0.0 {
                        assert_eq!(
                            u, 0.0,
                            "{name} ×{scale:e}, target {target:e}: underflowing ratio"
                        );
                    } else if target > 0.0 && target < total {
                        // Plus the rounding floor of I at u: 10⁻¹⁴ of Σ |a_j| u^{j+1}/(j+1)
                        let floor = 1e-14 * integral(&a.map(f64::abs), u);
                        let residual = (integral(&a, u) - target).abs();
                        assert!(
                            residual <= 1e-9 * target + floor,
                            "{name} ×{scale:e}, target {target:e}: residual {residual:e}"
                        );
                        if floor < 1e-9 * target {
                            worst = worst.max(residual / target);
                        }
                    }
                }
            }
        }
        println!("solve_integral: max relative error of I(u) {worst:.2e} (where above the rounding floor), at most {most_iterations} iterations");
    }

    /// Iterations on random cells (corners in `[0, 2]`) for uniform targets: what a free
    /// path costs in the renderer.
    #[test]
    fn solve_integral_typical_cost() {
        let (mut sum, mut most, mut count) = (0u64, 0u32, 0u64);
        for k in 0..500 {
            let mut s = Sampler::new(0x7e6, k, 0);
            let ray = random_ray(&mut s);
            let a = cubic_along(random_corners(&mut s, 0.0, 2.0), ray.f0, ray.d);
            for _ in 0..20 {
                let target = integral(&a, ray.len) * s.next_f64();
                let root = solve(&a, ray.len, target);
                (sum, most, count) =
                    (sum + u64::from(root.iterations), most.max(root.iterations), count + 1);
            }
        }
        let mean = sum as f64 / count as f64;
        println!("solve_integral on random cells: {mean:.2} iterations on average, at most {most}");
        assert!(mean <= 6.0 && most <= 20, "{mean} {most}");
    }
}
