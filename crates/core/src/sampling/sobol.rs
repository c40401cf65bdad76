//! Owen-scrambled Sobol points (Burley, *Practical Hash-based Owen Scrambling*, JCGT
//! 9(4), 2020) from the `sobol_burley` crate's building blocks.
//!
//! [`sobol_4d`] is `sobol_burley::sample_4d(index, 0, seed)` with the 32 scrambled bits
//! kept: the crate converts them to `f32` (23 bits), which would quantize a free path's
//! `−ln(1 − u)` to optical depths below 16; 32 bits reach 22 (a mass of `e⁻²²` lost, where
//! the hashed stream's 53 bits reach 36). A unit test checks that the top 23 bits are
//! the crate's `sample_4d`.
//!
//! Only the first four Sobol dimensions are used: higher dimensions come from *padding*,
//! another seed per 4-D set (Burley §4; the crate's recommended use), so every set is
//! as well stratified as the first and sets are randomly decorrelated. The crate holds
//! sequences of 2^16 points; plume gives each further run of 2^16 samples its own
//! scramble (a fresh, independent Owen-scrambled net per run).

use sobol_burley::parts::{
    hash, hash_int4, owen_scramble_int4_rev, owen_scramble_rev, sobol_int4_rev, Int4,
};

/// Points of one scrambled sequence (`sobol_burley`'s limit).
pub const SEQUENCE_LENGTH: u64 = 1 << 16;

/// The four first Sobol dimensions of point `index` (below [`SEQUENCE_LENGTH`]), Owen
/// scrambled and index-shuffled by `seed`, as 32-bit fixed-point fractions.
#[inline]
#[must_use]
pub fn sobol_4d(index: u32, seed: u32) -> [u32; 4] {
    debug_assert!(u64::from(index) < SEQUENCE_LENGTH);
    // Shuffle the index (a nested uniform scramble of its bits), as sample_4d does
    let shuffled_rev_index = owen_scramble_rev(index.reverse_bits(), hash(seed ^ 0x79c6_8e4a));
    let sobol = sobol_int4_rev(shuffled_rev_index, 0);
    // One Owen scramble per dimension (dimension set 0: no set term)
    let scramble: Int4 = Int4::from([seed.wrapping_mul(0x9c8f_2d3b); 4])
        ^ Int4::from([0x912f_69ba, 0x174f_18ab, 0x691e_72ca, 0xb40c_c1b8]);
    let scrambled_rev = owen_scramble_int4_rev(sobol, hash_int4(scramble));
    scrambled_rev.reverse_bits().into()
}

/// A 32-bit fraction as a uniform number in `[0, 1)`.
#[inline]
#[must_use]
pub fn to_unit(n: u32) -> f64 {
    f64::from(n) * (1.0 / 4_294_967_296.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The top 23 bits are the crate's own `sample_4d` (our only change is the precision).
    #[test]
    fn matches_sample_4d() {
        for seed in [0u32, 1, 0xdead_beef] {
            for index in (0..4096).chain([65_535]) {
                let ours =
                    sobol_4d(index, seed).map(|n| f32::from_bits((n >> 9) | 0x3f80_0000) - 1.0);
                assert_eq!(
                    ours,
                    sobol_burley::sample_4d(index, 0, seed),
                    "index {index} seed {seed}"
                );
            }
        }
    }

    #[test]
    fn unit_interval() {
        assert_eq!(to_unit(0), 0.0);
        assert!(to_unit(u32::MAX) < 1.0);
    }
}
