//! Piecewise-constant densities on `[0, 1)` and `[0, 1)²`, sampled by inverting their
//! cumulative distribution (the idea of pbrt-v4's `PiecewiseConstant1D/2D`).
//!
//! **1-D.** Non-negative weights `f_0 … f_{n−1}` define `f(x) = f_⌊n x⌋` on `[0, 1)`, with
//! integral `I = Σ f_i / n` and density `p(x) = f(x) / I` (with respect to length). The
//! cumulative distribution at the bin edges is
//!
//! ```text
//!   S_k = Σ_{i<k} f_i,     cdf_k = S_k / S_n,     k = 0 … n,
//! ```
//!
//! so `cdf_0 = 0` and `cdf_n = 1` exactly, and every trailing zero bin has `cdf_k = 1`
//! exactly too (`S_k = S_n`, and `a / a = 1` in floating point). A uniform `u ∈ [0, 1)`
//! picks the bin `k` with `cdf_k ≤ u < cdf_{k+1}` (binary search) and lands at
//! `x = (k + (u − cdf_k)/(cdf_{k+1} − cdf_k)) / n`. A zero bin has `cdf_k = cdf_{k+1}`
//! and so can never satisfy the bracket: **zero bins are never sampled**, and their
//! density is exactly 0.
//!
//! **2-D.** A `W × H` grid of weights `f_ij` (row-major, row `j` covers
//! `v ∈ [j/H, (j+1)/H)`, column `i` covers `u ∈ [i/W, (i+1)/W)`) is sampled in two steps:
//! the row from the *marginal* over row integrals `I_j = Σ_i f_ij / W`, then the column from
//! that row's *conditional*. The joint density is the product
//!
//! ```text
//!   p(u, v) = (I_j / I) · (f_ij / I_j) = f_ij / I,     I = Σ_j I_j / H = Σ_ij f_ij / (W H),
//! ```
//!
//! with respect to area on the unit square. A row of zeros has `I_j = 0`: the marginal
//! never picks it, so its conditional (built as uniform only to keep it well-formed) is
//! never consulted.
//!
//! **`sample` and `pdf` agree bit for bit.** MIS weights compare the pdf a technique
//! reported when sampling with the pdf another technique computes for the same point, so
//! both go through one expression (`f_ij / I`, [`Distribution2D::cell_pdf`]), and the
//! sampled point is nudged, if rounding put it on a neighbour's side of a bin edge, back
//! into the bin that was chosen: `pdf(sample(u).uv)` is the sample's pdf exactly.
//!
//! Memory: two `f64` per cell (weight and cdf), about 128 MiB for a 4096 × 2048 map.

/// A point drawn from a [`Distribution1D`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample1D {
    /// The point, in `[0, 1)`, inside bin `bin`.
    pub x: f64,
    /// Density at `x` with respect to length on `[0, 1)`; bit-identical to
    /// [`Distribution1D::pdf`]`(x)`.
    pub pdf: f64,
    /// The bin `⌊n x⌋` holding `x`.
    pub bin: usize,
}

/// A piecewise-constant density on `[0, 1)` over `n` equal bins (see the module docs).
#[derive(Clone, Debug)]
pub struct Distribution1D {
    /// The weights `f_i`, as given.
    func: Vec<f64>,
    /// `cdf_k`, `n + 1` of them, `cdf_0 = 0`, `cdf_n = 1`.
    cdf: Vec<f64>,
    /// `∫ f = Σ f_i / n`.
    integral: f64,
}

/// True when every weight is finite and non-negative.
fn valid_weights(weights: &[f64]) -> bool {
    weights.iter().all(|w| w.is_finite() && *w >= 0.0)
}

/// The largest `f64` below 1.
const ONE_MINUS_EPSILON: f64 = 1.0 - f64::EPSILON / 2.0;

/// The next `f64` below a positive `x`.
fn next_down(x: f64) -> f64 {
    debug_assert!(x > 0.0 && x.is_finite());
    f64::from_bits(x.to_bits() - 1)
}

/// The next `f64` above a non-negative finite `x`.
fn next_up(x: f64) -> f64 {
    debug_assert!(x >= 0.0 && x.is_finite());
    f64::from_bits((x + 0.0).to_bits() + 1)
}

/// The bin of `x` among `n` equal bins of `[0, 1)`, `⌊n x⌋` clamped into `0 … n − 1` (so
/// `x = 1` falls into the last bin, negative `x` and NaN into the first). The one lookup
/// every pdf here uses; a caller that indexes its own data by `(u, v)` should use it too.
///
/// # Panics
/// In debug builds, if `n` is 0.
#[inline]
#[must_use]
pub fn bin_of(x: f64, n: usize) -> usize {
    // `as usize` saturates: NaN and negatives give 0
    ((x * n as f64) as usize).min(n - 1)
}

impl Distribution1D {
    /// The distribution over `weights`.
    ///
    /// Returns `None` when `weights` is empty, any weight is negative, NaN or infinite,
    /// or all are zero (or their sum overflows).
    #[must_use]
    pub fn new(weights: &[f64]) -> Option<Distribution1D> {
        if weights.is_empty() || !valid_weights(weights) {
            return None;
        }
        let d = Distribution1D::build(weights.to_vec());
        (d.integral > 0.0 && d.integral.is_finite()).then_some(d)
    }

    /// Build without validation; all-zero weights give a uniform cdf and integral 0.
    fn build(func: Vec<f64>) -> Distribution1D {
        let n = func.len();
        let mut cdf = Vec::with_capacity(n + 1);
        let mut sum = 0.0f64;
        cdf.push(0.0);
        for &f in &func {
            sum += f;
            cdf.push(sum);
        }
        if sum > 0.0 && sum.is_finite() {
            for c in &mut cdf[1..] {
                *c /= sum;
            }
        } else {
            // never sampled (zero row of a 2-D grid), or rejected by `new`
            for (k, c) in cdf.iter_mut().enumerate() {
                *c = k as f64 / n as f64;
            }
        }
        Distribution1D { func, cdf, integral: sum / n as f64 }
    }

    /// Number of bins.
    #[must_use]
    pub fn len(&self) -> usize {
        self.func.len()
    }

    /// Always false: a distribution has at least one bin.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.func.is_empty()
    }

    /// `∫₀¹ f(x) dx = Σ f_i / n` of the weights as given (unnormalised).
    #[must_use]
    pub fn integral(&self) -> f64 {
        self.integral
    }

    /// Density of bin `bin` with respect to length: `f_bin / I`.
    ///
    /// # Panics
    /// If `bin` is out of range.
    #[inline]
    #[must_use]
    pub fn bin_pdf(&self, bin: usize) -> f64 {
        self.func[bin] / self.integral
    }

    /// Density at `x ∈ [0, 1)` with respect to length (0 in zero bins). `x` outside is
    /// clamped into the first or last bin.
    #[must_use]
    pub fn pdf(&self, x: f64) -> f64 {
        self.bin_pdf(bin_of(x, self.len()))
    }

    /// Draw `x` with density [`pdf`](Self::pdf) from a uniform `u ∈ [0, 1)` (values at or
    /// above 1 are treated as the largest `f64` below 1, negative ones and NaN as 0).
    /// Monotone in `u`.
    #[must_use]
    pub fn sample(&self, u: f64) -> Sample1D {
        debug_assert!(self.integral > 0.0, "sampling a distribution of zero integral");
        let u = if u >= 0.0 { u.min(ONE_MINUS_EPSILON) } else { 0.0 };
        let n = self.len();
        // cdf_0 = 0 ≤ u < 1 = cdf_n, so the bin is in 0 … n − 1 and has cdf_k < cdf_{k+1}
        let bin = self.cdf.partition_point(|&c| c <= u) - 1;
        let (lo, hi) = (self.cdf[bin], self.cdf[bin + 1]);
        debug_assert!(lo <= u && u < hi);
        let du = (u - lo) / (hi - lo);
        let mut x = ((bin as f64 + du) / n as f64).min(ONE_MINUS_EPSILON);
        // rounding may cross a bin edge: step back into the chosen bin
        while bin_of(x, n) > bin {
            x = next_down(x);
        }
        while bin_of(x, n) < bin {
            x = next_up(x);
        }
        Sample1D { x, pdf: self.bin_pdf(bin), bin }
    }
}

/// A point drawn from a [`Distribution2D`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample2D {
    /// The point `(u, v)` in `[0, 1)²`.
    pub uv: [f64; 2],
    /// Density with respect to area on the unit square; bit-identical to
    /// [`Distribution2D::pdf`]`(uv)`.
    pub pdf: f64,
}

/// A piecewise-constant density on `[0, 1)²` over a `width × height` grid (module docs).
#[derive(Clone, Debug)]
pub struct Distribution2D {
    width: usize,
    height: usize,
    /// One distribution over `u` per row `j`.
    conditional: Vec<Distribution1D>,
    /// The distribution over rows, weights `I_j`.
    marginal: Distribution1D,
}

impl Distribution2D {
    /// The distribution over `weights`, `width × height` of them, row-major with row 0
    /// at `v ∈ [0, 1/height)`.
    ///
    /// Returns `None` when the size is zero or does not match `weights.len()`, when any
    /// weight is negative, NaN or infinite, or when all are zero (or their sum
    /// overflows). Callers that need a reason validate first.
    #[must_use]
    pub fn new(weights: &[f64], width: usize, height: usize) -> Option<Distribution2D> {
        if width == 0
            || height == 0
            || width.checked_mul(height) != Some(weights.len())
            || !valid_weights(weights)
        {
            return None;
        }
        let conditional: Vec<Distribution1D> =
            weights.chunks_exact(width).map(|row| Distribution1D::build(row.to_vec())).collect();
        if conditional.iter().any(|c| !c.integral.is_finite()) {
            return None;
        }
        let marginal = Distribution1D::new(
            &conditional.iter().map(Distribution1D::integral).collect::<Vec<_>>(),
        )?;
        Some(Distribution2D { width, height, conditional, marginal })
    }

    /// Columns (bins along `u`).
    #[must_use]
    pub fn width(&self) -> usize {
        self.width
    }

    /// Rows (bins along `v`).
    #[must_use]
    pub fn height(&self) -> usize {
        self.height
    }

    /// `∫∫ f du dv = Σ f_ij / (W H)` of the weights as given.
    #[must_use]
    pub fn integral(&self) -> f64 {
        self.marginal.integral()
    }

    /// The cell `[column, row]` holding `uv` (coordinates outside `[0, 1)` are clamped
    /// into the edge cells).
    #[inline]
    #[must_use]
    pub fn cell(&self, uv: [f64; 2]) -> [usize; 2] {
        [bin_of(uv[0], self.width), bin_of(uv[1], self.height)]
    }

    /// Density of cell `[column, row]` with respect to area: `f_ij / I`.
    ///
    /// # Panics
    /// If the cell is out of range.
    #[inline]
    #[must_use]
    pub fn cell_pdf(&self, [column, row]: [usize; 2]) -> f64 {
        self.conditional[row].func[column] / self.marginal.integral
    }

    /// Density at `uv` with respect to area on the unit square (0 in zero cells).
    #[must_use]
    pub fn pdf(&self, uv: [f64; 2]) -> f64 {
        self.cell_pdf(self.cell(uv))
    }

    /// Draw `uv` with density [`pdf`](Self::pdf) from a uniform `u ∈ [0, 1)²`: `u[1]`
    /// picks the row (`v`), `u[0]` the column (`u`) within it.
    #[must_use]
    pub fn sample(&self, u: [f64; 2]) -> Sample2D {
        let v = self.marginal.sample(u[1]);
        let along = self.conditional[v.bin].sample(u[0]);
        Sample2D { uv: [along.x, v.x], pdf: self.cell_pdf([along.bin, v.bin]) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic stream of uniforms in [0, 1) (SplitMix64).
    fn uniforms(seed: u64, count: usize) -> Vec<f64> {
        let mut s = crate::sampling::Sampler::new(seed, 0, 0);
        (0..count).map(|_| s.next_f64()).collect()
    }

    /// Uniforms that hit the cdf's own values and their neighbours, where bracketing is
    /// most fragile.
    fn edge_uniforms(d: &Distribution1D) -> Vec<f64> {
        let mut u = vec![0.0, ONE_MINUS_EPSILON];
        for &c in &d.cdf {
            if c > 0.0 && c < 1.0 {
                u.extend([next_down(c), c, next_up(c)]);
            }
        }
        u
    }

    #[test]
    fn rejects_invalid_weights() {
        assert!(Distribution1D::new(&[]).is_none());
        assert!(Distribution1D::new(&[0.0, 0.0]).is_none());
        assert!(Distribution1D::new(&[1.0, -1.0]).is_none());
        assert!(Distribution1D::new(&[1.0, f64::NAN]).is_none());
        assert!(Distribution1D::new(&[1.0, f64::INFINITY]).is_none());
        assert!(Distribution1D::new(&[f64::MAX, f64::MAX]).is_none(), "overflowing sum");
        assert!(Distribution2D::new(&[0.0; 6], 3, 2).is_none());
        assert!(Distribution2D::new(&[1.0; 6], 3, 3).is_none(), "size mismatch");
        assert!(Distribution2D::new(&[], 0, 0).is_none());
        assert!(Distribution2D::new(&[1.0, -0.5, 1.0, 1.0], 2, 2).is_none());
        assert!(Distribution2D::new(&[1.0, f64::NAN, 1.0, 1.0], 2, 2).is_none());
        assert!(Distribution2D::new(&[1.0, 1.0, 1.0, f64::NEG_INFINITY], 2, 2).is_none());
        assert!(Distribution2D::new(&[1.0; 4], 2, 2).is_some());
    }

    #[test]
    fn one_d_pdf_integrates_to_one_and_matches_weights() {
        let w = [0.0, 3.0, 1.0, 0.0, 0.0, 4.0, 0.0];
        let d = Distribution1D::new(&w).unwrap();
        assert_eq!(d.integral(), 8.0 / 7.0);
        let total: f64 = (0..w.len()).map(|k| d.bin_pdf(k) / w.len() as f64).sum();
        assert!((total - 1.0).abs() < 1e-14, "{total}");
        // pdf(x) at bin centres is f/I
        for (k, &f) in w.iter().enumerate() {
            assert_eq!(d.pdf((k as f64 + 0.5) / 7.0), f / d.integral());
        }
        assert_eq!(d.cdf[w.len()], 1.0);
        assert_eq!(d.cdf[5], 4.0 / 8.0);
    }

    #[test]
    fn one_d_sample_is_consistent_and_skips_zero_bins() {
        // leading, inner and trailing zero bins
        let w = [0.0, 0.0, 2.5, 1e-3, 0.0, 7.0, 1.0, 0.0, 0.0];
        let d = Distribution1D::new(&w).unwrap();
        let mut us = uniforms(1, 20_000);
        us.extend(edge_uniforms(&d));
        let mut last = -1.0;
        us.sort_by(f64::total_cmp);
        for u in us {
            let s = d.sample(u);
            assert!((0.0..1.0).contains(&s.x), "u {u}: x {}", s.x);
            assert_eq!(bin_of(s.x, w.len()), s.bin, "u {u}: x {} outside its bin", s.x);
            assert!(w[s.bin] > 0.0, "u {u} sampled zero bin {}", s.bin);
            assert!(s.pdf > 0.0);
            assert_eq!(s.pdf.to_bits(), d.pdf(s.x).to_bits(), "u {u}");
            assert!(s.x >= last, "sampling is not monotone at u {u}");
            last = s.x;
        }
    }

    #[test]
    fn one_d_inverts_the_cdf() {
        // uniform weights: x = u up to rounding
        let d = Distribution1D::new(&[1.0; 10]).unwrap();
        for u in uniforms(2, 1000) {
            assert!((d.sample(u).x - u).abs() < 1e-15);
        }
        // two bins 1:3: u = 0.25 is the edge, u = 0.625 the middle of bin 1
        let d = Distribution1D::new(&[1.0, 3.0]).unwrap();
        assert_eq!(d.sample(0.125).x, 0.25);
        assert_eq!(d.sample(0.25).x, 0.5);
        assert_eq!(d.sample(0.625).x, 0.75);
        assert_eq!(d.sample(0.625).pdf, 1.5);
        // out-of-range uniforms stay in range
        assert_eq!(d.sample(-1.0).x, 0.0);
        assert_eq!(d.sample(f64::NAN).x, 0.0);
        assert!(d.sample(1.0).x < 1.0 && d.sample(7.0).x < 1.0);
    }

    fn grid() -> (Vec<f64>, usize, usize) {
        // 5 × 4: rows 0 and 3 all zero, zero cells in rows 1 and 2
        #[rustfmt::skip]
        let w = vec![
            0.0, 0.0, 0.0, 0.0, 0.0,
            1.0, 0.0, 2.0, 0.5, 0.0,
            0.0, 0.0, 0.0, 0.0, 9.0,
            0.0, 0.0, 0.0, 0.0, 0.0,
        ];
        (w, 5, 4)
    }

    #[test]
    fn two_d_pdf_integrates_to_one() {
        let (w, width, height) = grid();
        let d = Distribution2D::new(&w, width, height).unwrap();
        assert!((d.integral() - 12.5 / 20.0).abs() < 1e-15);
        let cells: f64 =
            (0..height).flat_map(|j| (0..width).map(move |i| [i, j])).map(|c| d.cell_pdf(c)).sum();
        assert!((cells / (width * height) as f64 - 1.0).abs() < 1e-14);
        // midpoint rule on a grid not aligned with the cells
        let n = 997;
        let mut total = 0.0;
        for a in 0..n {
            for b in 0..n {
                total += d.pdf([(a as f64 + 0.5) / n as f64, (b as f64 + 0.5) / n as f64]);
            }
        }
        let total = total / (n * n) as f64;
        assert!((total - 1.0).abs() < 5e-3, "{total}");
    }

    #[test]
    fn two_d_sample_is_consistent_and_skips_zero_cells() {
        let (w, width, height) = grid();
        let d = Distribution2D::new(&w, width, height).unwrap();
        let u0 = uniforms(3, 20_000);
        let u1 = uniforms(4, 20_000);
        let mut us: Vec<[f64; 2]> = u0.into_iter().zip(u1).map(|(a, b)| [a, b]).collect();
        // cdf edges in both dimensions, against each other
        for a in
            edge_uniforms(&d.conditional[1]).into_iter().chain(edge_uniforms(&d.conditional[2]))
        {
            for b in edge_uniforms(&d.marginal) {
                us.push([a, b]);
            }
        }
        for u in &us {
            let s = d.sample(*u);
            assert!(s.uv.iter().all(|x| (0.0..1.0).contains(x)), "{u:?}: {s:?}");
            let [i, j] = d.cell(s.uv);
            assert!(w[j * width + i] > 0.0, "{u:?} sampled zero cell ({i}, {j})");
            assert_eq!(s.pdf.to_bits(), d.pdf(s.uv).to_bits(), "{u:?}");
            assert_eq!(s.pdf, w[j * width + i] / d.integral());
        }
        // the random part lands in proportion to the weights (loose: ±5 σ)
        let n = 20_000.0;
        let mut counts = vec![0usize; width * height];
        for u in us.iter().take(20_000) {
            let [i, j] = d.cell(d.sample(*u).uv);
            counts[j * width + i] += 1;
        }
        let total: f64 = w.iter().sum();
        for (k, &c) in counts.iter().enumerate() {
            let p = w[k] / total;
            let sigma = (n * p * (1.0 - p)).sqrt();
            assert!((c as f64 - n * p).abs() <= 5.0 * sigma, "cell {k}: {c} vs {}", n * p);
        }
    }

    #[test]
    fn two_d_sample_is_the_product_of_marginal_and_conditional() {
        let (w, width, height) = grid();
        let d = Distribution2D::new(&w, width, height).unwrap();
        for u in uniforms(5, 200).chunks_exact(2) {
            let s = d.sample([u[0], u[1]]);
            let [i, j] = d.cell(s.uv);
            let product = d.marginal.bin_pdf(j) * d.conditional[j].bin_pdf(i);
            assert!((product / s.pdf - 1.0).abs() < 1e-14);
        }
    }
}
