//! How noisy a render still is, from its own samples: per-pixel standard errors, the
//! image's estimated relative RMSE, and the stopping rule of adaptive sampling.
//!
//! **Standard error.** A pixel holds `n` samples with exact sums `S₁ = Σ x` and
//! `S₂ = Σ x²` per colour channel (`film::Moments`). Its mean `x̄ = S₁/n` has the estimated
//! variance
//!
//! ```text
//! σ̂²(x̄) = (S₂ − S₁²/n) / (n (n − 1))
//! ```
//!
//! the unbiased sample variance over `n`, for independent samples. plume's samples are
//! Owen-scrambled Sobol points, whose mean is at most as noisy and usually less (the
//! gain is largest for pixels whose light depends on few dimensions, e.g. emission seen
//! directly), so the estimate leans to the safe side; docs/adaptive.md measures it against
//! converged references. A pixel with fewer than two samples has no estimate (infinite).
//!
//! **Relative error with a floor.** Per pixel, over the colour channels `c`,
//!
//! ```text
//! e² = (1/3) Σ_c σ̂²_c / (x̄²_c + ε),    ε = floor²
//! ```
//!
//! the error relative to the pixel's value, and relative to the floor (a radiance) where
//! the pixel is darker: the per-pixel form of the relative MSE of `plume bench compare`,
//! with the pixel's own mean for the unknown reference and the same `ε` (floor 0.1).
//! The image's estimated **relRMSE** is `sqrt(mean e²)` over the pixels whose alpha is
//! above 0.01 (where there is something to see).
//!
//! **Adaptive sampling.** A pixel stops once `e ≤ T` (`render.noise_threshold`). The test
//! is taken only at fixed sample counts, the checkpoints `c₀ = min_spp`,
//! `c_{k+1} = c_k + max(1, ⌊c_k/8⌋)`, from the pixel's own sums of samples `0..c_k`: a
//! pure function of the pixel's samples, so the image is the same for any thread count,
//! pass size, tiling or interruption. Checkpoints every eighth of the samples so far
//! cost a pixel at most 12.5 % more samples than it needed.

use crate::film::{Moments, FIXED_POINT_BITS};

/// Alpha above which a pixel counts in the image's error estimate.
pub const ALPHA_MIN: f32 = 0.01;

/// The default noise floor (radiance): `ε = 0.01`, the relative MSE's default in
/// `plume bench compare`.
pub const DEFAULT_FLOOR: f64 = 0.1;

/// 2^−F as `f64`.
fn unit() -> f64 {
    (-f64::from(FIXED_POINT_BITS)).exp2()
}

/// The estimated standard error of a pixel's mean, per colour channel, from its RGB(A)
/// sums and moments (infinite with fewer than two samples or a saturated square).
#[must_use]
pub fn standard_error(sums: &[i128; 4], moments: &Moments) -> [f64; 3] {
    let n = moments.count;
    std::array::from_fn(|c| {
        if n < 2 || moments.squares[c] == i128::MAX {
            return f64::INFINITY;
        }
        let n = n as f64;
        let s1 = sums[c] as f64 * unit();
        let s2 = moments.squares[c] as f64 * unit();
        ((s2 - s1 * s1 / n).max(0.0) / (n * (n - 1.0))).sqrt()
    })
}

/// The pixel's mean colour from its sums and count.
fn mean(sums: &[i128; 4], moments: &Moments) -> [f64; 3] {
    let n = moments.count.max(1) as f64;
    std::array::from_fn(|c| sums[c] as f64 * unit() / n)
}

/// The squared relative error `e²` of a pixel (module docs), with `epsilon = floor²`.
#[must_use]
pub fn relative_variance(sums: &[i128; 4], moments: &Moments, epsilon: f64) -> f64 {
    let se = standard_error(sums, moments);
    let m = mean(sums, moments);
    (0..3).map(|c| se[c] * se[c] / (m[c] * m[c] + epsilon)).sum::<f64>() / 3.0
}

/// What a render says of its own remaining error (stats JSON, EXR header).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ErrorEstimate {
    /// Estimated relative RMSE of the image (module docs); `None` when no pixel with
    /// alpha above [`ALPHA_MIN`] has two samples.
    pub rel_rmse: Option<f64>,
    /// Pixels it is taken over (alpha above [`ALPHA_MIN`]).
    pub pixels: u64,
    /// The noise floor (radiance).
    pub floor: f64,
}

/// The image's error estimate from its sums and moments (row-major, the same pixels).
///
/// # Panics
/// If the slices differ in length.
#[must_use]
pub fn estimate(sums: &[[i128; 4]], moments: &[Moments], floor: f64) -> ErrorEstimate {
    assert_eq!(sums.len(), moments.len(), "one moment per pixel");
    let epsilon = floor * floor;
    let mut total = 0.0;
    let mut pixels = 0u64;
    let mut finite = true;
    for (s, m) in sums.iter().zip(moments) {
        let alpha = crate::film::pixel_value(s[3], m.count);
        if alpha > ALPHA_MIN {
            let e2 = relative_variance(s, m, epsilon);
            finite &= e2.is_finite();
            total += e2;
            pixels += 1;
        }
    }
    let rel_rmse = (pixels > 0 && finite).then(|| (total / pixels as f64).sqrt());
    ErrorEstimate { rel_rmse, pixels, floor }
}

/// How many pixels hold each sample count.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct SppCount {
    /// Samples per pixel.
    pub spp: u64,
    /// Pixels holding that many.
    pub pixels: u64,
}

/// The spp histogram: each sample count held by some pixel, in increasing order.
#[must_use]
pub fn spp_histogram(moments: &[Moments]) -> Vec<SppCount> {
    let mut counts = std::collections::BTreeMap::<u64, u64>::new();
    for m in moments {
        *counts.entry(m.count).or_default() += 1;
    }
    counts.into_iter().map(|(spp, pixels)| SppCount { spp, pixels }).collect()
}

/// Adaptive sampling's settings, validated (`render.noise_threshold`, `render.min_spp`,
/// `render.noise_floor`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Adaptive {
    /// A pixel stops once its relative error `e` is at most this.
    pub threshold: f64,
    /// The first checkpoint: every pixel takes at least this many samples (≥ 2).
    pub min_spp: u64,
    /// The noise floor (radiance).
    pub floor: f64,
}

impl Adaptive {
    /// The checkpoint after checkpoint `c`.
    #[must_use]
    #[inline]
    pub fn after(c: u64) -> u64 {
        c + (c / 8).max(1)
    }

    /// The first checkpoint at or after sample count `n`.
    #[must_use]
    pub fn checkpoint_from(&self, n: u64) -> u64 {
        let mut c = self.min_spp;
        while c < n {
            c = Self::after(c);
        }
        c
    }

    /// Whether a pixel with these sums and moments has converged (`e ≤ threshold`);
    /// asked only at checkpoints.
    #[must_use]
    pub fn converged(&self, sums: &[i128; 4], moments: &Moments) -> bool {
        relative_variance(sums, moments, self.floor * self.floor) <= self.threshold * self.threshold
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::film::to_fixed;

    fn pixel(values: &[[f64; 4]]) -> ([i128; 4], Moments) {
        let mut sums = [0i128; 4];
        let mut m = Moments::default();
        for v in values {
            for (s, x) in sums.iter_mut().zip(v) {
                *s += to_fixed(*x).unwrap();
            }
            for (s, x) in m.squares.iter_mut().zip(v) {
                *s += to_fixed(x * x).unwrap();
            }
            m.count += 1;
        }
        (sums, m)
    }

    /// The standard error is the textbook one: sample variance over n.
    #[test]
    fn standard_error_is_the_sample_variance_over_n() {
        let xs = [1.0, 2.0, 4.0, 7.0];
        let (s, m) = pixel(&xs.map(|x| [x, 2.0 * x, 0.5, 1.0]));
        let mean = 3.5;
        let var = xs.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / 3.0;
        let se = standard_error(&s, &m);
        assert!((se[0] - (var / 4.0).sqrt()).abs() < 1e-12, "{se:?}");
        assert!((se[1] - 2.0 * (var / 4.0).sqrt()).abs() < 1e-12);
        assert_eq!(se[2], 0.0, "a constant channel has no error");
        let (s1, m1) = pixel(&[[1.0, 1.0, 1.0, 1.0]]);
        assert!(standard_error(&s1, &m1)[0].is_infinite(), "one sample has no estimate");
    }

    /// Relative to the value where it is bright, to the floor where it is dark.
    #[test]
    fn relative_error_uses_the_floor_for_dark_pixels() {
        let bright = pixel(&[[99.0; 4], [101.0; 4]]);
        let e2 = relative_variance(&bright.0, &bright.1, 0.01);
        assert!((e2 - 1.0 / (100.0f64.powi(2) + 0.01)).abs() < 1e-12, "{e2}");
        let dark = pixel(&[[0.0; 4], [0.002; 4]]);
        let e2 = relative_variance(&dark.0, &dark.1, 0.01);
        assert!((e2 - 1e-6 / (1e-6 + 0.01)).abs() < 1e-12, "{e2}");
    }

    /// The checkpoints grow by an eighth, from min_spp.
    #[test]
    fn checkpoints_grow_by_an_eighth() {
        let a = Adaptive { threshold: 0.1, min_spp: 4, floor: 0.1 };
        let mut c = a.min_spp;
        let mut seen = vec![c];
        while c < 40 {
            c = Adaptive::after(c);
            seen.push(c);
        }
        assert_eq!(
            seen,
            [4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 18, 20, 22, 24, 27, 30, 33, 37, 41]
        );
        assert_eq!(a.checkpoint_from(0), 4);
        assert_eq!(a.checkpoint_from(17), 18);
        assert_eq!(a.checkpoint_from(18), 18);
    }

    /// The histogram counts pixels per sample count; the image estimate averages e² over
    /// the pixels with alpha.
    #[test]
    fn histogram_and_image_estimate() {
        let a = pixel(&[[1.0, 1.0, 1.0, 1.0], [3.0, 3.0, 3.0, 1.0]]);
        let empty = pixel(&[[0.0; 4], [0.0; 4], [0.0; 4]]);
        let sums = [a.0, empty.0, a.0];
        let moments = [a.1, empty.1, a.1];
        assert_eq!(
            spp_histogram(&moments),
            [SppCount { spp: 2, pixels: 2 }, SppCount { spp: 3, pixels: 1 }]
        );
        let est = estimate(&sums, &moments, 0.1);
        assert_eq!(est.pixels, 2);
        let e2 = relative_variance(&a.0, &a.1, 0.01);
        assert!((est.rel_rmse.unwrap() - e2.sqrt()).abs() < 1e-15);
    }
}
