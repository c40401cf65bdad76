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
use super::Rgb;

/// First radiation constant for spectral radiance, `2hc²`, in W m² sr⁻¹ (METHOD §2).
pub const TWO_HC2: f64 = 1.19104e-16;

/// Second radiation constant `c₂ = hc/k`, in m K (METHOD §2).
pub const C2: f64 = 1.43878e-2;

/// Stefan–Boltzmann constant σ_SB in W m⁻² K⁻⁴, the value Cycles uses.
pub const STEFAN_BOLTZMANN: f64 = 5.670373e-8;

/// XYZ → linear Rec.709 (D65) matrix, row major (METHOD §2).
pub const XYZ_TO_REC709: [[f64; 3]; 3] = [
    [3.2410, -1.5374, -0.4986],
    [-0.9692, 1.8760, 0.0416],
    [0.0556, -0.2040, 1.0570],
];

/// Rec.709 luminance weights `(0.2126, 0.7152, 0.0722)` in `f64`, as in [`Rgb::luminance`].
const REC709_LUMINANCE: [f64; 3] = [0.2126, 0.7152, 0.0722];

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

/// Rec.709 luminance of an `f64` triple (weights of [`Rgb::luminance`]).
fn rec709_luminance(rgb: [f64; 3]) -> f64 {
    REC709_LUMINANCE[0] * rgb[0] + REC709_LUMINANCE[1] * rgb[1] + REC709_LUMINANCE[2] * rgb[2]
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
        PlanckCmf {
            weighted_cmf,
            c2_over_lambda,
        }
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
/// NOTE: building costs ≈ 11 ms of CPU (965k Planck terms at ≈ 11 ns) on one core of the
/// shared 2‑core dev VM (opt-level 2), spread over up to 8 threads; ≈ 12 ms wall there
/// with the second core busy. See the ignored test `table_build_time`.
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
}

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

        // Integrate every node (965k Planck terms, ≈ 11 ms on one core here), interleaved
        // over a few scoped threads (node k on thread k mod n: high T, where `expm1` is
        // slower, is spread evenly). Nodes are independent and each is summed in a fixed
        // order, so the table is bit-identical for any thread count.
        let spectrum = PlanckCmf::new();
        let strided = |first: usize| -> Vec<[f64; 3]> {
            (first..TABLE_NODES)
                .step_by(threads)
                .map(|k| spectrum.xyz(node_kelvin(k)))
                .collect()
        };
        let per_thread: Vec<Vec<[f64; 3]>> = std::thread::scope(|scope| {
            let handles: Vec<_> = (1..threads)
                .map(|first| scope.spawn(move || strided(first)))
                .collect();
            let mut per_thread = vec![strided(0)];
            for handle in handles {
                per_thread.push(
                    handle
                        .join()
                        .unwrap_or_else(|panic| std::panic::resume_unwind(panic)),
                );
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
        };
        table.chromaticity_floor = table.normalized_chromaticity(CHROMATICITY_FLOOR_KELVIN);
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
        let sample = self
            .sample(t_kelvin)
            .expect("invariant: called only for T >= 800 K, inside the table");
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
    #[must_use]
    pub fn rgb(&self, t_kelvin: f32) -> Rgb {
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
        let t = if t_kelvin.is_nan() { 0.0 } else { t_kelvin.clamp(CHROMATICITY_FLOOR_KELVIN, CYCLES_CHROMATICITY_CEILING_KELVIN) };
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

/// The process‑wide [`BlackbodyTable`], built on first use (≈ 11 ms CPU) and then shared.
///
/// Call it once before rendering (e.g. while building the scene) so that no render thread
/// waits on the build.
#[must_use]
pub fn blackbody_table() -> &'static BlackbodyTable {
    static TABLE: OnceLock<BlackbodyTable> = OnceLock::new();
    TABLE.get_or_init(BlackbodyTable::build)
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
    let t = if t_kelvin.is_nan() {
        0.0
    } else {
        t_kelvin.clamp(0.0, TABLE_MAX_KELVIN)
    };
    let intensity = STEFAN_BOLTZMANN / PI * 1e-6 * f64::from(t).powi(4);
    let chromaticity = blackbody_table().cycles_chromaticity(t);
    Rgb(chromaticity.0.map(|c| (intensity * f64::from(c)) as f32))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn assert_rel(actual: f64, expected: f64, tolerance: f64, what: &str) {
        let rel = (actual / expected - 1.0).abs();
        assert!(
            rel <= tolerance,
            "{what}: {actual:e} vs {expected:e} (rel {rel:e} > {tolerance:e})"
        );
    }

    /// Temperatures that must never produce NaN or ∞ (NaN is treated as 0 K).
    const EDGE_TEMPERATURES: [f32; 12] = [
        0.0,
        1e-3,
        1.0,
        100.0,
        499.0,
        500.0,
        1e4,
        1e7,
        1e8,
        f32::MAX,
        f32::INFINITY,
        f32::NAN,
    ];

    #[test]
    fn planck_matches_method_range() {
        // METHOD §10.6: B(550 nm) at 500 K, 2000 K, 1e7 K.
        assert_rel(planck(550.0, 500.0), 4.5e-17, 0.02, "B(550, 500 K)");
        assert_rel(planck(550.0, 2000.0), 4.9, 0.02, "B(550, 2000 K)");
        assert_rel(planck(550.0, 1e7), 9.0e8, 0.02, "B(550, 1e7 K)");
    }

    #[test]
    fn planck_edge_cases() {
        assert_eq!(planck(550.0, 0.0), 0.0);
        assert_eq!(planck(550.0, -300.0), 0.0);
        assert_eq!(planck(550.0, f64::NAN), 0.0);
        assert_eq!(planck(f64::NAN, 1000.0), 0.0);
        assert_eq!(planck(0.0, 1000.0), 0.0);
        // exp overflows: exactly 0, not NaN.
        assert_eq!(planck(550.0, 1e-3), 0.0);
        assert_eq!(planck(360.0, 1.0), 0.0);
        for t in [1e8, f64::from(f32::MAX)] {
            for lambda in [360.0, 550.0, 830.0] {
                let b = planck(lambda, t);
                assert!(b.is_finite() && b > 0.0, "B({lambda}, {t}) = {b}");
            }
        }
        // Rayleigh–Jeans regime, x = c₂/λT = 2.6e-11: 1/expm1(x) = 1/x − 1/2 + O(x). A naive
        // exp(x) − 1 would be off by ≈ 4e-6 relative here; expm1 is exact to rounding.
        let (lambda_m, t) = (550e-9f64, 1e15);
        let x = C2 / (lambda_m * t);
        let series = TWO_HC2 * 1e-9 / lambda_m.powi(5) * (1.0 / x - 0.5);
        assert_rel(planck(550.0, t), series, 1e-12, "Rayleigh–Jeans");
    }

    #[test]
    fn planck_integrates_to_stefan_boltzmann() {
        // ∫₀^∞ B dλ = σT⁴/π; with METHOD's rounded constants σ comes out within 1.1e-5 of
        // Cycles' 5.670373e-8. Simpson in s = ln λ over [λ_peak/50, 2000·λ_peak]: the
        // tails beyond hold < 1e-7 of the total.
        for t in [500.0f64, 2000.0, 6500.0, 1e5, 1e7] {
            let lambda_peak_nm = 2.897771955e6 / t;
            let (s0, s1) = ((lambda_peak_nm / 50.0).ln(), (lambda_peak_nm * 2000.0).ln());
            let n = 20_000;
            let h = (s1 - s0) / n as f64;
            let integral: f64 = (0..=n)
                .map(|k| {
                    let lambda = (s0 + k as f64 * h).exp();
                    let weight = if k == 0 || k == n {
                        1.0
                    } else if k % 2 == 1 {
                        4.0
                    } else {
                        2.0
                    };
                    weight * planck(lambda, t) * lambda
                })
                .sum::<f64>()
                * h
                / 3.0;
            assert_rel(
                integral,
                STEFAN_BOLTZMANN * t.powi(4) / PI,
                1e-4,
                "∫B dλ vs σT⁴/π",
            );
        }
    }

    #[test]
    fn cmf_table_integrals() {
        assert_eq!(
            CIE1931_2DEG.len() as u32,
            CIE1931_LAMBDA_MAX_NM - CIE1931_LAMBDA_MIN_NM + 1
        );
        let sums = CIE1931_2DEG.iter().fold([0.0f64; 3], |acc, row| {
            [acc[0] + row[0], acc[1] + row[1], acc[2] + row[2]]
        });
        assert!((sums[1] - 106.86).abs() < 0.05, "∫ȳ dλ = {} nm", sums[1]);
        // Equal-energy white: the three integrals agree to 0.04 %.
        assert!((sums[0] - sums[1]).abs() < 0.05 && (sums[2] - sums[1]).abs() < 0.05);
        // ȳ peaks at 1 at 555 nm.
        assert_eq!(CIE1931_2DEG[555 - 360][1], 1.0);
    }

    #[test]
    fn fast_xyz_matches_blackbody_xyz() {
        let spectrum = PlanckCmf::new();
        for t in [100.0, 500.0, 1234.5, 2000.0, 6500.0, 3e4, 1e6, 1e8] {
            let (fast, reference) = (spectrum.xyz(t), blackbody_xyz(t));
            for k in 0..3 {
                assert_rel(fast[k], reference[k], 1e-13, "PlanckCmf vs blackbody_xyz");
            }
        }
    }

    #[test]
    fn chromaticity_of_6504_k_on_planckian_locus() {
        let [x, y, z] = blackbody_xyz(6504.0);
        let (cx, cy) = (x / (x + y + z), y / (x + y + z));
        assert!(
            (cx - 0.3135).abs() < 0.002 && (cy - 0.3237).abs() < 0.002,
            "(x, y) = ({cx}, {cy})"
        );
    }

    #[test]
    fn xyz_to_rec709_luminance_row() {
        // The Rec.709 luminance of M·XYZ is Y, up to the 4-digit rounding of M.
        let rgb = xyz_to_rec709([0.3, 0.7, 0.2]);
        assert!((rec709_luminance(rgb) - 0.7).abs() < 1e-4);
        assert_eq!(xyz_to_rec709([0.0, 1.0, 0.0]), [-1.5374, 1.8760, -0.2040]);
    }

    #[test]
    fn rgb_exact_out_of_gamut_at_1000_k() {
        let c = blackbody_rgb_exact(1000.0);
        assert!(c.iter().all(|v| v.is_finite()), "{c:?}");
        assert_eq!(c[2], 0.0, "blue is out of gamut at 1000 K: {c:?}");
        assert!(c[0] > 0.0 && c[1] > 0.0, "{c:?}");
        // Unclamped blue is negative there.
        assert!(xyz_to_rec709(blackbody_xyz(1000.0))[2] < 0.0);
        // In gamut at 2000 K.
        assert!(blackbody_rgb_exact(2000.0).iter().all(|&v| v > 0.0));
    }

    #[test]
    fn luminance_grows_steeply_and_monotonically() {
        let y = |t: f64| blackbody_xyz(t)[1];
        let ratio = y(2000.0) / y(1000.0);
        assert!(ratio > 1e5, "Y(2000 K)/Y(1000 K) = {ratio:e}");
        let mut previous = 0.0;
        for k in 0..=400 {
            let t = 500.0 * (2e4f64).powf(f64::from(k) / 400.0);
            let yt = y(t);
            assert!(yt > previous, "Y not increasing at {t} K");
            previous = yt;
        }
        // The table too, on a finer grid.
        let table = blackbody_table();
        let mut previous = 0.0;
        for k in 0..=20_000 {
            let t = 500.0 * 2e4f32.powf(k as f32 / 20_000.0);
            let yt = table.luminance(t);
            assert!(yt >= previous, "table Y not increasing at {t} K");
            previous = yt;
        }
    }

    /// Table vs [`blackbody_rgb_exact`] over 500 K … 1e7 K at the quarter, half and
    /// three-quarter points of every table interval (linear interpolation is worst at
    /// the midpoints). Measured (2048 nodes): luminance 2.0e-4, colour 2.0e-4 of the
    /// largest channel, both at the cold end.
    #[test]
    fn table_matches_exact() {
        let table = blackbody_table();
        let (mut max_luminance_error, mut max_rgb_error) = (0.0f64, 0.0f64);
        let (mut worst_luminance_t, mut worst_rgb_t) = (0.0, 0.0);
        for k in 0..TABLE_NODES - 1 {
            for f in [0.25, 0.5, 0.75] {
                let t = (table.ln_t_min + (k as f64 + f) / table.nodes_per_ln_t).exp() as f32;
                if !(500.0..=1e7).contains(&t) {
                    continue;
                }
                // Compare at the f32 temperature the table actually sees.
                let xyz = blackbody_xyz(f64::from(t));
                let exact = xyz_to_rec709(xyz).map(|c| c.max(0.0));
                let luminance_error = (table.luminance(t) / xyz[1] - 1.0).abs();
                let approx = table.rgb(t).to_f64();
                let largest = exact.iter().fold(0.0f64, |m, &c| m.max(c));
                let rgb_error = (0..3)
                    .map(|c| (approx[c] - exact[c]).abs())
                    .fold(0.0, f64::max)
                    / largest;
                if luminance_error > max_luminance_error {
                    (max_luminance_error, worst_luminance_t) = (luminance_error, t);
                }
                if rgb_error > max_rgb_error {
                    (max_rgb_error, worst_rgb_t) = (rgb_error, t);
                }
            }
        }
        eprintln!(
            "table max relative error over 500 K..1e7 K: luminance {max_luminance_error:.2e} \
             (at {worst_luminance_t} K), rgb {max_rgb_error:.2e} of largest channel \
             (at {worst_rgb_t} K)"
        );
        assert!(
            max_luminance_error < 1e-3,
            "luminance error {max_luminance_error:e}"
        );
        assert!(max_rgb_error < 1e-3, "rgb error {max_rgb_error:e}");
    }

    #[test]
    fn table_exact_at_nodes_and_zero_below() {
        let table = blackbody_table();
        assert!(table.rgb(99.0).is_black());
        assert_eq!(table.luminance(99.0), 0.0);
        // At 2000 K (no clamping) the table agrees with the exact colour.
        let exact = blackbody_rgb_exact(2000.0);
        let approx = table.rgb(2000.0).to_f64();
        for c in 0..3 {
            assert_rel(approx[c], exact[c], 1e-3, "C(2000 K)");
        }
        // Above the table, T is clamped.
        assert_eq!(table.rgb(1e9), table.rgb(TABLE_MAX_KELVIN));
        assert_eq!(
            table.luminance(f32::INFINITY),
            table.luminance(TABLE_MAX_KELVIN)
        );
    }

    #[test]
    fn chromaticity_has_unit_luminance_and_floor() {
        let table = blackbody_table();
        for t in [800.0, 3000.0, 1e6] {
            let luminance = table.chromaticity(t).luminance();
            assert!(
                (luminance - 1.0).abs() < 1e-5,
                "Ĉ({t} K) luminance {luminance}"
            );
        }
        let floor = table.chromaticity(800.0);
        for t in [0.0, 1.0, 300.0, 799.9, f32::NAN, -5.0] {
            assert_eq!(table.chromaticity(t), floor, "Ĉ({t} K) should be Ĉ(800 K)");
        }
        // At 800 K green and blue are out of gamut: pure red of luminance 1.
        assert_eq!(floor.0[1], 0.0);
        assert_eq!(floor.0[2], 0.0);
        assert!((floor.0[0] - 1.0 / 0.2126).abs() < 1e-5);
        // Above ≈ 1900 K nothing is clamped and Ĉ = C/Y (to the rounding of M₇₀₉).
        let c = blackbody_rgb_exact(3000.0);
        let y = blackbody_xyz(3000.0)[1];
        let chromaticity = table.chromaticity(3000.0).to_f64();
        for k in 0..3 {
            assert!(
                (chromaticity[k] - c[k] / y).abs() < 1e-3,
                "Ĉ(3000 K) {chromaticity:?}"
            );
        }
    }

    #[test]
    fn cycles_blackbody_convention() {
        let expected_scale = STEFAN_BOLTZMANN / PI * 1e-6 * 1e12;
        let chromaticity = blackbody_table().cycles_chromaticity(1000.0);
        let actual = cycles_blackbody(1000.0);
        for c in 0..3 {
            let expected = expected_scale * f64::from(chromaticity.0[c]);
            assert!(
                (f64::from(actual.0[c]) - expected).abs() <= 1e-6 * expected.abs(),
                "{actual:?}"
            );
        }
        // Unclamped, like Cycles' own fit (values from Cycles' svm_math_blackbody_color_rec709),
        // and constant outside 800 K … 12000 K.
        let table = blackbody_table();
        for (t, cycles) in [(800.0f32, [5.413f64, -0.203, -0.082]), (12000.0, [0.82659, 0.99452, 1.56659])] {
            let c = table.cycles_chromaticity(t);
            for k in 0..3 {
                assert!((f64::from(c.0[k]) - cycles[k]).abs() < 0.01 * cycles[k].abs().max(0.5), "{t} K: {c:?} vs {cycles:?}");
            }
        }
        assert_eq!(table.cycles_chromaticity(500.0), table.cycles_chromaticity(800.0));
        assert_eq!(table.cycles_chromaticity(5e4), table.cycles_chromaticity(12000.0));
        // No cutoff: 300 K still emits ≈ 1.5e-4 (METHOD §2).
        assert!((cycles_blackbody(300.0).luminance() - 1.46e-4).abs() < 0.01e-4);
        assert!(cycles_blackbody(0.0).is_black());
        assert!(cycles_blackbody(-10.0).is_black());
        assert!(cycles_blackbody(f32::NAN).is_black());
    }

    #[test]
    fn no_nan_or_inf_anywhere() {
        let table = blackbody_table();
        for t in EDGE_TEMPERATURES {
            // The exact functions are specified for finite T.
            if t.is_finite() || t.is_nan() {
                let t64 = f64::from(t);
                assert!(planck(550.0, t64).is_finite(), "planck at {t}");
                assert!(
                    blackbody_xyz(t64).iter().all(|v| v.is_finite()),
                    "xyz at {t}"
                );
                assert!(
                    blackbody_rgb_exact(t64).iter().all(|v| v.is_finite()),
                    "rgb at {t}"
                );
            }
            assert!(table.rgb(t).is_finite(), "table rgb at {t}");
            assert!(table.luminance(t).is_finite(), "table luminance at {t}");
            assert!(table.chromaticity(t).is_finite(), "chromaticity at {t}");
            assert!(cycles_blackbody(t).is_finite(), "cycles at {t}");
        }
        // NaN is treated as 0 K.
        assert!(planck(550.0, f64::NAN) == 0.0 && blackbody_xyz(f64::NAN) == [0.0; 3]);
        assert!(table.rgb(f32::NAN).is_black() && table.luminance(f32::NAN) == 0.0);
    }

    /// Prints the cross-check values quoted in reports; run with `--nocapture`.
    #[test]
    fn print_reference_colours() {
        let table = blackbody_table();
        for t in [800.0f32, 1000.0, 1500.0, 2000.0, 3000.0, 6500.0, 12000.0] {
            let exact = blackbody_rgb_exact(f64::from(t));
            eprintln!(
                "T = {t} K: C exact = [{:.6e}, {:.6e}, {:.6e}], table = {:?}, Y = {:.6e}, Ĉ = {:?}",
                exact[0],
                exact[1],
                exact[2],
                table.rgb(t).0,
                blackbody_xyz(f64::from(t))[1],
                table.chromaticity(t).0
            );
        }
    }

    #[test]
    fn table_build_is_independent_of_thread_count() {
        let (one, three) = (
            BlackbodyTable::build_with_threads(1),
            BlackbodyTable::build_with_threads(3),
        );
        let bits = |table: &BlackbodyTable| {
            let ln_y: Vec<u32> = table.ln_y.iter().map(|v| v.to_bits()).collect();
            let rgb: Vec<[u32; 3]> = table
                .rgb_over_y
                .iter()
                .map(|c| c.map(f32::to_bits))
                .collect();
            (ln_y, rgb)
        };
        assert!(
            bits(&one) == bits(&three),
            "table differs between 1 and 3 build threads"
        );
    }

    /// Table build time. Not a timed assertion (STYLE §8); run with
    /// `cargo test --release --lib table_build_time -- --ignored --nocapture`.
    #[test]
    #[ignore = "benchmark; prints timing only"]
    fn table_build_time() {
        /// CPU time of this thread, s (wall time is inflated on a shared machine).
        fn thread_cpu_seconds() -> f64 {
            let mut ts = libc::timespec {
                tv_sec: 0,
                tv_nsec: 0,
            };
            // SAFETY: `ts` is a valid, writable timespec.
            let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
            assert_eq!(rc, 0);
            ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
        }
        let runs = 50;
        let (wall, cpu) = (std::time::Instant::now(), thread_cpu_seconds());
        let mut checksum = 0.0f32;
        for _ in 0..runs {
            let table = BlackbodyTable::build();
            checksum += table.ln_y[TABLE_NODES / 2];
        }
        let cpu_ms = (thread_cpu_seconds() - cpu) * 1e3 / f64::from(runs);
        let wall_ms = wall.elapsed().as_secs_f64() * 1e3 / f64::from(runs);
        eprintln!(
            "BlackbodyTable::build ({TABLE_NODES} nodes): {wall_ms:.2} ms wall, {cpu_ms:.2} ms \
             thread CPU per build (checksum {checksum})"
        );
    }
}
