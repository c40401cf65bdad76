//! Blackbody emission: Planck's law, CIE 1931 integration, linear Rec.709, a fast
//! log‑T lookup table for rendering, and the Cycles Principled Volume convention.
//!
//! # Maths and units (METHOD.md §2a)
//!
//! Spectral radiance per nanometre (Planck):
//!
//! ```text
//! B(λ, T) = 2hc² / (λ⁵ · expm1(c₂ / (λT))) · 1e-9      [W m⁻² sr⁻¹ nm⁻¹], λ in m inside
//! 2hc² = 1.19104e-16 W m² sr⁻¹,   c₂ = hc/k = 1.43878e-2 m K
//! ```
//!
//! `expm1` keeps full precision at huge T (x = c₂/λT → 0, where `exp(x) − 1` cancels);
//! at tiny T, `expm1` overflows to +∞ and B is correctly 0 (never NaN).
//!
//! Tristimulus values and colour (no normalisation by ∫ȳ = 106.86 nm, unlike pbrt-v4's
//! `BlackbodySpectrum`):
//!
//! ```text
//! (X, Y, Z)(T) = Σ_{λ=360}^{830} B(λ, T) · (x̄, ȳ, z̄)(λ) · Δλ,  Δλ = 1 nm    [W m⁻² sr⁻¹]
//! C(T)         = max(0, M₇₀₉ · (X, Y, Z))                                  [W m⁻² sr⁻¹]
//! ```
//!
//! `Y · 683 lm/W` is the photometric luminance in cd m⁻². The sum is the rectangle rule
//! on the 1 nm CIE grid (the endpoint weights are negligible: ȳ(360) = 4e-6). `M₇₀₉` is
//! XYZ → linear Rec.709 (D65), [`XYZ_TO_REC709`]. Below ≈ 1900 K the Planckian locus leaves
//! the Rec.709 gamut (blue < 0; green too below ≈ 900 K) and negative channels are
//! clamped to 0. Everything is computed in `f64` and cast at the end (METHOD §2 precision).
//!
//! # Table
//!
//! [`BlackbodyTable`] stores, on [`TABLE_NODES`] nodes uniform in ln T over
//! [`TABLE_MIN_KELVIN`] … [`TABLE_MAX_KELVIN`], `ln Y(T)` and the *unclamped* ratio
//! `C(T)/Y(T)` (luminance‑normalised Rec.709), both as `f32`, and interpolates both
//! linearly in ln T. `ln Y` varies smoothly (26 orders of magnitude in Y become a range of
//! ≈ 200 in ln Y) and `C/Y` is bounded (|C/Y| < 7.5), so the storage precision is ample;
//! T and B themselves are never stored (and never in f16, METHOD §10.6). The gamut clamp is
//! applied after interpolation. Accuracy against [`blackbody_rgb_exact`] over
//! 500 K … 1e7 K is checked by the test `table_matches_exact`.
//!
//! # Cycles Principled Volume convention
//!
//! [`cycles_blackbody`] reproduces Cycles' blackbody emission: `σ_SB·1e-6/π · T⁴ · Ĉ(T)`,
//! with `Ĉ = C/Y` (luminance 1), constant below 800 K, no cutoff, no density factor.
//! See its docs for the remaining differences from Cycles' own fit.
//!
//! # References
//!
//! - M. Planck (1901), *Ann. Phys.* 309(3), 553–563; constants: CODATA 2018
//!   (c₁L = 2hc² = 1.191042972e-16 W m² sr⁻¹, c₂ = 1.438776877e-2 m K), rounded as in METHOD §2.
//! - CIE 015:2018 *Colorimetry*; CMF data from CVRL, see `cie1931.rs`.
//! - IEC 61966-2-1 (sRGB) / ITU-R BT.709 primaries for `M₇₀₉` and the luminance weights.
//! - pbrt-v4, `src/pbrt/util/spectrum.h` (`BlackbodySpectrum`, normalised; we do not normalise).
//! - Blender Cycles, `intern/cycles/kernel/svm/closure.h` (`svm_node_principled_volume`) and
//!   `kernel/svm/math_util.h` (`svm_math_blackbody_color_rec709`).

use std::f64::consts::PI;
use std::sync::OnceLock;

use super::cie1931::{CIE1931_2DEG, CIE1931_LAMBDA_MAX_NM, CIE1931_LAMBDA_MIN_NM};
use super::{rec709_luminance, Rgb};

/// First radiation constant for spectral radiance, `2hc²`, in W m² sr⁻¹ (METHOD §2).
pub const TWO_HC2: f64 = 1.19104e-16;

/// Second radiation constant `c₂ = hc/k`, in m K (METHOD §2).
pub const C2: f64 = 1.43878e-2;

/// Stefan–Boltzmann constant σ_SB in W m⁻² K⁻⁴, the value Cycles uses.
pub const STEFAN_BOLTZMANN: f64 = 5.670373e-8;

/// XYZ → linear Rec.709 (D65) matrix, row major (METHOD §2).
pub const XYZ_TO_REC709: [[f64; 3]; 3] =
    [[3.2410, -1.5374, -0.4986], [-0.9692, 1.8760, 0.0416], [0.0556, -0.2040, 1.0570]];

/// Suggested blackbody cutoff temperature T_cut in kelvin: emission is 0 below it.
///
/// Nothing visible is lost: B(550 nm, 500 K) ≈ 4.5e-17 W m⁻² sr⁻¹ nm⁻¹, about 1e-17 of its
/// 2000 K value. And it keeps cold smoke (ambient ≈ 300 K) out of emission occupancy and
/// out of the emitted‑power proxy grid, which would otherwise count every smoky voxel
/// as a (hopelessly dim) light (METHOD §2; pbrt-v4 uses 100 K). Applied by callers, not by
/// the functions here; the Cycles look ([`cycles_blackbody`]) does not use it, because
/// Cycles still emits 1.5e-4 per unit length at 300 K.
pub const DEFAULT_CUTOFF_KELVIN: f32 = 500.0;

/// Lowest table temperature, K: [`BlackbodyTable::rgb`] and
/// [`BlackbodyTable::luminance`] are 0 below it (Y(100 K) ≈ 1e-76, far below `f32`).
pub const TABLE_MIN_KELVIN: f32 = 100.0;

/// Highest table temperature, K: table lookups (and [`cycles_blackbody`]) clamp T to it.
///
/// Temperatures this high are not flames but unit errors; clamping keeps every output
/// finite with headroom (Y(1e8 K) ≈ 9.5e11, σ/π·1e-6·T⁴ ≈ 1.8e18) instead of overflowing `f32`.
pub const TABLE_MAX_KELVIN: f32 = 1.0e8;

/// Number of table nodes, uniform in ln T (step ≈ 0.68 % in T).
///
/// Linear interpolation error scales with the step squared; 2048 nodes keep it at
/// ≈ 2e-4 relative over 500 K … 1e7 K (worst at the cold end; 1024 nodes give ≈ 8e-4) (test `table_matches_exact`).
pub const TABLE_NODES: usize = 2048;

/// At most this many threads build the table (see [`BlackbodyTable`]).
const MAX_BUILD_THREADS: usize = 8;

/// Below this temperature, K, the Cycles chromaticity Ĉ is held constant
/// ([`BlackbodyTable::chromaticity`]), as Cycles and OSL do.
pub const CHROMATICITY_FLOOR_KELVIN: f32 = 800.0;

/// Cycles holds its blackbody colour constant above this temperature.
pub const CYCLES_CHROMATICITY_CEILING_KELVIN: f32 = 12000.0;

/// Spectral radiance of a blackbody (Planck's law), in W m⁻² sr⁻¹ nm⁻¹.
///
/// `lambda_nm` is the wavelength in nm, `t_kelvin` the temperature in K. Returns 0 for
/// `t_kelvin ≤ 0`, for NaN, and for a non‑positive or NaN wavelength. Uses `expm1`, so it
/// is accurate at huge T and exactly 0 (not NaN) when `c₂/λT` overflows `exp` at tiny T.
/// Finite for every T up to ≈ 1e280 K (so for all of `f32`); `+∞` gives `+∞`.
#[must_use]
pub fn planck(lambda_nm: f64, t_kelvin: f64) -> f64 {
    if t_kelvin.is_nan() || t_kelvin <= 0.0 || lambda_nm.is_nan() || lambda_nm <= 0.0 {
        return 0.0;
    }
    let lambda_m = lambda_nm * 1e-9;
    let x = C2 / (lambda_m * t_kelvin);
    // Per metre of wavelength, times 1e-9 m/nm.
    TWO_HC2 * 1e-9 / (lambda_m.powi(5) * x.exp_m1())
}

/// CIE 1931 tristimulus values of a blackbody, `∫₃₆₀⁸³⁰ B(λ,T)·(x̄,ȳ,z̄) dλ`, in W m⁻² sr⁻¹.
///
/// dλ in nm, 1 nm steps (471 samples), accumulated in `f64`; no division by ∫ȳ.
/// `Y · 683` is the luminance in cd m⁻². Zero for `t_kelvin ≤ 0` or NaN.
#[must_use]
pub fn blackbody_xyz(t_kelvin: f64) -> [f64; 3] {
    let mut xyz = [0.0; 3];
    if t_kelvin.is_nan() || t_kelvin <= 0.0 {
        return xyz;
    }
    for (lambda_nm, cmf) in (CIE1931_LAMBDA_MIN_NM..=CIE1931_LAMBDA_MAX_NM).zip(&CIE1931_2DEG) {
        // Δλ = 1 nm.
        let b = planck(f64::from(lambda_nm), t_kelvin);
        for (sum, weight) in xyz.iter_mut().zip(cmf) {
            *sum += b * weight;
        }
    }
    xyz
}

/// CIE XYZ → linear Rec.709 (D65) with [`XYZ_TO_REC709`]; no clamping.
#[must_use]
pub fn xyz_to_rec709(xyz: [f64; 3]) -> [f64; 3] {
    XYZ_TO_REC709.map(|row| row[0] * xyz[0] + row[1] * xyz[1] + row[2] * xyz[2])
}

/// Blackbody colour C(T) in linear Rec.709, W m⁻² sr⁻¹, with negative channels clamped to 0.
///
/// The reference for [`BlackbodyTable`]: 471 Planck evaluations per call, so do not use
/// it per sample. Below ≈ 1900 K blue is clamped (out of gamut); below ≈ 900 K green too.
/// Zero for `t_kelvin ≤ 0` or NaN. Intended for finite T (`+∞` gives NaN).
#[must_use]
pub fn blackbody_rgb_exact(t_kelvin: f64) -> [f64; 3] {
    xyz_to_rec709(blackbody_xyz(t_kelvin)).map(|c| c.max(0.0))
}

/// [`blackbody_xyz`] with the per‑wavelength factors hoisted out, for building the table.
///
/// Per λ it stores `2hc²·1e-9/λ⁵ · (x̄, ȳ, z̄)` and `c₂/λ`, so one term costs one
/// exponential, one multiply and one divide. For `x = c₂/λT ≥ 1` it uses `exp(x) − 1`
/// (exact to an ulp there, as `exp(x) ≥ e`, and about twice as fast as `expm1`);
/// below 1 it uses `expm1`, where the subtraction would cancel. Agrees with
/// [`blackbody_xyz`] to ≈ 1e-15 relative (test `fast_xyz_matches_blackbody_xyz`).
struct PlanckCmf {
    /// `2hc²·1e-9/λ⁵ · (x̄, ȳ, z̄)(λ)` per 1 nm row, W m⁻² sr⁻¹ nm⁻¹.
    weighted_cmf: [[f64; 3]; CIE1931_2DEG.len()],
    /// `c₂/λ` per row, K.
    c2_over_lambda: [f64; CIE1931_2DEG.len()],
}

impl PlanckCmf {
    fn new() -> PlanckCmf {
        let mut weighted_cmf = [[0.0; 3]; CIE1931_2DEG.len()];
        let mut c2_over_lambda = [0.0; CIE1931_2DEG.len()];
        let wavelengths = CIE1931_LAMBDA_MIN_NM..=CIE1931_LAMBDA_MAX_NM;
        for (i, (lambda_nm, cmf)) in wavelengths.zip(&CIE1931_2DEG).enumerate() {
            let lambda_m = f64::from(lambda_nm) * 1e-9;
            let scale = TWO_HC2 * 1e-9 / lambda_m.powi(5);
            weighted_cmf[i] = cmf.map(|w| scale * w);
            c2_over_lambda[i] = C2 / lambda_m;
        }
        PlanckCmf { weighted_cmf, c2_over_lambda }
    }

    /// Same as [`blackbody_xyz`] for `t_kelvin > 0`.
    fn xyz(&self, t_kelvin: f64) -> [f64; 3] {
        let mut xyz = [0.0; 3];
        for (weights, c2_over_lambda) in self.weighted_cmf.iter().zip(&self.c2_over_lambda) {
            let x = c2_over_lambda / t_kelvin;
            let denominator = if x >= 1.0 { x.exp() - 1.0 } else { x.exp_m1() };
            // +∞ when exp overflows: the term is then exactly 0, as in `planck`.
            let inverse = 1.0 / denominator;
            for (sum, weight) in xyz.iter_mut().zip(weights) {
                *sum += weight * inverse;
            }
        }
        xyz
    }
}

/// Blackbody colour tabulated on a log‑T axis for fast lookups during rendering.
///
/// Built once per process by [`blackbody_table`]. Nodes `T_k = T_min·(T_max/T_min)^(k/(N−1))`,
/// `N =` [`TABLE_NODES`], hold `ln Y(T_k)` and the unclamped `C(T_k)/Y(T_k)`, computed in
/// `f64` by the sum of [`blackbody_xyz`] and stored as `f32`. Lookups interpolate both linearly in
/// ln T and clamp negative channels afterwards.
///
/// NOTE: building costs milliseconds of CPU (965k Planck terms), spread over up to 8
/// threads: cheap enough to compute at start-up rather than ship as data. See the ignored
/// test `table_build_time`.
#[derive(Clone, Debug)]
pub struct BlackbodyTable {
    /// ln of the first node temperature, ln K.
    ln_t_min: f64,
    /// Nodes per unit of ln T, `(N − 1) / ln(T_max / T_min)`.
    nodes_per_ln_t: f64,
    /// ln Y(T_k), Y in W m⁻² sr⁻¹.
    ln_y: Vec<f32>,
    /// C(T_k)/Y(T_k), unclamped linear Rec.709 per unit CIE Y (dimensionless).
    rgb_over_y: Vec<[f32; 3]>,
    /// Ĉ at [`CHROMATICITY_FLOOR_KELVIN`], from the table itself (continuous at 800 K).
    chromaticity_floor: Rgb,
    /// C(T) tabulated uniformly in T over the range fires live in ([`UNIFORM_SEGMENTS`]),
    /// from the ln-T table's own values, so [`BlackbodyTable::rgb`] needs no `ln` there.
    uniform: Vec<[f32; 3]>,
}

/// The T-uniform segments of [`BlackbodyTable::rgb`]: `(first K, last K, nodes)`. Y(T) is
/// exponential at low T (`∂ ln Y/∂T ≈ c₂/(λT²)`, 10 % per K at 500 K), so the first
/// segment is fine (0.05 K) and the second coarser (0.6 K); a node step changes C by at
/// most ≈ 0.5 % above 500 K, so linear interpolation is within ≈ 3e-6 of the ln-T table
/// (tested), far inside its 1e-3 agreement with the exact integral.
const UNIFORM_SEGMENTS: [(f64, f64, usize); 2] =
    [(100.0, 2000.0, 38_001), (2000.0, 20000.0, 30_001)];

/// One interpolated table lookup.
struct TableSample {
    /// ln Y, Y in W m⁻² sr⁻¹.
    ln_y: f64,
    /// Unclamped C/Y.
    rgb_over_y: [f64; 3],
}

impl BlackbodyTable {
    /// Tabulates [`TABLE_NODES`] temperatures (see the struct docs) on up to
    /// [`MAX_BUILD_THREADS`] threads.
    fn build() -> BlackbodyTable {
        let threads = std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get);
        BlackbodyTable::build_with_threads(threads.clamp(1, MAX_BUILD_THREADS))
    }

    /// [`BlackbodyTable::build`] on exactly `threads ≥ 1` threads; same bits for any count.
    fn build_with_threads(threads: usize) -> BlackbodyTable {
        assert!(threads >= 1, "need at least one thread");
        let ln_t_min = f64::from(TABLE_MIN_KELVIN).ln();
        let ln_t_max = f64::from(TABLE_MAX_KELVIN).ln();
        let nodes_per_ln_t = (TABLE_NODES - 1) as f64 / (ln_t_max - ln_t_min);
        let node_kelvin = move |k: usize| (ln_t_min + k as f64 / nodes_per_ln_t).exp();

        // Integrate every node (965k Planck terms), interleaved
        // over a few scoped threads (node k on thread k mod n: high T, where `expm1` is
        // slower, is spread evenly). Nodes are independent and each is summed in a fixed
        // order, so the table is bit-identical for any thread count.
        let spectrum = PlanckCmf::new();
        let strided = |first: usize| -> Vec<[f64; 3]> {
            (first..TABLE_NODES).step_by(threads).map(|k| spectrum.xyz(node_kelvin(k))).collect()
        };
        let per_thread: Vec<Vec<[f64; 3]>> = std::thread::scope(|scope| {
            let handles: Vec<_> =
                (1..threads).map(|first| scope.spawn(move || strided(first))).collect();
            let mut per_thread = vec![strided(0)];
            for handle in handles {
                per_thread
                    .push(handle.join().unwrap_or_else(|panic| std::panic::resume_unwind(panic)));
            }
            per_thread
        });
        let xyz = (0..TABLE_NODES).map(|k| per_thread[k % threads][k / threads]);

        let mut ln_y = Vec::with_capacity(TABLE_NODES);
        let mut rgb_over_y = Vec::with_capacity(TABLE_NODES);
        for (k, xyz) in xyz.enumerate() {
            // Y(100 K) ≈ 1e-76 is still a normal f64 (> 2e-308), so ln Y is finite.
            debug_assert!(
                xyz[1] > 0.0 && xyz[1].is_finite(),
                "Y({} K) = {}",
                node_kelvin(k),
                xyz[1]
            );
            ln_y.push(xyz[1].ln() as f32);
            rgb_over_y.push(xyz_to_rec709(xyz).map(|c| (c / xyz[1]) as f32));
        }
        let mut table = BlackbodyTable {
            ln_t_min,
            nodes_per_ln_t,
            ln_y,
            rgb_over_y,
            chromaticity_floor: Rgb::ZERO,
            uniform: Vec::new(),
        };
        table.chromaticity_floor = table.normalized_chromaticity(CHROMATICITY_FLOOR_KELVIN);
        let mut uniform = Vec::with_capacity(UNIFORM_SEGMENTS.iter().map(|s| s.2).sum());
        for (lo, hi, n) in UNIFORM_SEGMENTS {
            uniform
                .extend((0..n).map(|k| {
                    table.rgb_ln_t((lo + (hi - lo) * k as f64 / (n - 1) as f64) as f32).0
                }));
        }
        table.uniform = uniform;
        table
    }

    /// Interpolated `ln Y` and `C/Y` at `t` (clamped to [`TABLE_MAX_KELVIN`]);
    /// `None` below [`TABLE_MIN_KELVIN`] or for NaN.
    fn sample(&self, t_kelvin: f32) -> Option<TableSample> {
        // NaN counts as 0 K.
        if t_kelvin.is_nan() || t_kelvin < TABLE_MIN_KELVIN {
            return None;
        }
        let t = f64::from(t_kelvin.min(TABLE_MAX_KELVIN));
        let last = (TABLE_NODES - 1) as f64;
        let u = ((t.ln() - self.ln_t_min) * self.nodes_per_ln_t).clamp(0.0, last);
        // u ∈ [0, N−1]; the last node interpolates from the interval below it with f = 1.
        let i = (u as usize).min(TABLE_NODES - 2);
        let f = u - i as f64;
        let lerp = |a: f32, b: f32| f64::from(a) + f * (f64::from(b) - f64::from(a));
        let (c0, c1) = (self.rgb_over_y[i], self.rgb_over_y[i + 1]);
        Some(TableSample {
            ln_y: lerp(self.ln_y[i], self.ln_y[i + 1]),
            rgb_over_y: [lerp(c0[0], c1[0]), lerp(c0[1], c1[1]), lerp(c0[2], c1[2])],
        })
    }

    /// Clamped C/Y renormalised to Rec.709 luminance 1, for `t ≥ 800 K`.
    fn normalized_chromaticity(&self, t_kelvin: f32) -> Rgb {
        let sample =
            self.sample(t_kelvin).expect("invariant: called only for T >= 800 K, inside the table");
        let clamped = sample.rgb_over_y.map(|c| c.max(0.0));
        // Red dominates below the white point and never clamps, so the luminance is > 0.
        let luminance = rec709_luminance(clamped);
        Rgb(clamped.map(|c| (c / luminance) as f32))
    }

    /// Blackbody colour C(T) in linear Rec.709, W m⁻² sr⁻¹, negatives clamped to 0.
    ///
    /// `exp(ln Y) · C/Y`, interpolated linearly in ln T. Zero below [`TABLE_MIN_KELVIN`]
    /// and for NaN (a NaN temperature is treated as 0 K); T above [`TABLE_MAX_KELVIN`]
    /// (including +∞) is clamped to it. No cutoff: callers apply [`DEFAULT_CUTOFF_KELVIN`].
    /// Agrees with [`blackbody_rgb_exact`] to < 1e-3 relative over 500 K … 1e7 K.
    ///
    /// Between 100 K and 20 000 K from a table uniform in T (no `ln`; see
    /// `UNIFORM_SEGMENTS`), above from the ln-T table.
    #[must_use]
    #[inline]
    pub fn rgb(&self, t_kelvin: f32) -> Rgb {
        let t = f64::from(t_kelvin);
        let mut base = 0;
        for (lo, hi, n) in UNIFORM_SEGMENTS {
            if t >= lo && t <= hi {
                let u = (t - lo) * ((n - 1) as f64 / (hi - lo));
                let i = (u as usize).min(n - 2);
                let f = u - i as f64;
                let (a, b) = (self.uniform[base + i], self.uniform[base + i + 1]);
                return Rgb(std::array::from_fn(|c| {
                    (f64::from(a[c]) + f * (f64::from(b[c]) - f64::from(a[c]))) as f32
                }));
            }
            base += n;
        }
        self.rgb_ln_t(t_kelvin)
    }

    /// [`BlackbodyTable::rgb`] from the ln-T table.
    fn rgb_ln_t(&self, t_kelvin: f32) -> Rgb {
        match self.sample(t_kelvin) {
            None => Rgb::ZERO,
            Some(s) => {
                let y = s.ln_y.exp();
                Rgb(s.rgb_over_y.map(|c| (y * c).max(0.0) as f32))
            }
        }
    }

    /// Chromaticity Ĉ(T): the gamut‑clamped C(T) scaled to Rec.709 luminance 1.
    ///
    /// Constant below [`CHROMATICITY_FLOOR_KELVIN`] (800 K), where it takes the 800 K
    /// value, as in Cycles; NaN is treated as 0 K, so it also gets the 800 K value. T above
    /// [`TABLE_MAX_KELVIN`] is clamped. Above ≈ 1900 K (nothing clamped) this equals
    /// C/Y up to the rounding of [`XYZ_TO_REC709`] (≈ 1e-4).
    #[must_use]
    pub fn chromaticity(&self, t_kelvin: f32) -> Rgb {
        // NaN counts as 0 K.
        if t_kelvin.is_nan() || t_kelvin < CHROMATICITY_FLOOR_KELVIN {
            return self.chromaticity_floor;
        }
        self.normalized_chromaticity(t_kelvin)
    }

    /// Cycles' chromaticity: the *unclamped* C/Y (negative blue below ≈ 1900 K, negative
    /// green below ≈ 900 K, as Cycles renders them), held constant below
    /// [`CHROMATICITY_FLOOR_KELVIN`] and above [`CYCLES_CHROMATICITY_CEILING_KELVIN`]
    /// exactly as Cycles' `svm_math_blackbody_color_rec709` does.
    #[must_use]
    pub fn cycles_chromaticity(&self, t_kelvin: f32) -> Rgb {
        let t = if t_kelvin.is_nan() {
            0.0
        } else {
            t_kelvin.clamp(CHROMATICITY_FLOOR_KELVIN, CYCLES_CHROMATICITY_CEILING_KELVIN)
        };
        let s = self.sample(t).expect("invariant: 800 K ..= 12000 K lies inside the table");
        Rgb(s.rgb_over_y.map(|c| c as f32))
    }

    /// CIE luminance Y(T) in W m⁻² sr⁻¹ (times 683 lm/W for cd m⁻²), before gamut clamping.
    ///
    /// Zero below [`TABLE_MIN_KELVIN`] and for NaN; T above [`TABLE_MAX_KELVIN`] is clamped.
    /// Below ≈ 1900 K this exceeds `rgb(t).luminance()`, which has the negative channels
    /// removed.
    #[must_use]
    pub fn luminance(&self, t_kelvin: f32) -> f64 {
        self.sample(t_kelvin).map_or(0.0, |s| s.ln_y.exp())
    }
}

/// The process‑wide [`BlackbodyTable`], built on first use (milliseconds of CPU) and then shared.
///
/// Call it once before rendering (e.g. while building the scene) so that no render thread
/// waits on the build.
#[must_use]
pub fn blackbody_table() -> &'static BlackbodyTable {
    static TABLE: OnceLock<BlackbodyTable> = OnceLock::new();
    TABLE.get_or_init(BlackbodyTable::build)
}

/// Nodes of [`CyclesChromaticityTable`] over [`CHROMATICITY_FLOOR_KELVIN`] …
/// [`CYCLES_CHROMATICITY_CEILING_KELVIN`] (0.68 K apart).
const CYCLES_NODES: usize = 16384;

/// Cycles' chromaticity ([`BlackbodyTable::cycles_chromaticity`]) tabulated *uniformly in
/// T* over 800 … 12000 K, the only range where it varies: a lookup is one multiply and a
/// lerp, without the logarithm of the ln-T table (volume rendering in Cycles' convention
/// evaluates it at every emitting voxel a ray meets, so `ln` and the ln-T lookup would sit
/// on the hot path). The nodes are the ln-T table's own values, 0.68 K apart,
/// so the two agree to ≈ 1e-7 relative (tested).
struct CyclesChromaticityTable {
    nodes_per_kelvin: f64,
    rgb: Vec<[f32; 3]>,
}

impl CyclesChromaticityTable {
    fn build() -> CyclesChromaticityTable {
        let (lo, hi) =
            (f64::from(CHROMATICITY_FLOOR_KELVIN), f64::from(CYCLES_CHROMATICITY_CEILING_KELVIN));
        let step = (hi - lo) / (CYCLES_NODES - 1) as f64;
        let table = blackbody_table();
        let rgb = (0..CYCLES_NODES)
            .map(|k| table.cycles_chromaticity((lo + k as f64 * step) as f32).0)
            .collect();
        CyclesChromaticityTable { nodes_per_kelvin: 1.0 / step, rgb }
    }

    /// The chromaticity at `t` (clamped to 800 … 12000 K, as Cycles holds it).
    #[inline]
    fn at(&self, t: f64) -> [f64; 3] {
        let u = ((t - f64::from(CHROMATICITY_FLOOR_KELVIN)) * self.nodes_per_kelvin)
            .clamp(0.0, (CYCLES_NODES - 1) as f64);
        let i = (u as usize).min(CYCLES_NODES - 2);
        let f = u - i as f64;
        let (a, b) = (self.rgb[i], self.rgb[i + 1]);
        std::array::from_fn(|c| f64::from(a[c]) + f * (f64::from(b[c]) - f64::from(a[c])))
    }
}

fn cycles_table() -> &'static CyclesChromaticityTable {
    static TABLE: OnceLock<CyclesChromaticityTable> = OnceLock::new();
    TABLE.get_or_init(CyclesChromaticityTable::build)
}

/// Cycles Principled Volume blackbody emission for temperature `t_kelvin`, per unit length.
///
/// `σ_SB/π · 1e-6 · T⁴ · Ĉ(T)` with σ_SB = [`STEFAN_BOLTZMANN`] and Ĉ =
/// [`BlackbodyTable::chromaticity`] (luminance 1, constant below 800 K): Cycles'
/// `svm_node_principled_volume` with Blackbody Intensity 1, a white tint and an object
/// density of 1. No temperature cutoff and no density factor, as in Cycles (METHOD §2).
/// `T` is the Temperature socket times the temperature grid; negative T and NaN give 0,
/// and T above [`TABLE_MAX_KELVIN`] is clamped so the result stays finite (Cycles would
/// overflow `f32` only above 1.8e19 K).
///
/// Blackbody Intensity `i` (not exposed) would replace `T⁴` by `(1 − i) + i·T⁴`.
///
/// Ĉ is [`BlackbodyTable::cycles_chromaticity`]: like Cycles, it is not gamut-clamped
/// (below ≈ 1900 K blue is negative, as in Cycles' renders) and it is constant outside
/// 800 K … 12000 K. Against Cycles' own fit our unclamped values agree to about 0.1 %
/// ((5.407, −0.201, −0.0824) at 800 K vs Cycles' (5.413, −0.203, −0.082)).
#[must_use]
pub fn cycles_blackbody(t_kelvin: f32) -> Rgb {
    let t = if t_kelvin.is_nan() { 0.0 } else { f64::from(t_kelvin.clamp(0.0, TABLE_MAX_KELVIN)) };
    let intensity = STEFAN_BOLTZMANN / PI * 1e-6 * (t * t) * (t * t);
    let chromaticity = cycles_table().at(t);
    Rgb(chromaticity.map(|c| (intensity * c) as f32))
}

#[cfg(test)]
mod tests;
