//! Random numbers and sampling warps.
//!
//! [`Sampler`] is a stateless-seeded stream: its sequence is a pure function of
//! `(seed, pixel, sample)`, so any pixel sample can be replayed (`--debug-pixel`) and the
//! image does not depend on which thread rendered which tile. Building blocks never own
//! a sampler; they take uniform numbers `u` as arguments.

pub mod alias;
pub mod phase;

/// SplitMix64 finaliser (Steele, Lea, Flood 2014): a bijective 64-bit mix.
#[inline]
#[must_use]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A per-sample random stream (SplitMix64 over a hashed key).
#[derive(Clone, Debug)]
pub struct Sampler {
    state: u64,
}

impl Sampler {
    /// The stream for one pixel sample.
    #[must_use]
    pub fn new(seed: u64, pixel: u64, sample: u64) -> Sampler {
        let key = mix64(mix64(mix64(seed ^ 0x5851_f42d_4c95_7f2d) ^ pixel) ^ sample.wrapping_mul(0x9e37_79b9_7f4a_7c15));
        Sampler { state: key }
    }

    /// Next 64 random bits.
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        mix64(self.state)
    }

    /// Uniform in `[0, 1)` with 53 random bits.
    #[inline]
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in `[0, 1)` as `f32` (24 random bits).
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / (1u32 << 24) as f32)
    }
}
