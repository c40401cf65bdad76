//! Random numbers and sampling warps.
//!
//! A [`Sampler`] gives the uniform numbers of one pixel sample. Its values are a pure
//! function of `(kind, seed, pixel, sample)` and of the draws asked for, so any pixel
//! sample can be replayed (`--debug-pixel`) and the image does not depend on which thread
//! rendered which tile, nor on how samples are split into passes, ranges or parts.
//! Building blocks never own a sampler; they take uniform numbers `u` as arguments.
//!
//! **Two kinds** ([`SamplerKind`], `--sampler`):
//! - `sobol` (default): Owen-scrambled Sobol points (Burley 2020, [`sobol`]). The sample
//!   index is the Sobol index; each pixel has its own scramble seed `hash(seed, pixel)`,
//!   so pixels are decorrelated and their error is noise, not structure. The numbers of a
//!   path are *padded* per free-path segment: each segment has a block of named
//!   dimensions ([`Dim`]) in three 4-D sets, each set a Sobol point with its own seed
//!   `hash(pixel seed, block, set)`. A segment's direction and free path share the first
//!   set, so the 2-D pixel jitter (or phase direction) and the camera segment's free path
//!   are stratified together. The forward segment leaving vertex `k` (0: the camera) is
//!   block `2k` ([`Sampler::start_vertex`]), the light segment of vertex `k` block
//!   `2k + 1` ([`Sampler::start_light_segment`]). Draws whose number varies from path to
//!   path (ray-march's roulette) come
//!   from the hashed stream ([`Sampler::next_f64`]), never from a Sobol dimension.
//! - `random`: one SplitMix64 stream per pixel sample, every draw the next number of the
//!   stream, named or not; kept bit for bit, so its images do not change.

pub mod alias;
pub mod distribution2d;
pub mod phase;
pub mod sobol;

/// SplitMix64 finaliser (Steele, Lea, Flood 2014): a bijective 64-bit mix.
#[inline]
#[must_use]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

const GOLDEN: u64 = 0x9e37_79b9_7f4a_7c15;

/// Which numbers a render's samplers give (`--sampler`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum SamplerKind {
    /// Owen-scrambled Sobol points, padded per path segment (the module docs).
    #[default]
    Sobol,
    /// Independent hashed random numbers (SplitMix64).
    Random,
}

/// A named place among the uniform numbers of one free-path segment of a path: the same
/// draw gets the same Sobol dimension whether or not the draws before it happened.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dim {
    /// 2-D: the pixel jitter (camera segment) or the phase-sampled direction.
    Direction,
    /// The free path, `E = −ln(1 − u)`.
    FreePath,
    /// The position of ray-march's one-point rule on polynomial pieces (one per ray).
    OnePoint,
    /// Light sampling: which proxy cell or voxel.
    LightChoice,
    /// 3-D: the point within the chosen cell or voxel.
    LightPosition,
    /// Russian roulette at a scattering vertex.
    Roulette,
    /// External light sampling: which light.
    ExternalLightChoice,
    /// 2-D: the direction towards the chosen light.
    ExternalLightDirection,
    /// The sample's time in the shutter (motion blur; camera block only).
    Time,
    /// 2-D: the point on the camera's lens (depth of field; camera block only).
    Lens,
}

/// 4-D Sobol sets per segment block.
const SETS: usize = 3;

impl Dim {
    /// The dimension's 4-D set, first lane and number of lanes.
    const fn slot(self) -> (usize, usize, usize) {
        match self {
            Dim::Direction => (0, 0, 2),
            Dim::FreePath => (0, 2, 1),
            Dim::OnePoint => (0, 3, 1),
            Dim::LightChoice => (1, 0, 1),
            Dim::LightPosition => (1, 1, 3),
            Dim::Roulette => (2, 0, 1),
            // In light blocks, where roulette's lane is unused
            Dim::ExternalLightChoice => (2, 1, 1),
            Dim::ExternalLightDirection => (2, 2, 2),
            // In the camera block, where neither roulette nor light sampling draws
            Dim::Time => (2, 1, 1),
            // In the camera block, where light sampling's set is unused
            Dim::Lens => (1, 0, 2),
        }
    }
}

/// The Sobol side of a sampler: the pixel's scramble key, the point index and the
/// current segment block with its sets, computed when first asked for.
#[derive(Clone, Debug)]
struct SobolState {
    /// `hash(seed, pixel, sample / 2^16)`: every set's seed derives from it.
    key: u64,
    /// The sample's index in its run of 2^16.
    index: u32,
    /// The current segment block.
    block: u64,
    /// The block's sets, valid where `filled` has the set's bit.
    sets: [[u32; 4]; SETS],
    filled: u8,
}

impl SobolState {
    fn set(&mut self, set: usize) -> &[u32; 4] {
        if self.filled & (1 << set) == 0 {
            let seed =
                mix64(self.key ^ (self.block * SETS as u64 + set as u64 + 1).wrapping_mul(GOLDEN))
                    >> 32;
            self.sets[set] = sobol::sobol_4d(self.index, seed as u32);
            self.filled |= 1 << set;
        }
        &self.sets[set]
    }
}

/// The uniform numbers of one pixel sample (the module docs).
#[derive(Clone, Debug)]
pub struct Sampler {
    /// The hashed stream (SplitMix64 over the key).
    state: u64,
    /// Sobol points, for [`SamplerKind::Sobol`].
    sobol: Option<SobolState>,
}

impl Sampler {
    /// The [`SamplerKind::Random`] stream of one pixel sample; also the plain random
    /// stream that tests and benchmarks draw from.
    #[must_use]
    pub fn new(seed: u64, pixel: u64, sample: u64) -> Sampler {
        Sampler { state: stream_key(seed, pixel, sample), sobol: None }
    }

    /// The sampler of one pixel sample: sample `sample` of pixel `pixel` (the full-image
    /// pixel index) under `seed`. Starts at the camera segment (`start_vertex(0)`).
    #[must_use]
    pub fn with_kind(kind: SamplerKind, seed: u64, pixel: u64, sample: u64) -> Sampler {
        let sobol = match kind {
            SamplerKind::Random => None,
            SamplerKind::Sobol => {
                let run = sample / sobol::SEQUENCE_LENGTH;
                let key = mix64(
                    mix64(mix64(seed ^ 0x2545_f491_4f6c_dd1d) ^ pixel) ^ run.wrapping_mul(GOLDEN),
                );
                let index =
                    u32::try_from(sample % sobol::SEQUENCE_LENGTH).expect("invariant: below 2^16");
                Some(SobolState { key, index, block: 0, sets: [[0; 4]; SETS], filled: 0 })
            }
        };
        Sampler { state: stream_key(seed, pixel, sample), sobol }
    }

    /// Which kind of numbers this sampler gives.
    #[must_use]
    pub fn kind(&self) -> SamplerKind {
        if self.sobol.is_some() {
            SamplerKind::Sobol
        } else {
            SamplerKind::Random
        }
    }

    /// Named draws from now on are those of the forward segment leaving path vertex
    /// `depth` (0: the camera; `k`: the `k`-th collision).
    pub fn start_vertex(&mut self, depth: u32) {
        self.start_block(2 * u64::from(depth));
    }

    /// Named draws from now on are those of the light (next event) segment of path
    /// vertex `depth`.
    pub fn start_light_segment(&mut self, depth: u32) {
        self.start_block(2 * u64::from(depth) + 1);
    }

    /// The sampler of split path `k` of `n` leaving the camera segment's collision
    /// (`Integrator::split`): its named draws from block 1 on are Sobol point
    /// `sample · n + k` of the pixel's sequence, so the `n · spp` split paths of a pixel
    /// are stratified together, and its hashed stream is its own. With `n = 1` it is this
    /// sampler.
    #[must_use]
    pub fn split(&self, k: u32, n: u32) -> Sampler {
        if n <= 1 {
            return self.clone();
        }
        let state =
            mix64(self.state ^ 0x6a09_e667_f3bc_c909 ^ u64::from(k + 1).wrapping_mul(GOLDEN));
        let sobol = self.sobol.as_ref().map(|s| {
            let j = u64::from(s.index) * u64::from(n) + u64::from(k);
            let run = j / sobol::SEQUENCE_LENGTH;
            let key = if run == 0 {
                s.key
            } else {
                mix64(s.key ^ run.wrapping_mul(GOLDEN) ^ 0xbb67_ae85_84ca_a73b)
            };
            let index = u32::try_from(j % sobol::SEQUENCE_LENGTH).expect("invariant: below 2^16");
            SobolState { key, index, block: s.block, sets: [[0; 4]; SETS], filled: 0 }
        });
        Sampler { state, sobol }
    }

    fn start_block(&mut self, block: u64) {
        if let Some(s) = &mut self.sobol {
            s.block = block;
            s.filled = 0;
        }
    }

    /// A 1-D named draw of the current segment, uniform in `[0, 1)`.
    ///
    /// # Panics
    /// In debug builds, if `dim` is not 1-D.
    #[inline]
    pub fn get_1d(&mut self, dim: Dim) -> f64 {
        let [u] = self.get(dim);
        u
    }

    /// A 2-D named draw of the current segment, uniform in `[0, 1)²`.
    ///
    /// # Panics
    /// In debug builds, if `dim` is not 2-D.
    #[inline]
    pub fn get_2d(&mut self, dim: Dim) -> [f64; 2] {
        self.get(dim)
    }

    /// A 3-D named draw of the current segment, uniform in `[0, 1)³`.
    ///
    /// # Panics
    /// In debug builds, if `dim` is not 3-D.
    #[inline]
    pub fn get_3d(&mut self, dim: Dim) -> [f64; 3] {
        self.get(dim)
    }

    #[inline]
    fn get<const N: usize>(&mut self, dim: Dim) -> [f64; N] {
        let (set, lane, lanes) = dim.slot();
        debug_assert_eq!(N, lanes, "{dim:?} has {lanes} dimensions");
        let Some(s) = &mut self.sobol else {
            // Random: the stream's next numbers, in the order asked for
            return std::array::from_fn(|_| self.next_f64());
        };
        let v = s.set(set);
        std::array::from_fn(|i| sobol::to_unit(v[lane + i]))
    }

    /// Next 64 bits of the hashed stream.
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(GOLDEN);
        mix64(self.state)
    }

    /// Uniform in `[0, 1)` with 53 bits, from the hashed stream (both kinds): for draws
    /// whose number varies from path to path.
    #[inline]
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in `[0, 1)` as `f32` (24 bits), from the hashed stream.
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / (1u32 << 24) as f32)
    }
}

/// The hashed stream's starting state for one pixel sample.
fn stream_key(seed: u64, pixel: u64, sample: u64) -> u64 {
    mix64(mix64(mix64(seed ^ 0x5851_f42d_4c95_7f2d) ^ pixel) ^ sample.wrapping_mul(GOLDEN))
}
