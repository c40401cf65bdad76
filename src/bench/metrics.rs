//! Image error metrics of `plume bench compare`, and the spread of a figure over runs.
//!
//! All metrics compare an estimate `x` with a reference `r`, both row-major RGBA; alpha is
//! ignored. With `N` pixels and channels `c ∈ {R, G, B}`:
//! - **RMSE** `= sqrt( (1/3N) Σ_p Σ_c (x_pc − r_pc)² )`, in the image's radiance units;
//! - **relMSE** (relative MSE, the convention of recent rendering papers, e.g. Müller et
//!   al. 2017, Rath et al. 2020): per pixel `e_p = (1/3) Σ_c (x_pc − r_pc)² / (r_pc² + ε)`;
//!   the `⌊τN⌋` largest `e_p` are dropped (`τ = 0.001`, "top 0.1 % trimmed", so that a
//!   handful of fireflies does not decide the figure) and the rest averaged. `ε` keeps
//!   black reference pixels finite; it is an absolute radiance², so it is stated beside
//!   every figure (default `1e-2`);
//! - **bias** `= mean(x) − mean(r)` over all pixels and channels: the error that does not
//!   average out. Its spread over seeds tells a real bias (mean ≫ std) from noise.
//!
//! Sums are in `f64` (STYLE.md §8).

use serde::Serialize;

/// Fraction of per-pixel relMSE values trimmed from the top.
pub const RELMSE_TRIM: f64 = 0.001;

/// Default ε of relMSE (radiance², absolute).
pub const RELMSE_EPSILON: f64 = 1e-2;

/// The three error figures of one image against a reference.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Errors {
    /// Root mean squared error over all RGB values.
    pub rmse: f64,
    /// Trimmed relative MSE ([`relmse`]).
    pub relmse: f64,
    /// `mean(x) − mean(ref)` over all RGB values.
    pub bias: f64,
}

impl Errors {
    /// All three figures of `x` against `reference` with the given relMSE `epsilon` and
    /// the standard trim [`RELMSE_TRIM`].
    ///
    /// # Panics
    /// If the images differ in size.
    #[must_use]
    pub fn of(x: &[[f32; 4]], reference: &[[f32; 4]], epsilon: f64) -> Errors {
        Errors {
            rmse: rmse(x, reference),
            relmse: relmse(x, reference, epsilon, RELMSE_TRIM),
            bias: bias(x, reference),
        }
    }
}

fn check(x: &[[f32; 4]], reference: &[[f32; 4]]) {
    assert_eq!(x.len(), reference.len(), "image and reference differ in size");
}

/// RMSE over all RGB values (alpha ignored).
///
/// # Panics
/// If the images differ in size.
#[must_use]
pub fn rmse(x: &[[f32; 4]], reference: &[[f32; 4]]) -> f64 {
    check(x, reference);
    if x.is_empty() {
        return 0.0;
    }
    let s: f64 = x
        .iter()
        .zip(reference)
        .flat_map(|(p, q)| (0..3).map(move |c| (f64::from(p[c]) - f64::from(q[c])).powi(2)))
        .sum();
    (s / (3 * x.len()) as f64).sqrt()
}

/// Relative MSE: per pixel the mean over RGB of `(x − r)²/(r² + ε)`, the largest
/// `⌊trim · N⌋` pixel values dropped, the rest averaged.
///
/// # Panics
/// If the images differ in size, or `trim` is not in `[0, 1)`.
#[must_use]
pub fn relmse(x: &[[f32; 4]], reference: &[[f32; 4]], epsilon: f64, trim: f64) -> f64 {
    check(x, reference);
    assert!((0.0..1.0).contains(&trim), "trim fraction {trim} not in [0, 1)");
    let mut e: Vec<f64> = x
        .iter()
        .zip(reference)
        .map(|(p, q)| {
            (0..3)
                .map(|c| {
                    let r = f64::from(q[c]);
                    (f64::from(p[c]) - r).powi(2) / (r * r + epsilon)
                })
                .sum::<f64>()
                / 3.0
        })
        .collect();
    let drop = (trim * e.len() as f64).floor() as usize;
    let keep = e.len() - drop;
    if keep == 0 {
        return 0.0;
    }
    if drop > 0 {
        e.select_nth_unstable_by(keep - 1, f64::total_cmp);
    }
    // Sum the kept values in a fixed order so the figure does not depend on selection order
    let mut kept = e[..keep].to_vec();
    kept.sort_by(f64::total_cmp);
    kept.iter().sum::<f64>() / keep as f64
}

/// Mean over all RGB values of `x` minus that of `reference`.
///
/// # Panics
/// If the images differ in size.
#[must_use]
pub fn bias(x: &[[f32; 4]], reference: &[[f32; 4]]) -> f64 {
    check(x, reference);
    mean_rgb(x) - mean_rgb(reference)
}

/// Mean over all RGB values of an image (0 for an empty image).
#[must_use]
pub fn mean_rgb(x: &[[f32; 4]]) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    x.iter().flat_map(|p| p[..3].iter().map(|v| f64::from(*v))).sum::<f64>() / (3 * x.len()) as f64
}

/// Mean and sample standard deviation of a figure over runs (seeds).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Spread {
    /// Mean over runs.
    pub mean: f64,
    /// Sample standard deviation (`n − 1` in the denominator; 0 for one run).
    pub std: f64,
    /// Number of runs.
    pub n: usize,
}

impl Spread {
    /// The spread of `values`.
    #[must_use]
    pub fn of(values: &[f64]) -> Spread {
        let n = values.len();
        if n == 0 {
            return Spread { mean: f64::NAN, std: f64::NAN, n };
        }
        let mean = values.iter().sum::<f64>() / n as f64;
        let std = if n > 1 {
            (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()
        } else {
            0.0
        };
        Spread { mean, std, n }
    }
}

impl std::fmt::Display for Spread {
    /// `mean ± std` with the given precision (`{:.3}`), or in `e` notation for tiny or huge
    /// values.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let p = f.precision().unwrap_or(3);
        let m = self.mean.abs().max(self.std);
        if m != 0.0 && !(1e-3..1e5).contains(&m) {
            write!(f, "{:.p$e} ± {:.1e}", self.mean, self.std)
        } else {
            write!(f, "{:.p$} ± {:.p$}", self.mean, self.std)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spread_is_mean_and_sample_std() {
        let s = Spread::of(&[1.0, 2.0, 3.0, 4.0]);
        assert_eq!(s.mean, 2.5);
        assert!((s.std - (5.0f64 / 3.0).sqrt()).abs() < 1e-15);
        assert_eq!(Spread::of(&[7.0]).std, 0.0);
        assert_eq!(format!("{:.2}", Spread::of(&[1.0, 3.0])), "2.00 ± 1.41");
    }
}
