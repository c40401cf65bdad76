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
//! is therefore pooled over the pixel's 3×3 neighbourhood `N(p)`. What neighbours share
//! is the per-sample variance **per unit of brightness**, `v_q = s²_q / (x̄_q + f)` with
//! `s²_q = n_q σ̂²_q` and the noise floor `f` (below): light arrives in bright pieces whose
//! number grows with the pixel's value, so the variance of a sample grows about in
//! proportion to the value (as for photon counts), and a dim pixel on the silhouette of a
//! bright fireball does not inherit its neighbours' spread. The pixel's own count and
//! brightness scale it back:
//!
//! ```text
//! σ̄²(p) = η(p) max(mean_{q ∈ N(p)} v_q, v_p) (x̄_p + f) / n_p
//! ```
//!
//! where `N(p)` holds the neighbours inside the image-aligned block of
//! [`crate::film::TILE`]² pixels that holds `p` (a film tile, so that a tile can decide
//! alone) with two samples or more. The maximum keeps a pixel that has drawn a rare bright
//! sample from sharing it out: its own spread is then its error, and averaging it with
//! eight neighbours that missed the tail would hide most of it. A pixel with fewer than
//! two samples has no estimate (infinite). docs/adaptive.md measures what pooling does
//! against converged references (pooling the variance itself, divided by the neighbours'
//! mean value, read 0.6–0.8× the shared explosion's error, which sits on its silhouette).
//!
//! **The sampler's gain.** `σ̂²` is the error of independent samples. plume's Owen-scrambled
//! Sobol points do better (on the self-lit shared cloud, 3× less RMSE at 256 spp). The
//! first `2^k` samples of a pixel are a net, and so is each level `[2^ℓ, 2^{ℓ+1})`
//! (`moments`): two halves `A`, `B` of `h` samples that are both nets give
//! `net = (Ā − B̄)² h / 2`, an estimate of the per-sample variance `s²` as the nets
//! actually vary (for independent samples its mean is `s²`). One pixel's halves are one
//! number per channel, too noisy alone, so the gain is taken over the pixel's 5×5
//! neighbourhood `M(p)` (inside its block, like `N(p)`, with the pixels that have halves),
//! summed over the channels:
//!
//! ```text
//! η(p) = min(1, Σ_{q ∈ M(p)} net_q / Σ_{q ∈ M(p)} s²_q)
//! ```
//!
//! Local, because the gain differs across an image: emission seen directly gains most,
//! scattered light little, and a ratio over a whole block is ruled by its noisiest
//! pixels. This assumes the gain is a factor that does not change from `h` samples to `n`
//! (measured: about constant from 64 to 1024 spp on the shared files).
//!
//! **Relative error with a floor.** Per pixel, over the colour channels `c`,
//!
//! ```text
//! e² = (1/3) Σ_c σ̄²_c / (x̄²_c + f²)
//! ```
//!
//! the error relative to the pixel's value, and relative to the floor `f` (a radiance)
//! where the pixel is darker: the per-pixel form of the relative MSE of
//! `plume bench compare`, with the pixel's mean for the unknown reference and the same
//! `ε = f²` (floor 0.1).
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
/// noise, and the noise floor: what pooling reads.
#[derive(Clone, Copy, Debug)]
pub struct NoiseGrid<'a> {
    /// The rectangle, in image coordinates.
    rect: crate::film::Crop,
    /// One per pixel of `rect`, row-major.
    pixels: &'a [PixelNoise],
    /// The noise floor `f` (radiance, > 0).
    floor: f64,
}

/// The radius of the neighbourhood `N(p)` the variance per unit of brightness is pooled
/// over (3×3).
const POOL_RADIUS: u32 = 1;

/// The radius of the neighbourhood `M(p)` the sampler's gain is taken over (5×5).
const GAIN_RADIUS: u32 = 2;

impl<'a> NoiseGrid<'a> {
    /// The grid of `pixels` (row-major over `rect`) with the noise floor `floor`.
    ///
    /// # Panics
    /// If `pixels` does not have one entry per pixel of `rect`, or `floor` is not
    /// positive.
    #[must_use]
    pub fn new(rect: crate::film::Crop, pixels: &'a [PixelNoise], floor: f64) -> NoiseGrid<'a> {
        assert_eq!(pixels.len() as u64, rect.area(), "one entry per pixel");
        assert!(floor > 0.0, "the noise floor is positive");
        NoiseGrid { rect, pixels, floor }
    }

    /// The per-sample variance of channel `c` of `q` per unit of brightness above the
    /// floor, `v = s² / (x̄ + f)` (module docs).
    fn per_brightness(&self, q: &PixelNoise, c: usize) -> f64 {
        q.s2[c] / (q.mean[c].max(0.0) + self.floor)
    }

    /// The pixels within `radius` of `(x, y)` (itself included) that lie in the grid and
    /// in the block holding `(x, y)` and have an estimate.
    fn neighbours(&self, x: u32, y: u32, radius: u32) -> impl Iterator<Item = &'a PixelNoise> {
        let (r, pixels) = (self.rect, self.pixels);
        let block = |v: u32| v / crate::film::TILE;
        let (xs, ys) =
            (x.saturating_sub(radius)..=x + radius, y.saturating_sub(radius)..=y + radius);
        ys.flat_map(move |qy| xs.clone().map(move |qx| (qx, qy)))
            .filter(move |&(qx, qy)| {
                let inside = qx >= r.x0 && qx < r.x1 && qy >= r.y0 && qy < r.y1;
                inside && block(qx) == block(x) && block(qy) == block(y)
            })
            .map(move |(qx, qy)| &pixels[((qy - r.y0) * r.width() + (qx - r.x0)) as usize])
            .filter(|q| q.se2.iter().all(|v| v.is_finite()))
    }

    /// The sampler's gain `η` at pixel `(x, y)`: `min(1, Σ net / Σ s²)` over its 5×5
    /// neighbours in the grid and its block that have halves, summed over the channels
    /// (module docs; 1 where none has halves or there is no spread at all).
    #[must_use]
    pub fn gain(&self, x: u32, y: u32) -> f64 {
        let (mut net, mut s2) = (0.0f64, 0.0f64);
        for q in self.neighbours(x, y, GAIN_RADIUS) {
            if let Some(v) = q.net {
                net += v.iter().sum::<f64>();
                s2 += q.s2.iter().sum::<f64>();
            }
        }
        if s2 > 0.0 {
            (net / s2).min(1.0)
        } else {
            1.0
        }
    }

    /// The pixel's mean and pooled `σ̄²` at `(x, y)` (image coordinates, inside the grid),
    /// from its 3×3 neighbours in the grid and in its block with an estimate (module
    /// docs); infinite when the pixel itself has none.
    #[must_use]
    pub fn pooled(&self, x: u32, y: u32) -> PixelNoise {
        let r = self.rect;
        let at = |x: u32, y: u32| &self.pixels[((y - r.y0) * r.width() + (x - r.x0)) as usize];
        let own = at(x, y);
        if own.se2.iter().any(|v| !v.is_finite()) {
            return *own;
        }
        let mut shared = [0.0; 3];
        let mut count = 0.0;
        for q in self.neighbours(x, y, POOL_RADIUS) {
            for (c, v) in shared.iter_mut().enumerate() {
                *v += self.per_brightness(q, c);
            }
            count += 1.0;
        }
        // The variance per unit of brightness is what neighbours share, at least the
        // pixel's own; the pixel's own brightness and count scale it back
        let gain = self.gain(x, y);
        PixelNoise {
            se2: std::array::from_fn(|c| {
                let v = (shared[c] / count).max(self.per_brightness(own, c));
                gain * v * (own.mean[c].max(0.0) + self.floor) / own.n
            }),
            ..*own
        }
    }
}

/// Every pixel's noise from sums and moments (row-major, the same pixels).
#[must_use]
pub fn pixel_noise(sums: &[[i128; 4]], moments: &[Moments]) -> Vec<PixelNoise> {
    sums.iter().zip(moments).map(|(s, m)| PixelNoise::of(s, m)).collect()
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

/// A frame's noise, computed once from its sums and moments: the `error` layer, the
/// image's estimate and the spp histogram.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameNoise {
    /// Per pixel (row-major over the crop) and colour channel, the pooled standard error
    /// `σ̄` (infinite for a pixel with fewer than two samples): the `error` layer.
    pub errors: Vec<[f64; 3]>,
    /// The image's estimated relative RMSE.
    pub estimate: ErrorEstimate,
    /// How many pixels hold each sample count.
    pub histogram: Vec<SppCount>,
}

impl FrameNoise {
    /// The noise of the pixels of `crop` from their sums and moments (row-major over it),
    /// with the noise floor `floor` (module docs).
    ///
    /// # Panics
    /// If the slices do not have one entry per pixel of `crop`, or `floor` is not
    /// positive.
    #[must_use]
    pub fn of(
        sums: &[[i128; 4]],
        moments: &[Moments],
        crop: crate::film::Crop,
        floor: f64,
    ) -> FrameNoise {
        assert_eq!(sums.len() as u64, crop.area(), "one sum per pixel");
        assert_eq!(sums.len(), moments.len(), "one moment per pixel");
        let noise = pixel_noise(sums, moments);
        let grid = NoiseGrid::new(crop, &noise, floor);
        let epsilon = floor * floor;
        let mut errors = Vec::with_capacity(noise.len());
        let (mut total, mut pixels, mut finite) = (0.0, 0u64, true);
        let coordinates = (crop.y0..crop.y1).flat_map(|y| (crop.x0..crop.x1).map(move |x| (x, y)));
        for ((s, m), (x, y)) in sums.iter().zip(moments).zip(coordinates) {
            let pooled = grid.pooled(x, y);
            errors.push(pooled.se2.map(f64::sqrt));
            if crate::film::pixel_value(s[3], m.count) > ALPHA_MIN {
                let e2 = pooled.relative_variance(epsilon);
                finite &= e2.is_finite();
                total += e2;
                pixels += 1;
            }
        }
        let rel_rmse = (pixels > 0 && finite).then(|| (total / pixels as f64).sqrt());
        FrameNoise {
            errors,
            estimate: ErrorEstimate { rel_rmse, pixels, floor },
            histogram: spp_histogram(moments),
        }
    }
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

    /// The gain is Σ net / Σ s² over the 5×5 neighbours in the pixel's block that have
    /// halves, at most 1; without halves the independent-sample estimate stays.
    #[test]
    fn the_gain_is_local_and_stays_inside_the_block() {
        use crate::film::Crop;
        let rect = Crop { x0: 0, y0: 0, x1: 32, y1: 1 };
        let pixels: Vec<PixelNoise> = (0..32)
            .map(|x| PixelNoise {
                mean: [1.0; 3],
                se2: [0.01; 3],
                s2: [1.0; 3],
                n: 100.0,
                // Nets vary a quarter as much in 0..8, fully in 8..12, twice in 12..16;
                // the second block has none
                net: match x {
                    0..8 => Some([0.25; 3]),
                    8..12 => Some([1.0; 3]),
                    12..16 => Some([2.0; 3]),
                    _ => None,
                },
            })
            .collect();
        let grid = NoiseGrid::new(rect, &pixels, 0.1);
        assert_eq!(grid.gain(2, 0), 0.25);
        // (7, 0): 5, 6, 7 at a quarter and 8, 9 at one
        assert!((grid.gain(7, 0) - (3.0 * 0.25 + 2.0) / 5.0).abs() < 1e-15);
        assert_eq!((grid.gain(15, 0), grid.gain(16, 0)), (1.0, 1.0));
        assert!((grid.pooled(2, 0).se2[0] - 0.0025).abs() < 1e-15);
        assert!((grid.pooled(20, 0).se2[0] - 0.01).abs() < 1e-15);
    }

    /// Pooling averages the variance per unit of brightness of the 3×3 neighbours inside
    /// the grid and the pixel's block, leaves out neighbours without an estimate, takes at
    /// least the pixel's own, and keeps a pixel without an estimate infinite.
    #[test]
    fn pooling_stays_inside_the_block_and_the_grid() {
        use crate::film::Crop;
        // A 20×2 strip from x = 6: columns 6..16 are one block, 16..26 the next; a
        // pixel's value and variance are its x, but column 16 is a thousand times noisier
        let rect = Crop { x0: 6, y0: 0, x1: 26, y1: 2 };
        let mut pixels: Vec<PixelNoise> = (0..40)
            .map(|i| {
                let x = f64::from(6 + i % 20);
                let s2 = if x == 16.0 { 1000.0 * x } else { x };
                PixelNoise { mean: [x; 3], se2: [s2; 3], s2: [s2; 3], n: 1.0, net: None }
            })
            .collect();
        pixels[20 + 1].se2 = [f64::INFINITY; 3]; // (7, 1): one sample
        let floor = 1.0;
        let grid = NoiseGrid::new(rect, &pixels, floor);
        let v = |x: f64| x / (x + floor);
        // (6, 0): x = 6, 7 at y = 0 and x = 6 at y = 1 ((7, 1) has no estimate); their
        // mean is above the pixel's own v(6), and the pixel's own brightness scales it
        let p = grid.pooled(6, 0);
        assert_eq!(p.mean, [6.0; 3], "a pixel keeps its own mean");
        let shared = (v(6.0) + v(7.0) + v(6.0)) / 3.0;
        assert!((p.se2[0] - shared * (6.0 + floor)).abs() < 1e-12, "{p:?}");
        // (15, 0): x = 14, 15 (the noisy 16 is the next block): the mean is below its
        // own, which it keeps
        assert!((grid.pooled(15, 0).se2[0] - 15.0).abs() < 1e-12);
        assert!(grid.pooled(7, 1).se2[0].is_infinite());
    }

    /// A dim pixel beside bright ones whose variance grows with their value is not given
    /// their variance: what it shares is the variance per unit of brightness.
    #[test]
    fn a_dim_pixel_beside_bright_ones_keeps_a_small_error() {
        use crate::film::Crop;
        let rect = Crop { x0: 0, y0: 0, x1: 3, y1: 1 };
        let at = |x: f64| PixelNoise {
            mean: [x; 3],
            se2: [x / 64.0; 3],
            s2: [x; 3],
            n: 64.0,
            net: None,
        };
        let pixels = [at(100.0), at(1.0), at(100.0)];
        let grid = NoiseGrid::new(rect, &pixels, 0.1);
        let dim = grid.pooled(1, 0).se2[0];
        // Its own σ̂² is 1/64; pooling the variance itself would give about 67/64
        assert!(dim > 1.0 / 64.0 && dim < 1.1 / 64.0, "{dim}");
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
        let frame = FrameNoise::of(&sums, &moments, crop, 0.1);
        assert_eq!(frame.histogram, spp_histogram(&moments));
        let est = frame.estimate;
        assert_eq!(est.pixels, 2);
        // Each bright pixel's own spread is above what it shares with the empty one, and
        // its halves (1 and 3) vary as independent samples would: its own σ̂²
        let noise = pixel_noise(&sums, &moments);
        assert!(noise[1].s2[0] == 0.0 && noise[0].s2[0] > 0.0);
        let e2 = (noise[0].relative_variance(0.01) + noise[2].relative_variance(0.01)) / 2.0;
        assert!((est.rel_rmse.unwrap() - e2.sqrt()).abs() < 1e-15);
        assert_eq!(frame.errors[0], noise[0].se2.map(f64::sqrt));
    }
}
