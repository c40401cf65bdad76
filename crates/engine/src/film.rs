//! The film: per-pixel sums of samples, owned by tiles, in an exact fixed-point
//! representation so that any split of the work sums to the same bits.
//!
//! Every sample's `[r, g, b, alpha]` is rounded once to an integer number of units of
//! 2^−[`FIXED_POINT_BITS`] ([`to_fixed`]) and the integers are added in `i128`. Integer
//! addition is associative and commutative, so the sum over samples `0..n` of a pixel is
//! the same integer whether it was taken in one pass, in passes of any size, in several
//! processes each rendering a sample range, or resumed after an interruption.
//! [`pixel_value`] turns a sum and a sample count into the pixel value; it is the only
//! place that does, used by the render loop and by `plume merge` alike. Each pixel keeps
//! its own count and, for the error estimate, its [`Moments`] beside its sums. See
//! `ARCHITECTURE.md`, "Exact sums", for the choice of F = 64.

pub use plume_scene::Crop;

/// Channels of the half sums (`--denoise`): colour, alpha and sample count of one half.
pub const HALF_CHANNEL_COUNT: usize = 5;

/// Edge length of a film tile in pixels. Tiles are aligned to the image (a crop's first
/// row and column of tiles may be narrower), so each is one of adaptive sampling's pixel
/// blocks, cut only where the crop is (`plume_engine::noise`).
pub const TILE: u32 = plume_scene::ADAPTIVE_BLOCK;

/// F: sample values are stored in units of 2^−F. With F = 64 an `i128` sum covers
/// 2^−64 ≈ 5.4·10⁻²⁰ up to 2^63 ≈ 9.2·10¹⁸ (`ARCHITECTURE.md`, "Exact sums").
pub const FIXED_POINT_BITS: u32 = 64;

/// 2^F, exact in `f64`.
const SCALE: f64 = 18_446_744_073_709_551_616.0;
/// 2^−F, exact in `f64`.
const INV_SCALE: f64 = 1.0 / SCALE;
/// 2^127: the first magnitude that no longer fits an `i128`.
const I128_LIMIT: f64 = 170_141_183_460_469_231_731_687_303_715_884_105_728.0;

/// A sample value in fixed point: `round(v · 2^F)` (ties away from zero), or `None` when
/// its magnitude does not fit an `i128` (|v| ≥ 2^63) or it is not finite.
///
/// Exact and deterministic: scaling by a power of two is exact in binary floating
/// point, `round` is exact, and every integral `f64` below 2^127 converts exactly.
#[must_use]
#[inline]
pub fn to_fixed(v: f64) -> Option<i128> {
    let x = (v * SCALE).round();
    if x.abs() < I128_LIMIT {
        Some(x as i128)
    } else {
        None
    }
}

/// The pixel value of an exact sum over `spp` samples: `sum · 2^−F / spp`, rounded to
/// `f32` (0 when `spp` is 0). The one function that turns sums into pixels, used by the
/// render loop and by `plume merge`, so both give the same bits.
#[must_use]
#[inline]
pub fn pixel_value(sum: i128, spp: u64) -> f32 {
    if spp == 0 {
        return 0.0;
    }
    // i128 → f64 rounds to nearest; × 2^−F is exact; one division; one rounding to f32
    ((sum as f64 * INV_SCALE) / spp as f64) as f32
}

/// The count in a sum of samples that each added 1 (an AOV's `depth.hits`, `half.n`):
/// `sum · 2^−F`, exact (0 for a sum outside the `u64` range).
#[must_use]
#[inline]
pub fn count(sum: i128) -> u64 {
    u64::try_from(sum >> FIXED_POINT_BITS).unwrap_or(0)
}

/// A rectangle of pixels with its own exact sums.
#[derive(Clone, Debug)]
pub struct Tile {
    /// Left pixel column (full-image coordinates).
    pub x0: u32,
    /// Top pixel row (full-image coordinates).
    pub y0: u32,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `[r, g, b, alpha]` sums in units of 2^−F, row-major within the tile.
    pub sums: Vec<[i128; 4]>,
    /// AOV channel sums (`integrator::aov`), `aov_channels` per pixel, row-major; empty
    /// without AOVs.
    pub aov: Vec<i128>,
    /// AOV channels per pixel (0: none).
    pub aov_channels: usize,
    /// With half sums (`integrator::aov`, `--denoise`): their first AOV channel, the
    /// half block (`denoise::half_of`) and what they hold.
    pub half: Option<HalfSums>,
    /// Per pixel, the sums of the samples' squared colour, the sample count and the two
    /// highest sample levels ([`Moments`]), row-major within the tile.
    pub moments: Vec<Moments>,
    /// Sample values or sums that did not fit and were clamped to the `i128` range.
    pub saturated: u64,
    /// Non-zero sample values smaller than half a unit (2^−65), stored as 0.
    pub underflowed: u64,
}

/// Where and what a tile records of the second half buffer (`--denoise`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HalfSums {
    /// The first of the half sums' AOV channels ([`crate::integrator::AovLayout::half_at`]).
    pub at: usize,
    /// The half block ([`crate::denoise::half_of`]).
    pub block: u64,
    /// What the colour half sums hold.
    pub filtered: plume_scene::Filtered,
}

pub use crate::moments::Moments;

impl Tile {
    /// Add one finite sample `l`, sample `s` of pixel `index` (row-major within the tile).
    #[inline]
    pub fn add_sample(&mut self, index: usize, s: u64, l: [f64; 4]) {
        // Each value is quantized once, for its sum and for its level's sum in the moments
        let mut q = [0i128; 4];
        for ((a, &v), q) in self.sums[index].iter_mut().zip(&l).zip(&mut q) {
            *q = quantize(v, &mut self.saturated, &mut self.underflowed);
            add_quantized(a, *q, &mut self.saturated);
        }
        // Squares are not counted as clamps: the image itself is exact (`Moments`)
        let square = |v: f64| to_fixed(v * v).unwrap_or(i128::MAX);
        self.moments[index].add(s, [q[0], q[1], q[2]], [square(l[0]), square(l[1]), square(l[2])]);
    }

    /// Count sample `s` of pixel `index`, dropped (non-finite): a zero in its mean.
    #[inline]
    pub fn add_dropped(&mut self, index: usize, s: u64) {
        self.moments[index].add_dropped(s);
    }

    /// Samples pixel `index` holds (row-major within the tile).
    #[must_use]
    #[inline]
    pub fn count(&self, index: usize) -> u64 {
        self.moments[index].count
    }

    /// Add one sample's AOV values (`aov_channels` of them) to pixel `index`.
    #[inline]
    pub fn add_aov(&mut self, index: usize, values: &[f64]) {
        let n = self.aov_channels;
        add_fixed(
            &mut self.aov[index * n..(index + 1) * n],
            values,
            &mut self.saturated,
            &mut self.underflowed,
        );
    }
}

/// Add sample values to fixed-point sums, counting clamps and underflows.
#[inline]
fn add_fixed(sum: &mut [i128], l: &[f64], saturated: &mut u64, underflowed: &mut u64) {
    for (a, &v) in sum.iter_mut().zip(l) {
        add_quantized(a, quantize(v, saturated, underflowed), saturated);
    }
}

/// A sample value in fixed point ([`to_fixed`]), clamped to the `i128` range by its sign;
/// counts the clamp, or a nonzero value that rounds to 0.
#[inline]
fn quantize(v: f64, saturated: &mut u64, underflowed: &mut u64) -> i128 {
    match to_fixed(v) {
        Some(q) => {
            if q == 0 && v != 0.0 {
                *underflowed += 1;
            }
            q
        }
        None => {
            *saturated += 1;
            if v < 0.0 {
                i128::MIN
            } else {
                i128::MAX
            }
        }
    }
}

/// Add a quantized value to a fixed-point sum. Radiance and alpha are ≥ 0, so saturating
/// addition is min(Σ, MAX): still independent of order, and every clamp is counted.
#[inline]
fn add_quantized(a: &mut i128, q: i128, saturated: &mut u64) {
    let (s, overflow) = a.overflowing_add(q);
    if overflow {
        *saturated += 1;
        *a = if q < 0 { i128::MIN } else { i128::MAX };
    } else {
        *a = s;
    }
}

/// The image being rendered: the sums over all samples so far, for the pixels of
/// `crop` (the whole image unless a tile of it is rendered).
#[derive(Clone, Debug)]
pub struct Film {
    /// Width of the full image in pixels.
    pub width: u32,
    /// Height of the full image in pixels.
    pub height: u32,
    /// The pixels this film holds.
    pub crop: Crop,
    /// Tiles covering `crop`, in row-major tile order.
    pub tiles: Vec<Tile>,
}

impl Film {
    /// An empty film of the whole `width × height` image.
    #[must_use]
    pub fn new(width: u32, height: u32) -> Film {
        Film::with_crop(width, height, Crop::full(width, height))
    }

    /// An empty film holding the pixels of `crop` of a `width × height` image, cut into
    /// [`TILE`]-sized tiles.
    ///
    /// # Panics
    /// If `crop` does not fit the image.
    #[must_use]
    pub fn with_crop(width: u32, height: u32, crop: Crop) -> Film {
        Film::with_aovs(width, height, crop, 0)
    }

    /// [`Film::with_crop`] with `aov_channels` AOV sums per pixel.
    ///
    /// # Panics
    /// If `crop` does not fit the image.
    #[must_use]
    pub fn with_aovs(width: u32, height: u32, crop: Crop, aov_channels: usize) -> Film {
        assert!(crop.fits(width, height), "crop {crop} outside the {width}x{height} image");
        let mut tiles = Vec::new();
        // Tile edges at multiples of TILE in image coordinates, and the crop's edges
        let starts = |a: u32, b: u32| {
            std::iter::successors(Some(a), move |&v| Some((v / TILE + 1) * TILE).filter(|&n| n < b))
        };
        for y0 in starts(crop.y0, crop.y1) {
            for x0 in starts(crop.x0, crop.x1) {
                let next = |v: u32, end: u32| ((v / TILE + 1) * TILE).min(end);
                let (w, h) = (next(x0, crop.x1) - x0, next(y0, crop.y1) - y0);
                let n = (w * h) as usize;
                tiles.push(Tile {
                    x0,
                    y0,
                    width: w,
                    height: h,
                    sums: vec![[0; 4]; n],
                    aov: vec![0; n * aov_channels],
                    aov_channels,
                    half: None,
                    moments: vec![Moments::default(); n],
                    saturated: 0,
                    underflowed: 0,
                });
            }
        }
        Film { width, height, crop, tiles }
    }

    /// `Some(half)`: record each sample's beauty (or what `half.filtered` says) in the
    /// half sums at AOV channel `half.at` too, when it goes to the second half buffer
    /// (`denoise::half_of(sample, half.block)`, `--denoise`); `None`: no half sums.
    ///
    /// # Panics
    /// If the half sums (5 channels from `at`) do not fit the AOV channels, or `block` is 0.
    pub fn set_half(&mut self, half: Option<HalfSums>) {
        assert!(
            half.is_none_or(|h| h.block > 0 && h.at + HALF_CHANNEL_COUNT <= self.aov_channels()),
            "invariant: half sums within the AOV channels"
        );
        for t in &mut self.tiles {
            t.half = half;
        }
    }

    /// Per-pixel values `sums / count` ([`pixel_value`], each pixel's own sample count)
    /// as `f32` RGBA, row-major over `crop`.
    #[must_use]
    pub fn average(&self) -> Vec<[f32; 4]> {
        let moments = self.moments();
        self.sums().iter().zip(&moments).map(|(s, m)| s.map(|v| pixel_value(v, m.count))).collect()
    }

    /// The exact sums, row-major over `crop`.
    #[must_use]
    pub fn sums(&self) -> Vec<[i128; 4]> {
        self.gather(|t| &t.sums)
    }

    /// Replace the sums by `sums` (row-major over `crop`), e.g. to resume a render.
    ///
    /// # Panics
    /// If `sums` does not have one entry per pixel of `crop`.
    pub fn set_sums(&mut self, sums: &[[i128; 4]]) {
        self.scatter(sums, |t| &mut t.sums);
    }

    /// The pixels' moments (squares and sample counts), row-major over `crop`.
    #[must_use]
    pub fn moments(&self) -> Vec<Moments> {
        self.gather(|t| &t.moments)
    }

    /// Replace the moments by `moments` (row-major over `crop`), e.g. to resume a render.
    ///
    /// # Panics
    /// If `moments` does not have one entry per pixel of `crop`.
    pub fn set_moments(&mut self, moments: &[Moments]) {
        self.scatter(moments, |t| &mut t.moments);
    }

    /// One per-pixel record of every tile, row-major over `crop`.
    fn gather<T: Copy + Default>(&self, of: impl Fn(&Tile) -> &Vec<T>) -> Vec<T> {
        let cw = self.crop.width() as usize;
        let mut out = vec![T::default(); self.crop.area() as usize];
        for t in &self.tiles {
            for ty in 0..t.height {
                let row = (t.y0 - self.crop.y0 + ty) as usize * cw + (t.x0 - self.crop.x0) as usize;
                let src = (ty * t.width) as usize;
                out[row..row + t.width as usize]
                    .copy_from_slice(&of(t)[src..src + t.width as usize]);
            }
        }
        out
    }

    /// Set one per-pixel record of every tile from `values`, row-major over `crop`.
    fn scatter<T: Copy>(&mut self, values: &[T], of: impl Fn(&mut Tile) -> &mut Vec<T>) {
        assert_eq!(values.len() as u64, self.crop.area(), "one value per pixel of the crop");
        let cw = self.crop.width() as usize;
        let crop = self.crop;
        for t in &mut self.tiles {
            let (x0, y0, width, height) = (t.x0, t.y0, t.width as usize, t.height);
            let dst_all = of(t);
            for ty in 0..height {
                let row = (y0 - crop.y0 + ty) as usize * cw + (x0 - crop.x0) as usize;
                let dst = ty as usize * width;
                dst_all[dst..dst + width].copy_from_slice(&values[row..row + width]);
            }
        }
    }

    /// AOV channels per pixel (0: none).
    #[must_use]
    pub fn aov_channels(&self) -> usize {
        self.tiles.first().map_or(0, |t| t.aov_channels)
    }

    /// The exact AOV sums, `aov_channels` per pixel, row-major over `crop`.
    #[must_use]
    pub fn aov_sums(&self) -> Vec<i128> {
        let n = self.aov_channels();
        let cw = self.crop.width() as usize;
        let mut out = vec![0i128; self.crop.area() as usize * n];
        for t in &self.tiles {
            for ty in 0..t.height {
                let row = (t.y0 - self.crop.y0 + ty) as usize * cw + (t.x0 - self.crop.x0) as usize;
                let src = (ty * t.width) as usize;
                out[row * n..(row + t.width as usize) * n]
                    .copy_from_slice(&t.aov[src * n..(src + t.width as usize) * n]);
            }
        }
        out
    }

    /// Replace the AOV sums by `sums` (`aov_channels` per pixel, row-major over `crop`).
    ///
    /// # Panics
    /// If `sums` does not have `aov_channels` entries per pixel of `crop`.
    pub fn set_aov_sums(&mut self, sums: &[i128]) {
        let n = self.aov_channels();
        assert_eq!(
            sums.len() as u64,
            self.crop.area() * n as u64,
            "aov_channels sums per pixel of the crop"
        );
        let cw = self.crop.width() as usize;
        let crop = self.crop;
        for t in &mut self.tiles {
            for ty in 0..t.height {
                let row = (t.y0 - crop.y0 + ty) as usize * cw + (t.x0 - crop.x0) as usize;
                let dst = (ty * t.width) as usize;
                t.aov[dst * n..(dst + t.width as usize) * n]
                    .copy_from_slice(&sums[row * n..(row + t.width as usize) * n]);
            }
        }
    }

    /// Clamped (saturated) sample values and sums over all tiles.
    #[must_use]
    pub fn saturated(&self) -> u64 {
        self.tiles.iter().map(|t| t.saturated).sum()
    }

    /// Non-zero sample values too small for the fixed-point unit, over all tiles.
    #[must_use]
    pub fn underflowed(&self) -> u64 {
        self.tiles.iter().map(|t| t.underflowed).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fixed_point_is_exact_and_saturates() {
        assert_eq!(to_fixed(1.0), Some(1i128 << 64));
        assert_eq!(to_fixed(0.75), Some(3i128 << 62));
        assert_eq!(to_fixed(2f64.powi(-65)), Some(1), "ties round away from zero");
        assert_eq!(to_fixed(2f64.powi(-66)), Some(0));
        assert_eq!(to_fixed(1e11), Some((1e11f64 as i128) << 64));
        assert_eq!(to_fixed(2f64.powi(63)), None);
        assert_eq!(to_fixed(f64::INFINITY), None);
        assert!(to_fixed(2f64.powi(63) * (1.0 - f64::EPSILON)).is_some());
        for v in [1e-9, 0.3, 1.0 / 3.0, 12345.678, 1e11] {
            let back = pixel_value(to_fixed(v).unwrap(), 1);
            assert!((f64::from(back) - v).abs() <= v * 1e-7, "{v} → {back}");
        }
        // Below 2^-40 the unit 2^-64 shows: the error is at most half a unit per sample
        let tiny = 1e-19;
        assert!((tiny - to_fixed(tiny).unwrap() as f64 * INV_SCALE).abs() <= 0.5 * INV_SCALE);
        assert_eq!(pixel_value(123, 0), 0.0);
    }

    #[test]
    fn sums_are_independent_of_split_and_order() {
        let values: Vec<f64> =
            (0..200).map(|i| ((i * 7919) % 1000) as f64 * 1.37e-3 + 1e-9 * f64::from(i)).collect();
        let sum_of = |vs: &[f64]| vs.iter().map(|&v| to_fixed(v).unwrap()).sum::<i128>();
        let whole = sum_of(&values);
        let (a, b) = values.split_at(77);
        assert_eq!(sum_of(a) + sum_of(b), whole);
        let mut rev = values.clone();
        rev.reverse();
        assert_eq!(sum_of(&rev), whole);
    }

    #[test]
    fn tile_counts_saturation_and_underflow() {
        let mut f = Film::new(2, 1);
        f.tiles[0].add_sample(0, 0, [1e300, 1e-30, 0.0, 1.0]);
        f.tiles[0].add_sample(0, 1, [1e18, 0.0, 0.0, 1.0]);
        assert_eq!(f.saturated(), 2, "one sample clamped, then one sum");
        assert_eq!(f.underflowed(), 1);
        assert_eq!(f.sums()[0][0], i128::MAX);
        assert!(f.average()[0][0].is_finite());
    }

    #[test]
    fn crop_film_round_trips_sums() {
        let crop = Crop { x0: 3, y0: 5, x1: 40, y1: 23 };
        let mut f = Film::with_crop(50, 30, crop);
        assert_eq!(f.tiles.iter().map(|t| u64::from(t.width * t.height)).sum::<u64>(), crop.area());
        let sums: Vec<[i128; 4]> =
            (0..crop.area() as i128).map(|i| [i, 2 * i, 3 * i, 4 * i]).collect();
        f.set_sums(&sums);
        assert_eq!(f.sums(), sums);
        assert_eq!("3,5,40,23".parse::<Crop>().unwrap(), crop);
        assert_eq!(crop.to_string(), "3,5,40,23");
        assert!("3,5,3,23".parse::<Crop>().is_err());
        assert_eq!(
            crop.intersection(&Crop { x0: 39, y0: 0, x1: 60, y1: 6 }),
            Some(Crop { x0: 39, y0: 5, x1: 40, y1: 6 })
        );
        assert_eq!(crop.intersection(&Crop { x0: 40, y0: 0, x1: 60, y1: 6 }), None);
    }
}
