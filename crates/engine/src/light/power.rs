//! The power light sampling distributes by, per voxel: `Y(L_e(density, source))`, the
//! luminance of the emission density with unit `--emission-scale` and white
//! `--emission-color` (`integrator::light_power` says why those two are left out).
//!
//! Every emitting voxel of a volume is weighed once when the FNEE proxy or the NEE table
//! is built, and a brick cache weighs all of them during conversion, so this is a hot
//! loop: a blackbody `L_e` costs a logarithm, an exponential and table interpolation.
//! For blackbody emission the luminance per unit density, `g(T) = Y(L_e(1, T))`, is
//! tabulated instead at the first `FRACTION_BITS` mantissa bits of `T` (256 nodes per
//! octave, [`TABLE_MIN_KELVIN`] … [`TABLE_MAX_KELVIN`]), so a lookup is a shift and one
//! linear interpolation in `T` within an octave: of `g` itself where `ln g` changes by
//! less than `LINEAR_STEP` from node to node, of `ln g` (then one exponential) where
//! it changes faster (below about 3500 K):
//!
//! ```text
//!   power(d, T) = d · g(T)   (physical)        power(d, T) = g(T)   (Cycles)
//! ```
//!
//! Nodes are exact evaluations. `ln g ≈ −c/T + …` (Wien, `c ≈ 26 000 K` for luminance) is
//! nearly linear across a node spacing of `2^(1/256) − 1 ≈ 0.27 %` in `T`. The
//! interpolation error (about `c·δ²/(4T)` in `ln g`, `Δ²/8` in `g`, plus the kinks of
//! the colour table and its gamut clamp) is under `2·10⁻⁴` above 2000 K and about `10⁻³`
//! at the 100 K bottom of the table (tested), where a voxel emits `e^{−260}` of its
//! density anyway. Intervals touching a zero node are evaluated exactly. Light sampling
//! only needs a pdf that is positive where light is: an approximate power changes
//! noise, never the expected image, and every technique and the cache use this same
//! function.

use crate::medium::{Convention, Emission, EmissionKind};
use plume_core::color::blackbody::{TABLE_MAX_KELVIN, TABLE_MIN_KELVIN};

/// Mantissa bits of `T` that select a node: `2^FRACTION_BITS` nodes per octave.
const FRACTION_BITS: u32 = 8;
/// Bits of an `f32` below a node index.
const SHIFT: u32 = 23 - FRACTION_BITS;
/// Largest `|Δ ln g|` between nodes interpolated linearly in `g` (error `≈ Δ²/8 ≈ 10⁻⁵`).
const LINEAR_STEP: f64 = 0.01;

/// `g` at the nodes of one emission setting (see the module docs).
#[derive(Clone, Debug)]
struct Table {
    /// Node index of entry 0 (node `k` is the `f32` with bits `k << SHIFT`).
    first: u32,
    /// `g` at each node.
    g: Vec<f64>,
    /// `ln g` at each node.
    ln_g: Vec<f64>,
    /// Per interval `[k, k + 1]`: interpolate `g` linearly (else `ln g`).
    linear: Vec<bool>,
    /// Physical convention: power is density × g.
    times_density: bool,
}

/// Light-sampling power of voxels for one emission setting. See the module docs.
#[derive(Clone, Debug)]
pub struct LightPower {
    /// The emission with unit scale and white tint.
    unit: Emission,
    /// Blackbody only.
    table: Option<Table>,
}

impl LightPower {
    /// The power for `emission` (its scale and tint are ignored).
    #[must_use]
    pub fn new(emission: &Emission) -> LightPower {
        let unit = Emission { scale: 1.0, color: plume_core::color::Rgb([1.0; 3]), ..*emission };
        let table = (unit.kind == EmissionKind::Blackbody).then(|| {
            let first = TABLE_MIN_KELVIN.to_bits() >> SHIFT;
            // The last node at or below the table's top: above it `exact` clamps T
            let last = TABLE_MAX_KELVIN.to_bits() >> SHIFT;
            let g: Vec<f64> =
                (first..=last).map(|k| exact(&unit, 1.0, f32::from_bits(k << SHIFT))).collect();
            let ln_g: Vec<f64> = g.iter().map(|v| v.ln()).collect();
            let linear = ln_g.windows(2).map(|w| (w[1] - w[0]).abs() <= LINEAR_STEP).collect();
            Table { first, g, ln_g, linear, times_density: unit.convention == Convention::Physical }
        });
        LightPower { unit, table }
    }

    /// `Y(L_e(density, source))` with unit scale and tint, ≥ 0 for valid (cleaned) voxels.
    #[inline]
    #[must_use]
    pub fn power(&self, density: f32, source: f32) -> f64 {
        if source == 0.0 {
            return 0.0;
        }
        let Some(t) = &self.table else { return exact(&self.unit, density, source) };
        let bits = source.to_bits();
        if !(TABLE_MIN_KELVIN..=f32::MAX).contains(&source)
            || (bits >> SHIFT) - t.first + 1 >= t.g.len() as u32
        {
            return exact(&self.unit, density, source);
        }
        let k = ((bits >> SHIFT) - t.first) as usize;
        // Within a node interval the exponent is fixed, so T is linear in the low bits
        let f = f64::from(bits & ((1 << SHIFT) - 1)) * (1.0 / f64::from(1u32 << SHIFT));
        let value = if t.linear[k] {
            t.g[k] + f * (t.g[k + 1] - t.g[k])
        } else {
            let (a, b) = (t.ln_g[k], t.ln_g[k + 1]);
            if a == f64::NEG_INFINITY || b == f64::NEG_INFINITY {
                return exact(&self.unit, density, source);
            }
            (a + f * (b - a)).exp()
        };
        if t.times_density {
            f64::from(density) * value
        } else {
            value
        }
    }
}

/// `Y(L_e(density, source))` evaluated in full.
fn exact(unit: &Emission, density: f32, source: f32) -> f64 {
    f64::from(unit.le(density, source).luminance().max(0.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::medium::TemperatureMap;
    use plume_core::color::Rgb;

    fn emission(kind: EmissionKind, convention: Convention) -> Emission {
        Emission {
            kind,
            convention,
            scale: 3.0,
            color: Rgb([1.0, 0.5, 0.25]),
            temperature_map: TemperatureMap::Kelvin,
            cutoff_kelvin: 0.0,
        }
    }

    #[test]
    fn tabulated_power_follows_the_exact_luminance() {
        for convention in [Convention::Physical, Convention::Cycles] {
            let e = emission(EmissionKind::Blackbody, convention);
            let p = LightPower::new(&e);
            let (mut worst_low, mut worst): (f64, f64) = (0.0, 0.0);
            // Log-spaced temperatures over the whole table and beyond it
            for i in 0..200_000 {
                let t = (10f64.powf(1.5 + 7.0 * f64::from(i) / 200_000.0)) as f32;
                for d in [0.0f32, 0.25, 7.0] {
                    let want = exact(&p.unit, d, t);
                    let got = p.power(d, t);
                    assert!(got >= 0.0 && got.is_finite(), "T={t} d={d}: {got}");
                    // The exact value is computed in f32: compare where it is a normal number
                    if want > 1e-30 {
                        let e = (got / want - 1.0).abs();
                        if t >= 2000.0 {
                            worst = worst.max(e);
                        } else {
                            worst_low = worst_low.max(e);
                        }
                    } else if convention == Convention::Physical && d == 0.0 {
                        assert_eq!(got, 0.0, "no density, no power (T={t})");
                    }
                }
            }
            assert!(worst < 2e-4, "{convention:?}: relative error {worst:e} above 2000 K");
            assert!(worst_low < 2e-3, "{convention:?}: relative error {worst_low:e} below 2000 K");
        }
    }

    #[test]
    fn other_kinds_are_exact_and_scale_and_tint_are_ignored() {
        let grid = emission(EmissionKind::Grid, Convention::Physical);
        let p = LightPower::new(&grid);
        assert_eq!(p.power(2.0, 3.0), exact(&p.unit, 2.0, 3.0));
        assert_eq!(
            p.power(2.0, 3.0),
            LightPower::new(&Emission { scale: 9.0, color: Rgb::ONE, ..grid }).power(2.0, 3.0)
        );
        assert_eq!(
            LightPower::new(&emission(EmissionKind::None, Convention::Physical)).power(1.0, 5000.0),
            0.0
        );
    }
}
