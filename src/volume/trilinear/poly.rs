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

/// `Σ a_j uʲ` by Horner's rule.
#[inline]
#[must_use]
pub fn eval(a: &[f64; 4], u: f64) -> f64 {
    ((a[3] * u + a[2]) * u + a[1]) * u + a[0]
}
