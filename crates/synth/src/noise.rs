//! Seeded, hash-based 3D gradient noise and its fractal sums, for the explosion generator.
//!
//! **Gradient noise** follows Perlin, *Improving Noise* (SIGGRAPH 2002): quintic fade
//! `6t⁵ − 15t⁴ + 10t³` and the twelve cube-edge gradients (padded to sixteen). The
//! gradient at lattice point `(i, j, k)` comes from an integer hash of `(i, j, k, seed)`
//! rather than a permutation table, so there is no period, no table and no shared state:
//! a noise value is a pure function of its arguments. The value is 0 at every lattice
//! point and lies in about `[−1, 1]`; callers that need a hard bound clamp.
//!
//! **Fractal sums** add octaves `o = 0..n` at frequency `f·λᵒ` with amplitude `gᵒ`
//! (λ = [`LACUNARITY`], g = [`GAIN`]), normalised by `Σ gᵒ`, each octave with its own
//! seed. [`Fractal::fbm`] sums signed noise (fBm, zero mean); [`Fractal::turbulence`]
//! sums `|noise|` (Perlin's "turbulence"), whose creases give the billowy, cauliflower
//! look of pyroclastic clouds (Wrenninge, *Production Volume Rendering*, 2012, ch. 7).
//!
//! Arithmetic is plain `f32` without `mul_add`, so results are bit-identical on every
//! thread and every run of the same binary.

use glam::Vec3;

/// Frequency ratio between successive octaves; not exactly 2 so that octave lattices
/// do not align (their zeros would otherwise coincide at the coarse lattice points).
pub(crate) const LACUNARITY: f32 = 2.03;
/// Amplitude ratio between successive octaves.
pub(crate) const GAIN: f32 = 0.5;

/// Odd multipliers that spread the lattice coordinates before mixing (Teschner et al.
/// 2003 use similar large primes for spatial hashing).
const PRIME_X: u32 = 0x8da6_b343;
const PRIME_Y: u32 = 0xd816_3841;
const PRIME_Z: u32 = 0xcb1a_b31f;

/// MurmurHash3's 32-bit finaliser: a bijection with full avalanche.
#[inline]
fn fmix32(mut h: u32) -> u32 {
    h ^= h >> 16;
    h = h.wrapping_mul(0x85eb_ca6b);
    h ^= h >> 13;
    h = h.wrapping_mul(0xc2b2_ae35);
    h ^ (h >> 16)
}

/// SplitMix64 (Steele et al. 2014): derives well-separated 32-bit seeds for the noise
/// streams from the user's 64-bit seed and a stream number.
#[must_use]
pub(crate) fn stream_seed(seed: u64, stream: u64) -> u32 {
    let z = plume_core::sampling::mix64(
        (seed ^ stream.wrapping_mul(0x9e37_79b9_7f4a_7c15)).wrapping_add(0x9e37_79b9_7f4a_7c15),
    );
    (z ^ (z >> 32)) as u32
}

/// `⌊x⌋` as an integer (saturating for huge `x`; coordinates here stay far below 2³¹).
///
/// NOTE: `f32::floor` is a libm call on baseline x86-64 (no SSE4.1 `roundss`); this
/// compare-and-subtract form is inlined.
#[inline]
fn floor_i32(x: f32) -> i32 {
    let truncated = x as i32;
    truncated.wrapping_sub(i32::from((truncated as f32) > x))
}

/// Perlin's quintic fade, with zero first and second derivative at 0 and 1.
#[inline]
fn fade(t: f32) -> f32 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

#[inline]
fn lerp(t: f32, a: f32, b: f32) -> f32 {
    a + t * (b - a)
}

/// Perlin's (2002) twelve cube-edge gradients, four repeated to make sixteen.
const GRADIENTS: [[f32; 3]; 16] = [
    [1.0, 1.0, 0.0],
    [-1.0, 1.0, 0.0],
    [1.0, -1.0, 0.0],
    [-1.0, -1.0, 0.0],
    [1.0, 0.0, 1.0],
    [-1.0, 0.0, 1.0],
    [1.0, 0.0, -1.0],
    [-1.0, 0.0, -1.0],
    [0.0, 1.0, 1.0],
    [0.0, -1.0, 1.0],
    [0.0, 1.0, -1.0],
    [0.0, -1.0, -1.0],
    [1.0, 1.0, 0.0],
    [0.0, -1.0, 1.0],
    [-1.0, 1.0, 0.0],
    [0.0, -1.0, -1.0],
];

/// Dot product of offset `(x, y, z)` with the gradient picked by the top four bits of `h`.
///
/// NOTE: a table load, not Perlin's `if`/`else` selects: LLVM turned those into branches
/// on random hash bits, and mispredictions made the noise roughly 4× slower.
#[inline(always)]
fn grad(h: u32, x: f32, y: f32, z: f32) -> f32 {
    let g = GRADIENTS[(h >> 28) as usize];
    g[0] * x + g[1] * y + g[2] * z
}

/// Lattice cell of `p` (its minimum corner) and the position of `p` inside it, each
/// component in `[0, 1)`.
#[inline(always)]
fn lattice_point(p: Vec3) -> ([i32; 3], [f32; 3]) {
    let cell = [floor_i32(p.x), floor_i32(p.y), floor_i32(p.z)];
    (cell, [p.x - cell[0] as f32, p.y - cell[1] as f32, p.z - cell[2] as f32])
}

/// Hashes of the eight corners of lattice cell `[ix, iy, iz]` (index `dx | dy<<1 | dz<<2`).
#[inline(always)]
fn corner_hashes([ix, iy, iz]: [i32; 3], seed: u32) -> [u32; 8] {
    let hx = [(ix as u32).wrapping_mul(PRIME_X), (ix as u32).wrapping_add(1).wrapping_mul(PRIME_X)];
    let hy = [(iy as u32).wrapping_mul(PRIME_Y), (iy as u32).wrapping_add(1).wrapping_mul(PRIME_Y)];
    let hz = [(iz as u32).wrapping_mul(PRIME_Z), (iz as u32).wrapping_add(1).wrapping_mul(PRIME_Z)];
    std::array::from_fn(|c| fmix32(hx[c & 1] ^ hy[(c >> 1) & 1] ^ hz[c >> 2] ^ seed))
}

/// The corner hashes of the last lattice cell one noise stream visited.
///
/// Neighbouring voxels mostly share the cells of the coarse octaves, so keeping one
/// cell per octave skips most hashing. NOTE: hashing is only a small part of a noise
/// evaluation, so the cache saves roughly a tenth of an explosion's generation time. A cache must be used with one seed only; results are
/// bit-identical with or without it.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct CellCache {
    cell: Option<[i32; 3]>,
    hashes: [u32; 8],
}

impl CellCache {
    /// Corner hashes and in-cell position of `p` for `seed`, from the cache when `p` is
    /// in the same cell as the last call.
    #[inline(always)]
    fn lookup(&mut self, p: Vec3, seed: u32) -> ([u32; 8], [f32; 3]) {
        let (cell, fraction) = lattice_point(p);
        if self.cell != Some(cell) {
            self.hashes = corner_hashes(cell, seed);
            self.cell = Some(cell);
        }
        (self.hashes, fraction)
    }
}

/// Most octaves a [`Fractal`] may have.
pub(crate) const MAX_OCTAVES: usize = 8;

/// One [`CellCache`] per octave of one [`Fractal`].
pub(crate) type FractalCache = [CellCache; MAX_OCTAVES];

/// Gradient noise from corner hashes: the top four bits of each pick the gradient.
#[inline(always)]
fn interpolate(hashes: &[u32; 8], [fx, fy, fz]: [f32; 3]) -> f32 {
    let (gx, gy, gz) = (fx - 1.0, fy - 1.0, fz - 1.0);
    let n000 = grad(hashes[0], fx, fy, fz);
    let n100 = grad(hashes[1], gx, fy, fz);
    let n010 = grad(hashes[2], fx, gy, fz);
    let n110 = grad(hashes[3], gx, gy, fz);
    let n001 = grad(hashes[4], fx, fy, gz);
    let n101 = grad(hashes[5], gx, fy, gz);
    let n011 = grad(hashes[6], fx, gy, gz);
    let n111 = grad(hashes[7], gx, gy, gz);
    let (u, v, w) = (fade(fx), fade(fy), fade(fz));
    lerp(
        w,
        lerp(v, lerp(u, n000, n100), lerp(u, n010, n110)),
        lerp(v, lerp(u, n001, n101), lerp(u, n011, n111)),
    )
}

/// Seeded 3D gradient noise at `p` (lattice spacing 1), in about `[−1, 1]`.
#[inline]
#[must_use]
pub(crate) fn gradient_noise(p: Vec3, seed: u32, cache: &mut CellCache) -> f32 {
    let (hashes, fraction) = cache.lookup(p, seed);
    interpolate(&hashes, fraction)
}

/// Three independent gradient noises at `p` for the price of about 1.6: one corner hash
/// supplies three gradients from its bits 28–31, 24–27 and 20–23 (`fmix32` avalanches,
/// so the fields are independent for practical purposes).
#[inline]
#[must_use]
pub(crate) fn gradient_noise_vec3(p: Vec3, seed: u32, cache: &mut CellCache) -> Vec3 {
    let (hashes, fraction) = cache.lookup(p, seed);
    Vec3::new(
        interpolate(&hashes, fraction),
        interpolate(&hashes.map(|h| h << 4), fraction),
        interpolate(&hashes.map(|h| h << 8), fraction),
    )
}

/// A fractal sum of [`gradient_noise`] octaves with fixed base frequency and seed.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Fractal {
    /// Base frequency, cycles per world unit (metre).
    pub frequency: f32,
    /// Number of octaves, 1 to [`MAX_OCTAVES`].
    pub octaves: u32,
    /// Seed of octave 0; octave `o` uses a hash of `(seed, o)`.
    pub seed: u32,
}

impl Fractal {
    /// Octave seeds and frequencies, then the normalised sum of `shape(noise)`.
    #[inline]
    fn sum(&self, p: Vec3, cache: &mut FractalCache, shape: impl Fn(f32) -> f32) -> f32 {
        let mut frequency = self.frequency;
        let mut amplitude = 1.0;
        let mut total = 0.0;
        let mut norm = 0.0;
        for o in 0..self.octaves {
            let seed = fmix32(self.seed ^ o.wrapping_mul(0x9e37_79b9));
            let n = gradient_noise(p * frequency, seed, &mut cache[o as usize]);
            total += amplitude * shape(n);
            norm += amplitude;
            amplitude *= GAIN;
            frequency *= LACUNARITY;
        }
        total / norm
    }

    /// Three independent fBms at `p` (one per component), sharing lattice hashes.
    #[inline]
    #[must_use]
    pub fn fbm_vec3(&self, p: Vec3, cache: &mut FractalCache) -> Vec3 {
        let mut frequency = self.frequency;
        let mut amplitude = 1.0;
        let mut total = Vec3::ZERO;
        let mut norm = 0.0;
        for o in 0..self.octaves {
            let seed = fmix32(self.seed ^ o.wrapping_mul(0x9e37_79b9));
            total += amplitude * gradient_noise_vec3(p * frequency, seed, &mut cache[o as usize]);
            norm += amplitude;
            amplitude *= GAIN;
            frequency *= LACUNARITY;
        }
        total / norm
    }

    /// Fractional Brownian motion at `p` (world units): signed, zero mean, in about `[−1, 1]`.
    #[inline]
    #[must_use]
    pub fn fbm(&self, p: Vec3, cache: &mut FractalCache) -> f32 {
        self.sum(p, cache, |n| n)
    }

    /// Turbulence at `p`: the normalised sum of `|noise|`, in about `[0, 1]`, with sharp
    /// creases where an octave crosses zero.
    #[inline]
    #[must_use]
    pub fn turbulence(&self, p: Vec3, cache: &mut FractalCache) -> f32 {
        self.sum(p, cache, f32::abs)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Noise without a warm cache.
    fn noise(p: Vec3, seed: u32) -> f32 {
        gradient_noise(p, seed, &mut CellCache::default())
    }

    /// A fixed scattering of sample points (no RNG needed).
    fn points(count: usize) -> impl Iterator<Item = Vec3> {
        (0..count).map(|i| {
            let i = i as f32;
            Vec3::new(i * 0.618_034 % 37.0, i * 0.414_214 % 23.0, i * 0.732_051 % 29.0) - 11.0
        })
    }

    #[test]
    fn synth_noise_zero_at_lattice_points_and_bounded() {
        for i in -3..3 {
            let p = Vec3::new(i as f32, (2 * i) as f32, (-i) as f32);
            assert_eq!(noise(p, 7), 0.0);
        }
        for p in points(20_000) {
            let n = noise(p, 7);
            assert!(n.is_finite() && n.abs() <= 1.1, "noise({p}) = {n}");
        }
    }

    #[test]
    fn synth_noise_is_continuous_across_cells() {
        for p in points(2_000) {
            let c = p.floor() + 1.0;
            let below = noise(Vec3::new(c.x - 1e-4, p.y, p.z), 3);
            let above = noise(Vec3::new(c.x + 1e-4, p.y, p.z), 3);
            assert!((below - above).abs() < 1e-3, "jump at x = {}", c.x);
        }
    }

    #[test]
    fn synth_noise_seeds_are_uncorrelated() {
        let (mut sab, mut saa, mut sbb) = (0.0f64, 0.0f64, 0.0f64);
        for p in points(20_000) {
            let a = f64::from(noise(p, stream_seed(1, 0)));
            let b = f64::from(noise(p, stream_seed(2, 0)));
            sab += a * b;
            saa += a * a;
            sbb += b * b;
        }
        let correlation = sab / (saa * sbb).sqrt();
        assert!(correlation.abs() < 0.05, "correlation {correlation}");
        assert!(saa / 20_000.0 > 0.01, "noise has almost no variance");
    }

    #[test]
    fn synth_noise_vec3_channels_are_uncorrelated() {
        let mut sums = [[0.0f64; 3]; 3];
        for p in points(20_000) {
            let v = gradient_noise_vec3(p, 5, &mut CellCache::default()).as_dvec3().to_array();
            assert_eq!(v[0], f64::from(noise(p, 5)));
            for a in 0..3 {
                for b in 0..3 {
                    sums[a][b] += v[a] * v[b];
                }
            }
        }
        for (a, b) in [(0, 1), (0, 2), (1, 2)] {
            let correlation = sums[a][b] / (sums[a][a] * sums[b][b]).sqrt();
            assert!(correlation.abs() < 0.05, "channels {a}, {b}: correlation {correlation}");
        }
    }

    #[test]
    fn synth_fractal_ranges() {
        let f = Fractal { frequency: 1.3, octaves: 5, seed: 11 };
        for p in points(5_000) {
            let b = f.fbm(p, &mut FractalCache::default());
            let t = f.turbulence(p, &mut FractalCache::default());
            assert!(b.abs() <= 1.1 && (0.0..=1.1).contains(&t), "fbm {b}, turbulence {t}");
        }
    }

    #[test]
    fn synth_cached_noise_is_bit_identical() {
        let f = Fractal { frequency: 0.9, octaves: 5, seed: 21 };
        let (mut scalar, mut vector) = (FractalCache::default(), FractalCache::default());
        // A walk in small steps (mostly cache hits) with occasional jumps (misses).
        for (i, jump) in points(3_000).enumerate() {
            let p = Vec3::new(0.013 * i as f32, 0.007 * i as f32, -0.011 * i as f32)
                + if i % 97 == 0 { jump } else { Vec3::ZERO };
            let fresh = f.turbulence(p, &mut FractalCache::default());
            assert_eq!(f.turbulence(p, &mut scalar).to_bits(), fresh.to_bits());
            let fresh = f.fbm_vec3(p, &mut FractalCache::default());
            assert_eq!(f.fbm_vec3(p, &mut vector), fresh);
        }
    }
}
