//! Henyey–Greenstein phase function: evaluation, importance sampling and the uniform
//! sphere warp.
//!
//! All pdfs here are **per unit solid angle** (sr⁻¹). θ is the angle between the *old* and
//! the *new propagation* directions, so `g > 0` scatters forward (METHOD.md §5):
//!
//! ```text
//! p(cos θ) = (1 − g²) / (4π (1 + g² − 2g cos θ)^{3/2}),      ∫_{S²} p dω = 1.
//! ```
//!
//! **Sampling** inverts the cosine CDF. METHOD.md §5 writes it as
//! `cos θ = (1/2g)[1 + g² − ((1 − g²)/(1 − g + 2gξ))²]` with a uniform fallback for
//! `|g| < 10⁻³`, because the `1/(2g)` form cancels catastrophically as `g → 0`. We use the
//! algebraically identical form with the `1/g` divided out:
//!
//! ```text
//! a = 1 − g + 2gξ,    cos θ = [2ξ(1 + g²)(1 − g + gξ) − (1 − g)²] / a²,
//! ```
//!
//! which is well conditioned for every `|g| < 1` (at `g = 0` it *is* the uniform warp
//! `2ξ − 1`). So no isotropic switch is needed and the sampled density equals [`hg_pdf`]
//! for every `g`: the weight `p/pdf` is exactly 1, with no approximation near `g = 0`.
//! `cos θ` is clamped to `[−1, 1]`.
//!
//! **`|g| = 1`** is a Dirac delta (all light continues straight on for `g = 1`, reverses for
//! `g = −1`): [`sample_hg`] returns `±direction`, weight 1 and `pdf = +∞`, and [`hg_pdf`]
//! returns 0 (a delta has no density per unit solid angle, so another technique's
//! direction has zero probability under it). The integrator must treat such a lobe as a
//! delta: forward-only, MIS weight 1 (METHOD.md §8). `|g| > 1` is invalid and treated as
//! `±1` (debug builds assert).
//!
//! The tangent frame is the branchless orthonormal basis of Duff et al., *Building an
//! Orthonormal Basis, Revisited*, JCGT 6(1), 2017.

use std::f64::consts::PI;

use glam::DVec3;

/// `1/(4π)`: the uniform sphere density per unit solid angle.
pub const INV_FOUR_PI: f64 = 1.0 / (4.0 * PI);

/// A sampled scattering direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhaseSample {
    /// New propagation direction, world space, unit length.
    pub direction: DVec3,
    /// Density of `direction`, per unit solid angle (`+∞` for the delta lobe `|g| = 1`).
    pub pdf: f64,
    /// Phase function over pdf, `p/pdf`: exactly 1 for Henyey–Greenstein.
    pub weight: f64,
}

/// Henyey–Greenstein density per unit solid angle for the cosine of the angle between the
/// old and new propagation directions (`g > 0`: forward scattering).
///
/// Returns 0 for `|g| ≥ 1` (a delta lobe, see the module docs). `cos_theta` is clamped to
/// `[−1, 1]`.
#[inline]
#[must_use]
pub fn hg_pdf(g: f64, cos_theta: f64) -> f64 {
    debug_assert!(g.abs() <= 1.0, "HG asymmetry g = {g} outside [-1, 1]");
    if g.abs() >= 1.0 {
        return 0.0;
    }
    let c = cos_theta.clamp(-1.0, 1.0);
    // 1 + g² − 2gc as a sum of two non-negative terms (no cancellation near the peak).
    let denom = if g >= 0.0 {
        (1.0 - g) * (1.0 - g) + 2.0 * g * (1.0 - c)
    } else {
        (1.0 + g) * (1.0 + g) - 2.0 * g * (1.0 + c)
    };
    INV_FOUR_PI * (1.0 - g * g) / (denom * denom.sqrt())
}

/// Sample a new propagation direction from Henyey–Greenstein around `direction` (the
/// current propagation direction, unit length) with uniforms `u ∈ [0, 1)²`.
///
/// `u[0]` picks `cos θ`, `u[1]` the azimuth. See the module docs for the inversion used and
/// for `|g| = 1`. Never returns NaN for finite `g ∈ [−1, 1]`, unit `direction` and
/// `u ∈ [0, 1]²`.
#[must_use]
pub fn sample_hg(g: f64, direction: DVec3, u: [f64; 2]) -> PhaseSample {
    debug_assert!(g.abs() <= 1.0, "HG asymmetry g = {g} outside [-1, 1]");
    if g.abs() >= 1.0 {
        // Delta lobe: straight on (g = 1) or straight back (g = −1).
        return PhaseSample { direction: direction * g.signum(), pdf: f64::INFINITY, weight: 1.0 };
    }
    // Invert the cosine CDF (1/g divided out, see module docs)
    let xi = u[0];
    let a = 1.0 - g + 2.0 * g * xi;
    let cos_theta = ((2.0 * xi * (1.0 + g * g) * (1.0 - g + g * xi) - (1.0 - g) * (1.0 - g))
        / (a * a))
        .clamp(-1.0, 1.0);
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let phi = 2.0 * PI * u[1];
    let (t1, t2) = orthonormal_basis(direction);
    let new = (t1 * (sin_theta * phi.cos()) + t2 * (sin_theta * phi.sin()) + direction * cos_theta)
        .normalize();
    PhaseSample { direction: new, pdf: hg_pdf(g, cos_theta), weight: 1.0 }
}

/// Uniform direction on the unit sphere from `u ∈ [0, 1)²`; density [`INV_FOUR_PI`] per unit
/// solid angle. `z = 1 − 2u₀`, azimuth `2πu₁`.
#[inline]
#[must_use]
pub fn sample_uniform_sphere(u: [f64; 2]) -> DVec3 {
    let z = 1.0 - 2.0 * u[0];
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u[1];
    DVec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Two unit vectors `(t1, t2)` such that `(t1, t2, n)` is a right-handed orthonormal basis,
/// for unit `n`. Branchless (Duff et al. 2017): continuous except across `n.z = 0`, exact
/// for `n = ±z`, and free of the `1/(1 + n.z)` blow-up of Frisvad's original (the sign is
/// taken from `n.z`, so `-0.0` is handled too).
#[inline]
#[must_use]
pub fn orthonormal_basis(n: DVec3) -> (DVec3, DVec3) {
    let sign = 1.0f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        DVec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    const ONE_MINUS_EPS: f64 = 1.0 - f64::EPSILON / 2.0;

    #[test]
    fn basis_is_orthonormal_for_axes_and_signed_zeros() {
        for n in [
            DVec3::X,
            DVec3::Y,
            DVec3::Z,
            -DVec3::Z,
            DVec3::new(0.0, 0.0, -0.0),
            DVec3::new(0.6, 0.0, -0.8),
            DVec3::new(0.0, 1.0, -0.0),
        ] {
            let n = if n.length() == 0.0 { DVec3::Z } else { n };
            let (t1, t2) = orthonormal_basis(n);
            assert!((t1.length() - 1.0).abs() < 1e-15 && (t2.length() - 1.0).abs() < 1e-15, "{n}");
            assert!(
                t1.dot(t2).abs() < 1e-15 && t1.dot(n).abs() < 1e-15 && t2.dot(n).abs() < 1e-15,
                "{n}"
            );
            assert!((t1.cross(t2) - n).length() < 1e-15, "right-handed for {n}");
        }
    }

    #[test]
    fn hg_extremes_are_finite_unit_and_weight_one() {
        let dir = DVec3::new(0.0, -0.0, -1.0);
        for g in [-1.0, -0.999, -1e-9, 0.0, 1e-9, 0.5, 0.999, 1.0] {
            for u0 in [0.0, 1e-300, 0.5, ONE_MINUS_EPS, 1.0] {
                for u1 in [0.0, ONE_MINUS_EPS] {
                    let s = sample_hg(g, dir, [u0, u1]);
                    assert!(
                        s.direction.is_finite() && (s.direction.length() - 1.0).abs() < 1e-12,
                        "g={g} u0={u0}: {s:?}"
                    );
                    assert!(!s.pdf.is_nan() && s.pdf > 0.0, "g={g} u0={u0}: {s:?}");
                    assert_eq!(s.weight, 1.0);
                    if g.abs() < 1.0 {
                        let again = hg_pdf(g, s.direction.dot(dir));
                        assert!(
                            (s.pdf - again).abs() <= 1e-6 * s.pdf,
                            "g={g} u0={u0}: {} vs {again}",
                            s.pdf
                        );
                    }
                }
            }
        }
        // The delta lobe: straight on / straight back.
        assert_eq!(sample_hg(1.0, dir, [0.3, 0.3]).direction, dir);
        assert_eq!(sample_hg(-1.0, dir, [0.3, 0.3]).direction, -dir);
        assert_eq!(hg_pdf(1.0, 1.0), 0.0);
    }

    #[test]
    fn hg_inversion_is_monotone_and_hits_the_ends() {
        for g in [-0.999, -0.5, 0.0, 0.3, 0.999] {
            let dir = DVec3::Z;
            let c0 = sample_hg(g, dir, [0.0, 0.0]).direction.z;
            let c1 = sample_hg(g, dir, [ONE_MINUS_EPS, 0.0]).direction.z;
            assert!((c0 + 1.0).abs() < 1e-7 && (c1 - 1.0).abs() < 1e-7, "g={g}: {c0} {c1}");
            let mut last = -2.0;
            for k in 0..=1000 {
                let c = sample_hg(g, dir, [f64::from(k) / 1000.0, 0.0]).direction.z;
                assert!(c >= last - 1e-15, "g={g} not monotone at {k}");
                last = c;
            }
        }
    }

    #[test]
    fn uniform_sphere_ends() {
        assert_eq!(sample_uniform_sphere([0.0, 0.0]), DVec3::Z);
        let s = sample_uniform_sphere([ONE_MINUS_EPS, ONE_MINUS_EPS]);
        assert!((s.length() - 1.0).abs() < 1e-15 && s.z < -0.999_999);
    }
}
