//! Emission density `L_e(ρ, v)` from the density ρ and the stored *source* value v
//! (METHOD.md §2).
//!
//! | kind / convention | physical | cycles |
//! |---|---|---|
//! | blackbody (v = T′ in K) | `s_e · c · ρ · C(T′)` | `s_e · c · σ_SB/π · 10⁻⁶ · T′⁴ · Ĉ(T′)` |
//! | grid (v = grid value)   | `s_e · c · ρ · v`      | `s_e · c · v` |
//!
//! `C(T)` is full Planck integrated against the CIE 1931 matching functions into linear
//! Rec.709 (W m⁻² sr⁻¹), `Ĉ = C/Y` its luminance-normalised colour, `s_e` the
//! `--emission-scale`, `c` the `--emission-color`. The *cycles* convention reproduces
//! Blender's Principled Volume: emission is not multiplied by density.
//!
//! Temperatures are mapped (`kelvin` or `linear:OFFSET,SCALE`) and cut off (physical
//! blackbody only: `T′ < T_cut` emits nothing) once, when the volume is built, so that a
//! stored source of 0 always means "no emission" and the DDA can skip it.

use std::cell::Cell;

use crate::color::blackbody::{blackbody_table, cycles_blackbody};
use crate::color::Rgb;
use crate::error::{Error, Result};

/// What drives emission.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EmissionKind {
    /// No emission.
    None,
    /// Blackbody radiation from a temperature grid.
    Blackbody,
    /// A scalar emission grid times a colour.
    Grid,
}

/// Which renderer's meaning of emission to follow.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Convention {
    /// Emission density proportional to density × source.
    Physical,
    /// Blender Cycles' Principled Volume: emission not multiplied by density; blackbody
    /// scaled by σ_SB/π·10⁻⁶·T⁴.
    Cycles,
}

/// Mapping from temperature-grid values to Kelvin.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TemperatureMap {
    /// Values are Kelvin.
    Kelvin,
    /// `T′ = offset + scale · v`.
    Linear {
        /// Kelvin at v = 0.
        offset: f32,
        /// Kelvin per unit v.
        scale: f32,
    },
}

impl std::str::FromStr for TemperatureMap {
    type Err = Error;

    fn from_str(s: &str) -> Result<TemperatureMap> {
        if s == "kelvin" {
            return Ok(TemperatureMap::Kelvin);
        }
        let bad = || Error::invalid("emission.temperature_map", format!("{s:?}: expected `kelvin` or `linear:OFFSET,SCALE`"));
        let rest = s.strip_prefix("linear:").ok_or_else(bad)?;
        let (a, b) = rest.split_once(',').ok_or_else(bad)?;
        let offset: f32 = a.trim().parse().map_err(|_| bad())?;
        let scale: f32 = b.trim().parse().map_err(|_| bad())?;
        if !offset.is_finite() || !scale.is_finite() {
            return Err(bad());
        }
        Ok(TemperatureMap::Linear { offset, scale })
    }
}

impl TemperatureMap {
    /// Kelvin for a grid value.
    #[inline]
    #[must_use]
    pub fn kelvin(&self, v: f32) -> f32 {
        match *self {
            TemperatureMap::Kelvin => v,
            TemperatureMap::Linear { offset, scale } => offset + scale * v,
        }
    }
}

/// An emission model (see the module table).
#[derive(Clone, Copy, Debug)]
pub struct Emission {
    /// What drives emission.
    pub kind: EmissionKind,
    /// Physical or Cycles meaning.
    pub convention: Convention,
    /// `s_e`, the emission scale.
    pub scale: f32,
    /// `c`, the emission colour (a tint for blackbody).
    pub color: Rgb,
    /// Temperature mapping (blackbody only).
    pub temperature_map: TemperatureMap,
    /// Physical blackbody: temperatures below this emit nothing, in Kelvin.
    pub cutoff_kelvin: f32,
}

impl Emission {
    /// No emission at all.
    #[must_use]
    pub fn none() -> Emission {
        Emission {
            kind: EmissionKind::None,
            convention: Convention::Physical,
            scale: 0.0,
            color: Rgb::ONE,
            temperature_map: TemperatureMap::Kelvin,
            cutoff_kelvin: 0.0,
        }
    }

    /// Raw source-grid value → stored source (Kelvin after map and cutoff, or the grid
    /// value). 0 means "no emission"; negative or non-finite results are cleaned (and
    /// counted) by the volume builder.
    #[inline]
    #[must_use]
    pub fn map_source(&self, v: f32) -> f32 {
        match self.kind {
            EmissionKind::None => 0.0,
            EmissionKind::Grid => v,
            EmissionKind::Blackbody => {
                let t = self.temperature_map.kelvin(v);
                let cut = match self.convention {
                    Convention::Physical => self.cutoff_kelvin,
                    Convention::Cycles => 0.0,
                };
                if t.is_finite() && t < cut && t >= 0.0 {
                    0.0
                } else {
                    t
                }
            }
        }
    }

    /// What [`Emission::map_source`] depends on, as text: a brick cache stores sources
    /// mapped with one key and may only be rendered with the same.
    #[must_use]
    pub fn source_key(&self) -> String {
        match self.kind {
            EmissionKind::None => "none".into(),
            EmissionKind::Grid => "grid".into(),
            EmissionKind::Blackbody => {
                let cut = match self.convention {
                    Convention::Physical => self.cutoff_kelvin,
                    Convention::Cycles => 0.0,
                };
                format!("blackbody map={:?} cutoff={cut}K", self.temperature_map)
            }
        }
    }

    /// What light sampling's power (`integrator::light_power`) depends on: the source key
    /// and the convention (never the scale or tint).
    #[must_use]
    pub fn light_key(&self) -> String {
        format!("{} convention={:?}", self.source_key(), self.convention)
    }

    /// Emission density `L_e` for density `density` and stored source `source`.
    #[inline]
    #[must_use]
    pub fn le(&self, density: f32, source: f32) -> Rgb {
        if source == 0.0 {
            return Rgb::ZERO;
        }
        match (self.kind, self.convention) {
            (EmissionKind::None, _) => Rgb::ZERO,
            (EmissionKind::Blackbody, Convention::Physical) => blackbody_table().rgb(source) * self.color * (self.scale * density),
            (EmissionKind::Blackbody, Convention::Cycles) => cycles_blackbody(source) * self.color * self.scale,
            (EmissionKind::Grid, Convention::Physical) => self.color * (self.scale * source * density),
            (EmissionKind::Grid, Convention::Cycles) => self.color * (self.scale * source),
        }
    }

    /// True when emission can be non-zero where density is zero (then the point
    /// estimator, which scores only at collisions, misses it).
    #[must_use]
    pub fn emits_without_density(&self) -> bool {
        self.kind != EmissionKind::None && self.convention == Convention::Cycles
    }
}

/// Slots of an [`EmissionMemo`].
const MEMO_SLOTS: usize = 32;

/// [`Emission::le`] with a small direct-mapped memo of the last voxels asked for.
///
/// Along a ray, consecutive trilinear pieces share 4 of their 8 corner voxels, and every
/// emitting piece needs `le` of each corner (`volume/trilinear/piece.rs`): the memo
/// answers the shared ones without evaluating the blackbody again. Keys are the exact bits
/// of `(density, source)`, so a hit returns exactly what `le` would.
#[derive(Debug)]
pub(crate) struct EmissionMemo<'e> {
    emission: &'e Emission,
    keys: [Cell<u64>; MEMO_SLOTS],
    values: [Cell<Rgb>; MEMO_SLOTS],
}

impl<'e> EmissionMemo<'e> {
    /// An empty memo of `emission.le` (no key matches: `u64::MAX` is a NaN density, which
    /// volumes never hold).
    pub(crate) fn new(emission: &'e Emission) -> Self {
        EmissionMemo { emission, keys: std::array::from_fn(|_| Cell::new(u64::MAX)), values: std::array::from_fn(|_| Cell::new(Rgb::ZERO)) }
    }

    /// `emission.le(density, source)`.
    #[inline]
    pub(crate) fn le(&self, density: f32, source: f32) -> Rgb {
        if source == 0.0 {
            return Rgb::ZERO;
        }
        let key = (u64::from(density.to_bits()) << 32) | u64::from(source.to_bits());
        // Fibonacci hashing of both words: the top 5 bits of the product pick the slot
        let slot = ((density.to_bits() ^ source.to_bits().rotate_left(16)).wrapping_mul(0x9e37_79b1) >> 27) as usize;
        if self.keys[slot].get() == key {
            return self.values[slot].get();
        }
        let value = self.emission.le(density, source);
        self.keys[slot].set(key);
        self.values[slot].set(value);
        value
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Sampler;

    /// The memo returns exactly `le`, bit for bit, however keys collide in its slots:
    /// 20 000 lookups drawn from 40 distinct voxels (more than the slots, so entries are
    /// evicted and refilled) in both conventions; and a memo that returned a stale value
    /// would fail, since no two of the voxels share an emission.
    #[test]
    fn the_memo_returns_exactly_what_le_returns() {
        for convention in [Convention::Cycles, Convention::Physical] {
            let emission = Emission {
                kind: EmissionKind::Blackbody,
                convention,
                scale: 1.5,
                color: Rgb([1.0, 0.8, 0.6]),
                temperature_map: TemperatureMap::Kelvin,
                cutoff_kelvin: 0.0,
            };
            let mut rng = Sampler::new(3, 0, 0);
            let voxels: Vec<(f32, f32)> = (0..40).map(|i| (0.1 + rng.next_f32(), 900.0 + 50.0 * i as f32)).collect();
            let memo = EmissionMemo::new(&emission);
            for _ in 0..20_000 {
                let (d, s) = voxels[(rng.next_u64() % 40) as usize];
                let (a, b) = (memo.le(d, s), emission.le(d, s));
                assert_eq!(a.0.map(f32::to_bits), b.0.map(f32::to_bits), "density {d}, source {s}");
            }
            assert_eq!(memo.le(0.5, 0.0).0, [0.0; 3]);
        }
    }
}
