//! Splitting by brightness (`--split-by brightness`): how many paths leave a camera
//! collision, per pixel, from a low-resolution pilot render.
//!
//! **Why.** With `--split N` every camera collision starts `N` paths of weight `1/N`
//! (`integrator::volpath`, "Splitting"). Their noise is not uniform over the image: a
//! pixel's scattered light `S` and its standard deviation grow together (on the demo
//! scene, `data/explosion.toml`, the log of the one follows the log of the other
//! closely), so the bright smoke beside the fire carries most of the squared error while
//! the dim smoke gets as many paths. Spending paths where the noise is lowers the error
//! for the cost.
//!
//! **The rule.** A pixel of block `b` (blocks of [`BLOCK`]² pixels) splits into
//!
//! ```text
//!   n_b = clamp(round(N · √S̄_b / m), 1, 4N),   m = mean of √S̄_b over the blocks the smoke covers
//! ```
//!
//! where `S̄_b` is the luminance of the light the pilot did not see directly (the beauty
//! less the camera segment's emission) at block `b`, averaged over the 3×3 blocks around
//! it, and "covered" means a pilot opacity above [`COVERED_ALPHA`]. So the mean count over
//! the covered blocks stays `N`. Paths in the bright smoke beside the fire live longer, so
//! the cost grows anyway.
//!
//! **What it gives** (docs/BENCHMARKS.md, "Splitting by brightness"). On the demo scene the
//! error falls by more than the cost grows, denoised and noisy
//! (efficiency = 1/(error² · cost)). The exponent ¼ is within the noise of ½ without the
//! denoiser; ½ is kept for its lower error with it, where the demo is judged. Dividing by the root of the pilot's cost
//! per sample gains nothing more, Neyman's `n ∝ S/√cost` loses (the pilot's noise and the
//! longer paths undo it), a mean weighted by the blocks' opacity (fewer paths in all) gains
//! less, and an oracle map from the noise of other renders does no better than this pilot.
//! On thin smoke it gives nothing (the same noise for more instructions), so it is not the
//! default.
//!
//! **Unbiased.** Any count fixed before a collision's paths are drawn keeps the split
//! unbiased (each path estimates the same in-scattered radiance; volpath's module docs).
//! The pilot draws its own numbers (another seed's stream), so a pixel's count does not
//! depend on the noise of the samples it splits.
//!
//! **Deterministic.** The pilot renders the whole frame (one pixel per block, at its
//! centre, [`PILOT_SPP`] samples) whatever part of the image, tile or sample range a
//! render computes, and the map is a function of its exact sums: the image stays a pure
//! function of (seed, pixel, sample), bit-identical for any thread count, tile, crop and
//! sample split, and a `--debug-pixel` replay builds the same map. The pilot takes
//! `4/(64·spp)` of the render's samples.
//!
//! This module is the map's data and rule; the pilot render itself is
//! [`crate::pilot::split_map`].

use super::volpath::Integrator;
pub use plume_scene::sets::SplitBy;

/// Pixels per block side: the pilot renders one pixel per `BLOCK × BLOCK` block.
pub const BLOCK: u32 = 8;

/// Samples the pilot takes at each block's pixel.
pub const PILOT_SPP: u32 = 4;

/// Pilot opacity above which a block counts as covered by the smoke (the normalisation
/// runs over those blocks).
pub const COVERED_ALPHA: f64 = 0.05;

/// Largest count, as a multiple of `--split`.
pub const MAX_FACTOR: u32 = 4;

/// What the pilot measured at one block: means over its samples.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PilotBlock {
    /// Luminance of the light not seen directly (the beauty less the camera segment's
    /// emission), clamped at 0.
    pub scattered: f64,
    /// Opacity `1 − τ` of the camera rays.
    pub alpha: f64,
}

/// Paths per camera collision for every pixel of a `width × height` image.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SplitMap {
    /// Blocks per row.
    cols: u32,
    /// Paths per collision of each block, row-major.
    paths: Vec<u32>,
}

impl SplitMap {
    /// Blocks per row and per column of a `width × height` image.
    #[must_use]
    pub fn blocks(width: u32, height: u32) -> (u32, u32) {
        (width.div_ceil(BLOCK).max(1), height.div_ceil(BLOCK).max(1))
    }

    /// The pixel the pilot renders for block `(bx, by)`: the block's centre, inside the image.
    #[must_use]
    pub fn pilot_pixel(bx: u32, by: u32, width: u32, height: u32) -> (u32, u32) {
        (
            (bx * BLOCK + BLOCK / 2).min(width.saturating_sub(1)),
            (by * BLOCK + BLOCK / 2).min(height.saturating_sub(1)),
        )
    }

    /// The map from the pilot's blocks (`cols` per row, row-major) for a mean count of
    /// `split` over the covered blocks. `None` when `split ≤ 1`, when no block is
    /// covered, or when none of them shows scattered light: then every pixel keeps `split`.
    ///
    /// # Panics
    /// If `pilot` is empty or not a whole number of rows of `cols` blocks.
    #[must_use]
    pub fn from_pilot(cols: u32, pilot: &[PilotBlock], split: u32) -> Option<SplitMap> {
        let w = cols as usize;
        assert!(
            w > 0 && !pilot.is_empty() && pilot.len() % w == 0,
            "invariant: whole rows of pilot blocks"
        );
        if split <= 1 {
            return None;
        }
        let h = pilot.len() / w;
        // √ of the scattered light averaged over the 3×3 blocks around (edges clamped)
        let root: Vec<f64> = (0..pilot.len())
            .map(|i| {
                let (x, y) = ((i % w) as isize, (i / w) as isize);
                let mut sum = 0.0;
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        let (nx, ny) = (
                            (x + dx).clamp(0, w as isize - 1) as usize,
                            (y + dy).clamp(0, h as isize - 1) as usize,
                        );
                        sum += pilot[ny * w + nx].scattered.max(0.0);
                    }
                }
                (sum / 9.0).sqrt()
            })
            .collect();
        let covered: Vec<f64> = root
            .iter()
            .zip(pilot)
            .filter(|(_, b)| b.alpha > COVERED_ALPHA)
            .map(|(r, _)| *r)
            .collect();
        let mean = covered.iter().sum::<f64>() / covered.len().max(1) as f64;
        if covered.is_empty() || !(mean > 0.0 && mean.is_finite()) {
            return None;
        }
        let n = f64::from(split);
        let most = f64::from(split.saturating_mul(MAX_FACTOR));
        let paths = root.iter().map(|r| (n * r / mean).round().clamp(1.0, most) as u32).collect();
        Some(SplitMap { cols, paths })
    }

    /// Paths per camera collision at pixel `(x, y)`.
    #[must_use]
    #[inline]
    pub fn paths(&self, x: u32, y: u32) -> u32 {
        self.paths[((y / BLOCK) * self.cols + x / BLOCK) as usize]
    }

    /// The blocks' counts, row-major.
    #[must_use]
    pub fn counts(&self) -> &[u32] {
        &self.paths
    }
}

/// The integrator of pixel `(x, y)`: `integrator` with the pixel's count from `split_map`
/// when splitting by brightness ([`crate::pilot::split_map`]), else `integrator` itself.
#[must_use]
#[inline]
pub fn pixel_integrator(
    integrator: &Integrator,
    split_map: Option<&SplitMap>,
    x: u32,
    y: u32,
) -> Integrator {
    split_map.map_or(*integrator, |m| Integrator { split: m.paths(x, y), ..*integrator })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn block(scattered: f64, alpha: f64) -> PilotBlock {
        PilotBlock { scattered, alpha }
    }

    #[test]
    fn counts_follow_the_square_root_with_the_mean_kept() {
        // A 6×4 pilot, all covered: scattered light 1 on the left half, 16 on the right,
        // so the 3×3 means differ from the blocks' own values only at the seam
        let (w, h) = (6usize, 4usize);
        let pilot: Vec<PilotBlock> = (0..w * h)
            .map(|i| if i % w < 3 { block(1.0, 0.9) } else { block(16.0, 0.9) })
            .collect();
        let map =
            SplitMap::from_pilot(w as u32, &pilot, 8).expect("a covered, lit pilot gives a map");
        let counts = map.counts();
        // Far from the seam: √1 = 1 and √16 = 4 against a mean of √ over all blocks
        let roots: Vec<f64> = (0..w * h)
            .map(|i| {
                let x = i % w;
                let lit = |x: isize| if x.clamp(0, w as isize - 1) < 3 { 1.0 } else { 16.0 };
                (((-1..=1).map(|d| lit(x as isize + d)).sum::<f64>() * 3.0) / 9.0).sqrt()
            })
            .collect();
        let mean = roots.iter().sum::<f64>() / roots.len() as f64;
        for (i, &c) in counts.iter().enumerate() {
            assert_eq!(c, (8.0 * roots[i] / mean).round().clamp(1.0, 32.0) as u32, "block {i}");
        }
        assert!(counts[0] < counts[w - 1], "the brighter side gets more paths: {counts:?}");
        // The mean count over the covered blocks stays near the uniform split
        let mean_count = counts.iter().map(|&c| f64::from(c)).sum::<f64>() / counts.len() as f64;
        assert!((mean_count - 8.0).abs() < 0.5, "mean count {mean_count}");
        // Pixels read their block
        assert_eq!(map.paths(0, 0), counts[0]);
        assert_eq!(map.paths(5 * BLOCK + 3, 3 * BLOCK + 7), counts[3 * w + 5]);
    }

    #[test]
    fn uncovered_blocks_do_not_set_the_mean_and_counts_are_clamped() {
        // One covered block among dark uncovered ones, and a blazing uncovered one far off
        let w = 7usize;
        let mut pilot = vec![block(0.0, 0.0); w * 5];
        pilot[2 * w + 1] = block(4.0, 0.5);
        pilot[2 * w + 6] = block(1e6, 0.01);
        let map = SplitMap::from_pilot(w as u32, &pilot, 6).expect("one covered block suffices");
        // The covered block's own 3×3 mean is 4/9, which is the mean: it gets 6
        assert_eq!(map.counts()[2 * w + 1], 6);
        // Dark blocks get one path, the blazing one at most 4 × 6
        assert_eq!(map.counts()[0], 1);
        assert_eq!(map.counts()[2 * w + 6], 24);
    }

    #[test]
    fn no_map_without_splitting_cover_or_light() {
        let lit = vec![block(1.0, 0.9); 4];
        assert!(SplitMap::from_pilot(2, &lit, 1).is_none());
        assert!(SplitMap::from_pilot(2, &[block(1.0, 0.0); 4], 8).is_none());
        assert!(SplitMap::from_pilot(2, &[block(0.0, 0.9); 4], 8).is_none());
        // A NaN pilot value counts as no light
        assert!(SplitMap::from_pilot(2, &[block(f64::NAN, 0.9); 4], 8).is_none());
    }

    #[test]
    fn blocks_cover_the_image_and_pilot_pixels_lie_inside() {
        assert_eq!(SplitMap::blocks(640, 480), (80, 60));
        assert_eq!(SplitMap::blocks(641, 1), (81, 1));
        assert_eq!(SplitMap::pilot_pixel(0, 0, 640, 480), (4, 4));
        assert_eq!(SplitMap::pilot_pixel(80, 0, 641, 3), (640, 2));
    }
}
