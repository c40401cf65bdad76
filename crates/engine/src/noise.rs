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
//! **Pooled over neighbours.** One pixel's `σ̂²` is a noisy figure of its own: where the
//! light is heavy-tailed (rare, bright scattered light from a fireball), a pixel that has
//! not yet drawn the tail has both a low mean and a low `σ̂²`. The estimate a render uses
//! is therefore pooled: for pixel `p` with `n_p` samples, over its 3×3 neighbourhood
//! `N(p)`, the mean per-sample variance `s²_q = n_q σ̂²_q` (what neighbours share; their
//! counts differ under adaptive sampling) over the pixel's own count, and the mean value:
//!
//! ```text
//! σ̄²(p) = η_B mean_{q ∈ N(p)} s²_q / n_p,    x̃(p) = mean_{q ∈ N(p)} x̄_q
//! ```
//!
//! where `N(p)` holds the neighbours inside the image-aligned block of
//! [`crate::film::TILE`]² pixels that holds `p` (a film tile, so that a tile can decide
//! alone) with two samples or more. A pixel with fewer than two samples has no estimate
//! (infinite). docs/adaptive.md measures what pooling does against converged references.
//!
//! **The sampler's gain.** `σ̂²` is the error of independent samples. plume's Owen-scrambled
//! Sobol points do better (on the self-lit shared cloud, 3× less RMSE at 256 spp). The
//! first `2^k` samples of a pixel are a net, and so is each level `[2^ℓ, 2^{ℓ+1})`
//! (`moments`): two halves `A`, `B` of `h` samples that are both nets give
//! `net = (Ā − B̄)² h / 2`, an estimate of the per-sample variance `s²` as the nets
//! actually vary (for independent samples its mean is `s²`). Per block (below) the gain
//! is `η = min(1, Σ net / Σ s²)` over the pixels with halves and their channels, and the
//! estimate is `η σ̂²`. This assumes the sampler's gain is a factor that does not change
//! from `h` samples to `n` (measured: about constant from 64 to 1024 spp on the shared
//! files), and is taken per block because one pixel's halves are one number each.
//!
//! **Relative error with a floor.** Per pixel, over the colour channels `c`,
//!
//! ```text
//! e² = (1/3) Σ_c σ̄²_c / (x̃²_c + ε),    ε = floor²
//! ```
//!
//! the error relative to the pixel's value, and relative to the floor (a radiance) where
//! the pixel is darker: the per-pixel form of the relative MSE of `plume bench compare`,
//! with the pooled mean for the unknown reference and the same `ε` (floor 0.1).
//! The image's estimated **relRMSE** is `sqrt(mean e²)` over the pixels whose alpha is
//! above 0.01 (where there is something to see).
//!
//! **Adaptive sampling.** A pixel stops once `e ≤ T` (`render.noise_threshold`). The test
//! is taken only at fixed sample counts, the checkpoints `c₀ = min_spp`,
//! `c_{k+1} = 2 c_k`, for every pixel of a film tile together, from the
//! tile's sums with every pixel at that count or stopped before it: a pure function of the
//! samples, so the image is the same for any thread count, pass size, tiling that does
//! not cut a block, or interruption. Doubling keeps what the Sobol sampler gives: the first
//! `2^m` samples of a pixel are a stratified net, and a pixel stopped between nets would
//! lose that (measured: stopping every eighth of the samples cost 1.4–2× the CPU for the
//! same error on the shared cloud, smoke and explosion).

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

/// One pixel's mean colour and squared standard error per channel (infinite with fewer
/// than two samples), and what its two halves say of the sampler's gain.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PixelNoise {
    /// The pixel's mean `x̄` per colour channel.
    pub mean: [f64; 3],
    /// `σ̂²(x̄)` per colour channel, for independent samples.
    pub se2: [f64; 3],
    /// Per channel, the per-sample variance `s² = n σ̂²` (0 without an estimate).
    pub s2: [f64; 3],
    /// Samples the pixel holds.
    pub n: f64,
    /// Per channel, `(Ā − B̄)² h / 2` from the pixel's two halves of `h` samples
    /// (`moments`): the same `s²` as the nets actually vary; `None` without halves.
    pub net: Option<[f64; 3]>,
}

impl PixelNoise {
    /// A pixel's noise from its RGB(A) sums and moments.
    #[must_use]
    pub fn of(sums: &[i128; 4], moments: &Moments) -> PixelNoise {
        let n = moments.count.max(1) as f64;
        let se2 = standard_error(sums, moments).map(|s| s * s);
        let finite = se2.iter().all(|v| v.is_finite());
        let s2 = if finite { se2.map(|v| v * n) } else { [0.0; 3] };
        let net = match moments.halves([sums[0], sums[1], sums[2]]) {
            Some((a, b, h)) if finite => {
                let h = h as f64;
                Some(std::array::from_fn(|c| {
                    let d = (a[c] as f64 - b[c] as f64) * unit() / h;
                    d * d * h / 2.0
                }))
            }
            _ => None,
        };
        let mean = std::array::from_fn(|c| sums[c] as f64 * unit() / n);
        PixelNoise { mean, se2, s2, n: moments.count as f64, net }
    }

    /// `e²` of these (pooled) figures, with `epsilon = floor²` (module docs).
    #[must_use]
    pub fn relative_variance(&self, epsilon: f64) -> f64 {
        (0..3).map(|c| self.se2[c] / (self.mean[c] * self.mean[c] + epsilon)).sum::<f64>() / 3.0
    }
}

/// The pixels of a rectangle of the image (a crop or a film tile), row-major, with their
/// noise and their blocks' sampler gains: what pooling reads.
#[derive(Clone, Debug)]
pub struct NoiseGrid<'a> {
    /// The rectangle, in image coordinates.
    rect: crate::film::Crop,
    /// One per pixel of `rect`, row-major.
    pixels: &'a [PixelNoise],
    /// Per block of `rect` (row-major over the blocks it touches), the gain `η`.
    gains: Vec<f64>,
}

impl<'a> NoiseGrid<'a> {
    /// The grid of `pixels` (row-major over `rect`), with each block's gain
    /// `η = min(1, Σ net / Σ s²)` over its pixels with halves and their channels (module
    /// docs; 1 where no pixel has halves or there is no spread at all).
    ///
    /// # Panics
    /// If `pixels` does not have one entry per pixel of `rect`.
    #[must_use]
    pub fn new(rect: crate::film::Crop, pixels: &'a [PixelNoise]) -> NoiseGrid<'a> {
        assert_eq!(pixels.len() as u64, rect.area(), "one entry per pixel");
        let (bx0, by0) = (rect.x0 / crate::film::TILE, rect.y0 / crate::film::TILE);
        let bw = ((rect.x1 - 1) / crate::film::TILE - bx0 + 1) as usize;
        let bh = ((rect.y1 - 1) / crate::film::TILE - by0 + 1) as usize;
        let mut sums = vec![(0.0f64, 0.0f64); bw * bh];
        for (i, p) in pixels.iter().enumerate() {
            let (x, y) = (rect.x0 + i as u32 % rect.width(), rect.y0 + i as u32 / rect.width());
            let b = ((y / crate::film::TILE - by0) as usize) * bw
                + (x / crate::film::TILE - bx0) as usize;
            if let Some(net) = p.net {
                sums[b].0 += net.iter().sum::<f64>();
                sums[b].1 += p.s2.iter().sum::<f64>();
            }
        }
        let gains = sums
            .iter()
            .map(|&(net, s2)| if s2 > 0.0 { (net / s2).min(1.0) } else { 1.0 })
            .collect();
        NoiseGrid { rect, pixels, gains }
    }

    /// The gain `η` of the block holding pixel `(x, y)`.
    #[must_use]
    pub fn gain(&self, x: u32, y: u32) -> f64 {
        let (bx0, by0) = (self.rect.x0 / crate::film::TILE, self.rect.y0 / crate::film::TILE);
        let bw = (self.rect.x1 - 1) / crate::film::TILE - bx0 + 1;
        self.gains[((y / crate::film::TILE - by0) * bw + (x / crate::film::TILE - bx0)) as usize]
    }

    /// The pooled mean and `σ̄²` of pixel `(x, y)` (image coordinates, inside the grid):
    /// the averages over its 3×3 neighbours in the grid and in its block with an estimate
    /// (module docs); infinite when the pixel itself has none.
    #[must_use]
    pub fn pooled(&self, x: u32, y: u32) -> PixelNoise {
        let r = self.rect;
        let at = |x: u32, y: u32| &self.pixels[((y - r.y0) * r.width() + (x - r.x0)) as usize];
        let own = at(x, y);
        if own.se2.iter().any(|v| !v.is_finite()) {
            return *own;
        }
        let block = |v: u32| v / crate::film::TILE;
        let mut sum = PixelNoise::default();
        let mut count = 0.0;
        for qy in y.saturating_sub(1)..=y + 1 {
            for qx in x.saturating_sub(1)..=x + 1 {
                let inside = qx >= r.x0 && qx < r.x1 && qy >= r.y0 && qy < r.y1;
                if !inside || block(qx) != block(x) || block(qy) != block(y) {
                    continue;
                }
                let q = at(qx, qy);
                if q.se2.iter().all(|v| v.is_finite()) {
                    for c in 0..3 {
                        sum.mean[c] += q.mean[c];
                        sum.s2[c] += q.s2[c];
                    }
                    count += 1.0;
                }
            }
        }
        // The per-sample variance is what neighbours share; the pixel's own count divides it
        let gain = self.gain(x, y);
        PixelNoise {
            mean: sum.mean.map(|v| v / count),
            se2: sum.s2.map(|v| gain * v / count / own.n),
            ..PixelNoise::default()
        }
    }
}

/// Every pixel's noise from sums and moments (row-major, the same pixels).
#[must_use]
pub fn pixel_noise(sums: &[[i128; 4]], moments: &[Moments]) -> Vec<PixelNoise> {
    sums.iter().zip(moments).map(|(s, m)| PixelNoise::of(s, m)).collect()
}

/// The pooled standard error `σ̄` of every pixel of `crop` (row-major sums and moments
/// over it), per colour channel: the `error` layer.
///
/// # Panics
/// If the slices do not have one entry per pixel of `crop`.
#[must_use]
pub fn pooled_standard_errors(
    sums: &[[i128; 4]],
    moments: &[Moments],
    crop: crate::film::Crop,
) -> Vec<[f64; 3]> {
    assert_eq!(sums.len() as u64, crop.area(), "one sum per pixel");
    let pixels = pixel_noise(sums, moments);
    let grid = NoiseGrid::new(crop, &pixels);
    let mut out = Vec::with_capacity(pixels.len());
    for y in crop.y0..crop.y1 {
        for x in crop.x0..crop.x1 {
            out.push(grid.pooled(x, y).se2.map(f64::sqrt));
        }
    }
    out
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

/// The image's error estimate from its sums and moments (row-major over `crop`).
///
/// # Panics
/// If the slices do not have one entry per pixel of `crop`.
#[must_use]
pub fn estimate(
    sums: &[[i128; 4]],
    moments: &[Moments],
    crop: crate::film::Crop,
    floor: f64,
) -> ErrorEstimate {
    assert_eq!(sums.len() as u64, crop.area(), "one sum per pixel");
    assert_eq!(sums.len(), moments.len(), "one moment per pixel");
    let noise = pixel_noise(sums, moments);
    let grid = NoiseGrid::new(crop, &noise);
    let epsilon = floor * floor;
    let mut total = 0.0;
    let mut pixels = 0u64;
    let mut finite = true;
    let coordinates = (crop.y0..crop.y1).flat_map(|y| (crop.x0..crop.x1).map(move |x| (x, y)));
    for ((s, m), (x, y)) in sums.iter().zip(moments).zip(coordinates) {
        let alpha = crate::film::pixel_value(s[3], m.count);
        if alpha > ALPHA_MIN {
            let e2 = grid.pooled(x, y).relative_variance(epsilon);
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
        2 * c
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

    /// Whether the first checkpoint at or after `n` is `n`.
    #[must_use]
    pub fn is_checkpoint(&self, n: u64) -> bool {
        n >= self.min_spp && self.checkpoint_from(n) == n
    }

    /// Whether pixel `(x, y)` of `grid` has converged (`e ≤ threshold` with the pooled
    /// figures); asked only at checkpoints.
    #[must_use]
    pub fn converged(&self, grid: &NoiseGrid<'_>, x: u32, y: u32) -> bool {
        grid.pooled(x, y).relative_variance(self.floor * self.floor)
            <= self.threshold * self.threshold
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
        let e2 = PixelNoise::of(&bright.0, &bright.1).relative_variance(0.01);
        assert!((e2 - 1.0 / (100.0f64.powi(2) + 0.01)).abs() < 1e-12, "{e2}");
        let dark = pixel(&[[0.0; 4], [0.002; 4]]);
        let e2 = PixelNoise::of(&dark.0, &dark.1).relative_variance(0.01);
        assert!((e2 - 1e-6 / (1e-6 + 0.01)).abs() < 1e-12, "{e2}");
    }

    /// The gain of a block is Σ net / Σ s² over its pixels with halves, at most 1; a block
    /// without halves keeps the independent-sample estimate.
    #[test]
    fn the_gain_scales_the_estimate_per_block() {
        use crate::film::Crop;
        let rect = Crop { x0: 0, y0: 0, x1: 32, y1: 1 };
        let pixels: Vec<PixelNoise> = (0..32)
            .map(|x| PixelNoise {
                mean: [1.0; 3],
                se2: [0.01; 3],
                s2: [1.0; 3],
                n: 100.0,
                // The first block's nets vary a quarter as much; the second has none
                net: (x < 16).then_some([0.25; 3]),
            })
            .collect();
        let grid = NoiseGrid::new(rect, &pixels);
        assert_eq!((grid.gain(3, 0), grid.gain(20, 0)), (0.25, 1.0));
        assert!((grid.pooled(3, 0).se2[0] - 0.0025).abs() < 1e-15);
        assert!((grid.pooled(20, 0).se2[0] - 0.01).abs() < 1e-15);
    }

    /// Pooling averages the 3×3 neighbours inside the grid and the pixel's block, leaves
    /// out neighbours without an estimate, and keeps a pixel without one infinite.
    #[test]
    fn pooling_stays_inside_the_block_and_the_grid() {
        use crate::film::Crop;
        // A 20×2 strip from x = 6: columns 6..16 are one block, 16..26 the next
        let rect = Crop { x0: 6, y0: 0, x1: 26, y1: 2 };
        let mut pixels: Vec<PixelNoise> = (0..40)
            .map(|i| {
                let v = f64::from(6 + i % 20);
                PixelNoise { mean: [v; 3], se2: [v; 3], s2: [v; 3], n: 1.0, net: None }
            })
            .collect();
        pixels[20 + 1].se2 = [f64::INFINITY; 3]; // (7, 1): one sample
        let grid = NoiseGrid::new(rect, &pixels);
        // (15, 0): neighbours x = 14, 15 (16 is the next block), y = 0, 1
        assert_eq!(grid.pooled(15, 0).mean, [14.5; 3]);
        // (6, 0): x = 6, 7 at y = 0 and x = 6 at y = 1 ((7, 1) has no estimate)
        let p = grid.pooled(6, 0);
        assert!((p.se2[0] - (6.0 + 7.0 + 6.0) / 3.0).abs() < 1e-12, "{p:?}");
        assert!(grid.pooled(7, 1).se2[0].is_infinite());
    }

    /// The checkpoints double from min_spp.
    #[test]
    fn checkpoints_double() {
        let a = Adaptive { threshold: 0.1, min_spp: 4, floor: 0.1 };
        let mut c = a.min_spp;
        let mut seen = vec![c];
        while c < 40 {
            c = Adaptive::after(c);
            seen.push(c);
        }
        assert_eq!(seen, [4, 8, 16, 32, 64]);
        assert_eq!(a.checkpoint_from(0), 4);
        assert_eq!(a.checkpoint_from(17), 32);
        assert!(a.is_checkpoint(16) && !a.is_checkpoint(17) && !a.is_checkpoint(2));
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
        // Three pixels in a row: the empty one between the two has no alpha
        let crop = crate::film::Crop { x0: 0, y0: 0, x1: 3, y1: 1 };
        let est = estimate(&sums, &moments, crop, 0.1);
        assert_eq!(est.pixels, 2);
        let noise = pixel_noise(&sums, &moments);
        let pooled = |i: usize| {
            let (a, b) = (noise[i], noise[1]);
            PixelNoise {
                mean: std::array::from_fn(|c| (a.mean[c] + b.mean[c]) / 2.0),
                se2: std::array::from_fn(|c| (a.se2[c] + b.se2[c]) / 2.0),
                ..PixelNoise::default()
            }
        };
        let e2 = (pooled(0).relative_variance(0.01) + pooled(2).relative_variance(0.01)) / 2.0;
        assert!((est.rel_rmse.unwrap() - e2.sqrt()).abs() < 1e-15);
    }
}
