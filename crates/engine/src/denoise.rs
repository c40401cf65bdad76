//! Denoising (`--denoise`): non-local means on two half buffers, after Rousselle, Knaus
//! and Zwicker, *Adaptive Rendering with Non-Local Means Filtering* (SIGGRAPH Asia 2012),
//! the filter family Cycles used before OpenImageDenoise.
//!
//! **Inputs.** For every pixel the means `a` and `b` of two disjoint halves of its samples
//! (which sample goes to which half: [`half_of`]), so `u = (a + b)/2` is the pixel (for
//! equal halves; `(n_a a + n_b b)/(n_a + n_b)` in general). Their
//! difference measures the noise without a model of it: for a channel,
//! `E[(a − b)²] = σ²_a + σ²_b`, and the variance of one half's mean is estimated as
//! `v = box₅((a − b)²/2)`, the mean over the 5×5 pixels around (one pair alone is a
//! one-degree-of-freedom estimate). Halves of unequal size (an spp that is not a power of
//! two) split `(a − b)²` in proportion, `σ²_a : σ²_b = n_b : n_a`.
//!
//! **Weights.** Pixel `q` of the `(2r+1)²` window around `p` gets
//!
//! ```text
//!   d²(p, q) = mean over the (2f+1)² patch offsets and R, G, B of
//!              [(g_p − g_q)² − (v_p + v_q)] / (ε + k²(v_p + v_q))
//!   w(p, q)  = exp(−max(0, d²(p, q)))
//! ```
//!
//! where `g` is the guide: the expected squared difference of two noisy values is the
//! squared difference of the truths plus the two variances, so the subtraction makes `d²`
//! an estimate of how far the *truths* differ in units of the noise, and `k` ([`Nlm::k`])
//! sets how far is still "the same". `p` itself always gets `w = 1`; pixels whose patches
//! differ by more than the noise get (nearly) 0, which is what keeps edges.
//!
//! The weights are symmetric, `w(p, q) = w(q, p)`. The paper subtracts `v_p + min(v_p,
//! v_q)` instead, which lets a bright (noisier) pixel take from dark neighbours more
//! readily than they take from it: light leaves bright regions and arrives nowhere, and
//! the image mean falls. Symmetric weights keep the mean, for a slightly larger
//! error.
//!
//! **Cross filtering.** Weights computed on half `b` average half `a`, and weights from
//! `a` average `b`; the output is the mean of the two. A half's own noise never chooses
//! the weights that average it, which removes the bias of weights correlated with the
//! values they weigh (the paper's dual-buffer filtering); unequal halves are combined in
//! proportion to their samples. Alpha is averaged with the same weights as the colour.
//!
//! **What is filtered** ([`Filtered`]). Normally the whole beauty. When the camera
//! segment is ray-marched (`--camera-estimator ray-march`), its emission is exact along
//! each ray, with only the pixel footprint's noise, far below the scattered light's: the
//! halves then hold the beauty less it, the filter sees only the rest (the scattered
//! light, external lights) and the emission is added back as rendered, so the fire keeps
//! its texture and the error falls.
//!
//! **Opacity.** With a ray-marched camera segment the pixel's alpha, `1 − τ` along its
//! rays, is exact too (the footprint's noise only), and the scattered light is proportional
//! to it where the smoke is thin: the light scattered toward the camera along a ray is
//! `∫ τ σ_s L_i ds`, at most `α` times the largest in-scattered radiance `L_i`. So the rest
//! is divided by `max(α, 0.05)` ([`OPACITY_FLOOR`]) in both halves, filtered, and
//! multiplied back ([`denoise_per_opacity`]): the filter then averages the in-scattered
//! radiance, which is smooth across the smoke's wisps and edges, instead of a signal whose
//! structure is the opacity's, and the opacity's texture comes back exactly. It lowers the
//! error on the dense demo scene and, more, on thin explosions.
//!
//! A noise-free input (`a = b`) has `v = 0`: every pixel whose patch is not identical gets
//! weight 0 and the image comes back unchanged. The cost is `(2r+1)²` patch distances per
//! pixel, twice: with the defaults, small beside the render it filters.

pub use plume_scene::sets::Filtered;
use rayon::prelude::*;

use crate::film::{count, pixel_value};
use crate::integrator::aov::{AovLayout, Component};

/// The non-local means filter's parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Nlm {
    /// Window radius `r`: pixels up to `r` away in x and y are averaged.
    pub radius: u32,
    /// Patch radius `f`: pixels are compared by their `(2f+1)²` neighbourhoods.
    pub patch: u32,
    /// Strength `k`: patch differences up to about `k` noise deviations count as equal.
    pub k: f32,
}

impl Default for Nlm {
    /// `r = 3`, `f = 4`, `k = 0.6`: the flat optimum over the demo scene
    /// (`data/explosion.toml`) and, held out, the peer comparison's three explosions at
    /// albedo 0.8 (`r` 3–4, `f` 4–5, `k` 0.5–0.7 are
    /// nearly as good on each). With little noise to remove a small window blurs less.
    fn default() -> Nlm {
        Nlm { radius: 3, patch: 4, k: 0.6 }
    }
}

/// Which half buffer sample `sample` goes to (`false`: `a`, `true`: `b`): alternate
/// blocks of `block` samples ([`half_block`]), `b` holding the odd blocks.
///
/// A block of `2^j` consecutive samples that starts at a multiple of `2^j` is, with
/// Owen-scrambled Sobol points, a stratified net of its own, so each half is as well
/// distributed as a render of its size, and `a − b` measures the noise of such renders.
/// Smaller blocks make halves that are not nets: their difference overstates the noise
/// of the whole and the filter blurs what it need not: the denoised error grows as the
/// blocks shrink, and halves by a hash of the sample are worse still. Parity, blocks of 1, is worst in principle: even and odd indices lie in
/// opposite halves of every dimension's first stratum, so the halves would differ by the
/// image's structure inside the pixel. A function of the sample index and the block
/// alone, so the halves, like the image, do not depend on how the work was split.
#[must_use]
#[inline]
pub fn half_of(sample: u64, block: u64) -> bool {
    (sample / block) % 2 == 1
}

/// The half block of a render of `spp` samples per pixel: the largest power of two up
/// to `spp/2` (so 32 spp are split into samples 0–15 and 16–31), or 16 when the count
/// is not fixed (a time budget, or sample ranges without `--spp`; such a render is
/// denoised once it has more than 16 samples).
#[must_use]
pub fn half_block(spp: Option<u32>) -> u64 {
    match spp {
        Some(n) if n >= 2 => 1 << (n / 2).ilog2(),
        Some(_) => 1,
        None => 16,
    }
}

/// An RGBA image: `width × height` pixels, row-major.
#[derive(Clone, Copy, Debug)]
pub struct Rgba<'a> {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// The pixels.
    pub pixels: &'a [[f32; 4]],
}

/// The denoised image of the two half buffers `a` and `b` (the same size), as the module
/// docs describe. `b_share`: per pixel, `n_a / (n_a + n_b)` for halves of `n_a` and `n_b`
/// samples, the part of `E[(a − b)²]` that is `b`'s variance; `None`: equal halves (½).
///
/// # Panics
/// If `a`, `b` and `b_share` differ in size or do not hold `width × height` pixels.
#[must_use]
pub fn denoise(a: Rgba<'_>, b: Rgba<'_>, b_share: Option<&[f32]>, nlm: &Nlm) -> Vec<[f32; 4]> {
    let (w, h) = (a.width, a.height);
    assert!(
        (b.width, b.height) == (w, h) && a.pixels.len() == w * h && b.pixels.len() == w * h,
        "invariant: halves of one image"
    );
    assert!(b_share.is_none_or(|s| s.len() == w * h), "invariant: a share per pixel");
    let share = |i: usize| b_share.map_or(0.5, |s| s[i]);
    let var_b = half_variance(a, b, share);
    let var_a = half_variance(a, b, |i| 1.0 - share(i));
    let fa = filter(b, &var_b, a, nlm);
    let fb = filter(a, &var_a, b, nlm);
    // Each filtered half weighted by its sample count, as the pixel weighs the halves
    fa.iter()
        .zip(&fb)
        .enumerate()
        .map(|(i, (x, y))| std::array::from_fn(|c| share(i) * x[c] + (1.0 - share(i)) * y[c]))
        .collect()
}

/// The smallest opacity the scattered light is divided by ([`denoise_per_opacity`]):
/// fainter pixels are filtered as they are, up to this constant factor.
pub const OPACITY_FLOOR: f32 = 0.05;

/// [`denoise`] of the halves' colour divided by `max(opacity, OPACITY_FLOOR)` per pixel,
/// multiplied back after (module docs, "Opacity"). The output's alpha is `opacity`, the
/// pixel's own: exact, it has nothing to filter, and weights chosen on light per unit
/// of opacity would average it across the opacity's texture.
///
/// # Panics
/// As [`denoise`], or if `opacity` does not hold one value per pixel.
#[must_use]
pub fn denoise_per_opacity(
    a: Rgba<'_>,
    b: Rgba<'_>,
    b_share: Option<&[f32]>,
    opacity: &[f32],
    nlm: &Nlm,
) -> Vec<[f32; 4]> {
    assert_eq!(opacity.len(), a.pixels.len(), "invariant: an opacity per pixel");
    let scale: Vec<f32> = opacity.iter().map(|&o| o.max(OPACITY_FLOOR)).collect();
    let divide = |half: Rgba<'_>| -> Vec<[f32; 4]> {
        half.pixels.iter().zip(&scale).map(|(p, &s)| [p[0] / s, p[1] / s, p[2] / s, p[3]]).collect()
    };
    let (da, db) = (divide(a), divide(b));
    let mut out = denoise(Rgba { pixels: &da, ..a }, Rgba { pixels: &db, ..b }, b_share, nlm);
    for ((p, &s), &o) in out.iter_mut().zip(&scale).zip(opacity) {
        for v in &mut p[..3] {
            *v *= s;
        }
        p[3] = o;
    }
    out
}

/// The denoised beauty of an image (`crop` pixels, row-major) from its exact sums over
/// `counts` samples per pixel: `sums` (RGBA per pixel) and `aov_sums`
/// (`layout.channels()` per pixel, with the half sums), with the default [`Nlm`]. `None` when the layout has no half sums
/// or no pixel has samples in both halves (fewer samples than one half block, e.g. a
/// time budget that ended before sample 16).
///
/// The second half's mean is `half / n_b` and the first's `(total − half)/(spp − n_b)`,
/// both from the exact sums (so a merged frame denoises to the same bits as one render).
/// A dropped non-finite sample counts as a zero in the first half, as it counts as a zero
/// in the beauty; a pixel whose second half was all dropped gets its mean for both.
///
/// With [`Filtered::LessEmission`] (the layout's `half.rest` sums) the camera segment's
/// emission (the `emission` layer) is taken out of both halves, the rest filtered per
/// unit of opacity ([`denoise_per_opacity`], with the pixel's alpha), and the emission
/// added back as rendered: the ray-march estimator makes it exact along each ray, so it
/// has no noise to remove and keeps the fire's texture, which the filter would soften.
#[must_use]
pub fn from_sums(
    layout: &AovLayout,
    sums: &[[i128; 4]],
    aov_sums: &[i128],
    counts: &[u64],
    size: (usize, usize),
) -> Option<Vec<[f32; 4]>> {
    let at = layout.half_at()?;
    let rest = layout.halves == Some(Filtered::LessEmission);
    let n = layout.channels();
    let (mut a, mut b) = (Vec::with_capacity(sums.len()), Vec::with_capacity(sums.len()));
    let mut b_share = Vec::with_capacity(sums.len());
    let mut kept = Vec::with_capacity(if rest { sums.len() } else { 0 });
    let mut both = false;
    let emission = AovLayout::offset(Component::Emission);
    for ((total, aov), &spp) in sums.iter().zip(aov_sums.chunks_exact(n)).zip(counts) {
        let half = &aov[at..at + 5];
        // The filtered part's total: the beauty, less the emission layer's sums when those
        // are kept out (as `AovSample::half` leaves them out of the half sums)
        let mut total = *total;
        if rest {
            let e = &aov[emission..emission + 3];
            for c in 0..3 {
                total[c] -= e[c];
            }
            kept.push(std::array::from_fn::<f32, 3, _>(|c| pixel_value(e[c], spp)));
        }
        let nb = count(half[4]).min(spp);
        both |= nb > 0 && nb < spp;
        b_share.push(((spp - nb) as f64 / spp.max(1) as f64) as f32);
        if nb == 0 || nb == spp {
            let u: [f32; 4] = std::array::from_fn(|c| pixel_value(total[c], spp));
            a.push(u);
            b.push(u);
        } else {
            a.push(std::array::from_fn(|c| pixel_value(total[c] - half[c], spp - nb)));
            b.push(std::array::from_fn(|c| pixel_value(half[c], nb)));
        }
    }
    if !both {
        return None;
    }
    let (width, height) = size;
    let (a, b) = (Rgba { width, height, pixels: &a }, Rgba { width, height, pixels: &b });
    let mut out = if rest {
        let opacity: Vec<f32> =
            sums.iter().zip(counts).map(|(t, &spp)| pixel_value(t[3], spp)).collect();
        denoise_per_opacity(a, b, Some(&b_share), &opacity, &Nlm::default())
    } else {
        denoise(a, b, Some(&b_share), &Nlm::default())
    };
    for (p, e) in out.iter_mut().zip(&kept) {
        for c in 0..3 {
            p[c] += e[c];
        }
    }
    Some(out)
}

/// Per pixel and colour channel, the variance of one half's mean: `box₅((a − b)² ·
/// share)`, where `share(pixel)` is that half's part of the difference's variance (½ for
/// equal halves; a half of `n` of `N` samples has the part `(N − n)/N`).
fn half_variance(a: Rgba<'_>, b: Rgba<'_>, share: impl Fn(usize) -> f32) -> Vec<[f32; 3]> {
    let raw: Vec<[f32; 3]> = a
        .pixels
        .iter()
        .zip(b.pixels)
        .enumerate()
        .map(|(i, (x, y))| std::array::from_fn(|c| (x[c] - y[c]) * (x[c] - y[c]) * share(i)))
        .collect();
    box_mean(&raw, a.width, a.height, 2)
}

/// `i` clamped to `0..n` (image edges repeat their last row or column).
#[inline]
fn clamp_index(i: isize, n: usize) -> usize {
    i.clamp(0, n as isize - 1) as usize
}

/// The mean of each pixel's `(2f+1)²` neighbourhood, rows and columns clamped at the
/// edges (a row pass, then a column pass).
fn box_mean(img: &[[f32; 3]], w: usize, h: usize, f: usize) -> Vec<[f32; 3]> {
    let n = (2 * f + 1) as f32;
    let mut rows = vec![[0f32; 3]; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut s = [0f32; 3];
            for dx in -(f as isize)..=f as isize {
                let p = img[y * w + clamp_index(x as isize + dx, w)];
                for c in 0..3 {
                    s[c] += p[c];
                }
            }
            rows[y * w + x] = s;
        }
    }
    let mut out = vec![[0f32; 3]; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut s = [0f32; 3];
            for dy in -(f as isize)..=f as isize {
                let p = rows[clamp_index(y as isize + dy, h) * w + x];
                for c in 0..3 {
                    s[c] += p[c];
                }
            }
            out[y * w + x] = s.map(|v| v / (n * n));
        }
    }
    out
}

/// Rows of output computed together (each strip recomputes `f` rows of patch distances
/// above and below it).
const STRIP: usize = 16;

/// Average `target` with the weights that `guide` (whose per-channel variance is `var`)
/// gives: the module docs' `Σ_q w(p,q) target_q / Σ_q w(p,q)`.
fn filter(guide: Rgba<'_>, var: &[[f32; 3]], target: Rgba<'_>, nlm: &Nlm) -> Vec<[f32; 4]> {
    let (w, h) = (guide.width, guide.height);
    let mut out = vec![[0f32; 4]; w * h];
    out.par_chunks_mut(STRIP * w)
        .enumerate()
        .for_each(|(i, strip)| filter_strip(guide, var, target, nlm, i * STRIP, strip));
    out
}

/// [`filter`] for the rows `y0..` that `out` holds.
fn filter_strip(
    guide: Rgba<'_>,
    var: &[[f32; 3]],
    target: Rgba<'_>,
    nlm: &Nlm,
    y0: usize,
    out: &mut [[f32; 4]],
) {
    let (w, h) = (guide.width, guide.height);
    let rows = out.len() / w;
    let (r, f) = (nlm.radius as isize, nlm.patch as usize);
    let k2 = nlm.k * nlm.k;
    // Patch distances are needed for rows y0 − f .. y0 + rows + f (clamped to the image)
    let halo = rows + 2 * f;
    let mut dist = vec![0f32; halo * w];
    // Row sums of `dist` over the patch's 2f + 1 columns
    let mut hsum = vec![0f32; halo * w];
    let mut acc = vec![[0f64; 4]; rows * w];
    let mut wsum = vec![0f64; rows * w];
    let g = guide.pixels;
    let inv_patch = 1.0 / (3 * (2 * f + 1) * (2 * f + 1)) as f32;
    for dy in -r..=r {
        for dx in -r..=r {
            // d for every pixel p of the halo rows against q = p + (dx, dy)
            for j in 0..halo {
                let y = clamp_index(y0 as isize - f as isize + j as isize, h);
                let qy = clamp_index(y as isize + dy, h);
                for x in 0..w {
                    let p = y * w + x;
                    let q = qy * w + clamp_index(x as isize + dx, w);
                    let (vp, vq) = (var[p], var[q]);
                    let mut d = 0f32;
                    for c in 0..3 {
                        let diff = g[p][c] - g[q][c];
                        d += (diff * diff - (vp[c] + vq[c])) / (1e-10 + k2 * (vp[c] + vq[c]));
                    }
                    dist[j * w + x] = d;
                }
                let row = &dist[j * w..(j + 1) * w];
                for x in 0..w {
                    hsum[j * w + x] = (-(f as isize)..=f as isize)
                        .map(|o| row[clamp_index(x as isize + o, w)])
                        .sum();
                }
            }
            for j in 0..rows {
                let qy = clamp_index((y0 + j) as isize + dy, h);
                let src = &target.pixels[qy * w..(qy + 1) * w];
                for x in 0..w {
                    // The patch mean of d: the halo rows j .. j + 2f around output row j
                    let patch: f32 =
                        (0..=2 * f).map(|k| hsum[(j + k) * w + x]).sum::<f32>() * inv_patch;
                    let wt = f64::from((-patch.max(0.0)).exp());
                    let q = src[clamp_index(x as isize + dx, w)];
                    let a = &mut acc[j * w + x];
                    for c in 0..4 {
                        a[c] += wt * f64::from(q[c]);
                    }
                    wsum[j * w + x] += wt;
                }
            }
        }
    }
    for ((o, a), s) in out.iter_mut().zip(&acc).zip(&wsum) {
        *o = a.map(|v| (v / s) as f32);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic standard normal stream (splitmix64 + Box–Muller).
    struct Normal(u64);
    impl Normal {
        fn uniform(&mut self) -> f64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
        }
        fn next(&mut self) -> f32 {
            let (u, v) = (self.uniform().max(1e-300), self.uniform());
            ((-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()) as f32
        }
    }

    /// A smooth ramp with a vertical step of height 1 at x = 40 (values 0.5..2.5).
    fn truth(w: usize, h: usize) -> Vec<[f32; 4]> {
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                let v = 0.5
                    + 0.5 * (x / w as f32)
                    + 0.3 * (y / h as f32)
                    + if x >= 40.0 { 1.0 } else { 0.0 };
                [v, 0.8 * v, 0.6 * v, 1.0]
            })
            .collect()
    }

    fn rms(x: &[[f32; 4]], t: &[[f32; 4]], keep: impl Fn(usize) -> bool) -> f64 {
        let (mut s, mut n) = (0.0, 0usize);
        for (_, (p, q)) in x.iter().zip(t).enumerate().filter(|(i, _)| keep(*i)) {
            s += (0..3).map(|c| f64::from(p[c] - q[c]).powi(2)).sum::<f64>() / 3.0;
            n += 1;
        }
        (s / n as f64).sqrt()
    }

    #[test]
    fn noise_is_removed_and_the_edge_is_kept() {
        let (w, h) = (80, 48);
        let t = truth(w, h);
        let mut rng = Normal(7);
        // Each half: the truth plus noise of deviation 0.2 (a tenth of the step)
        let mut half = || {
            t.iter()
                .map(|p| {
                    [p[0] + 0.2 * rng.next(), p[1] + 0.2 * rng.next(), p[2] + 0.2 * rng.next(), 1.0]
                })
                .collect::<Vec<_>>()
        };
        let (a, b) = (half(), half());
        let u: Vec<[f32; 4]> =
            a.iter().zip(&b).map(|(x, y)| std::array::from_fn(|c| 0.5 * (x[c] + y[c]))).collect();
        let img = |p| Rgba { width: w, height: h, pixels: p };
        let d = denoise(img(&a), img(&b), None, &Nlm::default());
        let all = rms(&d, &t, |_| true);
        let noisy = rms(&u, &t, |_| true);
        // The mean of two halves has deviation 0.2/√2 ≈ 0.141; the filter averages many
        // pixels of equal truth
        assert!((noisy - 0.141).abs() < 0.01, "{noisy}");
        assert!(all < noisy / 3.0, "denoised {all} against noisy {noisy}");
        // The two columns beside the step: averaging across it would put them a step's
        // fraction (≥ 0.2 for a window reaching 7 pixels over) off; kept, they stay within
        // the noise
        let edge = rms(&d, &t, |i| (38..42).contains(&(i % w)));
        assert!(edge < 0.1, "the step is blurred: {edge} at the edge, {all} overall");
        // Alpha is averaged with the same weights: a constant stays constant
        assert!(d.iter().all(|p| (p[3] - 1.0).abs() < 1e-6));
    }

    #[test]
    fn a_noise_free_image_comes_back_unchanged() {
        let (w, h) = (40, 24);
        let t = truth(w, h);
        let img = Rgba { width: w, height: h, pixels: &t };
        let d = denoise(img, img, None, &Nlm::default());
        for (p, q) in d.iter().zip(&t) {
            for c in 0..4 {
                assert!((p[c] - q[c]).abs() <= 1e-6 * q[c].abs(), "{p:?} against {q:?}");
            }
        }
    }

    #[test]
    fn unequal_halves_are_combined_as_the_pixel_combines_them() {
        // 32 samples of mean 1 and 16 of mean 2: the pixel is (32 + 32)/48 = 4/3, and
        // the filter, averaging constants, must give it back (an equal mix gives 3/2)
        let (w, h) = (24, 16);
        let (a, b) = (vec![[1.0f32; 4]; w * h], vec![[2.0f32; 4]; w * h]);
        let share = vec![32.0f32 / 48.0; w * h];
        let d = denoise(
            Rgba { width: w, height: h, pixels: &a },
            Rgba { width: w, height: h, pixels: &b },
            Some(&share),
            &Nlm::default(),
        );
        assert!(d.iter().all(|p| p.iter().all(|v| (v - 4.0 / 3.0).abs() < 1e-6)), "{:?}", d[0]);
    }

    /// Scattered light that is a smooth in-scattered radiance times a fine opacity
    /// texture (stripes of α 0.15 and 0.9, two pixels wide, noise proportional to the
    /// light): divided by the known opacity the filter averages the smooth part and the
    /// texture comes back exactly; filtered as it is, the stripes (finer than a patch) are
    /// either blurred or left noisy.
    #[test]
    fn filtering_per_unit_of_opacity_keeps_the_opacity_texture() {
        let (w, h) = (80, 48);
        let opacity: Vec<f32> =
            (0..w * h).map(|i| if (i % w / 2) % 2 == 0 { 0.15 } else { 0.9 }).collect();
        let t: Vec<[f32; 4]> = truth(w, h)
            .iter()
            .zip(&opacity)
            .map(|(p, &o)| [p[0] * o, p[1] * o, p[2] * o, o])
            .collect();
        let mut rng = Normal(11);
        let mut half = || {
            t.iter()
                .map(|p| {
                    [
                        p[0] * (1.0 + 0.3 * rng.next()),
                        p[1] * (1.0 + 0.3 * rng.next()),
                        p[2] * (1.0 + 0.3 * rng.next()),
                        p[3],
                    ]
                })
                .collect::<Vec<_>>()
        };
        let (a, b) = (half(), half());
        let img = |p| Rgba { width: w, height: h, pixels: p };
        let plain = rms(&denoise(img(&a), img(&b), None, &Nlm::default()), &t, |_| true);
        let per_opacity = denoise_per_opacity(img(&a), img(&b), None, &opacity, &Nlm::default());
        let demodulated = rms(&per_opacity, &t, |_| true);
        assert!(
            demodulated < 0.6 * plain,
            "per unit of opacity {demodulated} against {plain} filtered as it is"
        );
        // Alpha is the given opacity, not averaged across the stripes
        assert!(per_opacity.iter().zip(&opacity).all(|(p, &o)| p[3] == o));
        // A noise-free input comes back unchanged, also below the opacity floor
        let faint: Vec<f32> = opacity.iter().map(|o| o * 0.1).collect();
        let d = denoise_per_opacity(img(&t), img(&t), None, &faint, &Nlm::default());
        assert!(d
            .iter()
            .zip(&t)
            .all(|(p, q)| (0..3).all(|c| (p[c] - q[c]).abs() <= 1e-5 * q[c].abs())));
    }

    #[test]
    fn halves_are_two_aligned_blocks_at_powers_of_two() {
        assert_eq!(
            (
                half_block(Some(32)),
                half_block(Some(48)),
                half_block(Some(7)),
                half_block(Some(1)),
                half_block(None)
            ),
            (16, 16, 2, 1, 16)
        );
        for m in 1..12 {
            let n = 1u32 << m;
            let block = half_block(Some(n));
            let b: Vec<u64> = (0..u64::from(n)).filter(|&s| half_of(s, block)).collect();
            assert_eq!(b, (u64::from(n) / 2..u64::from(n)).collect::<Vec<_>>(), "{n} spp");
        }
        // Beyond the planned count the blocks alternate
        assert!(!half_of(32, 16) && half_of(48, 16) && !half_of(64, 16));
    }
}
