//! Film: per-pixel `f64` sums of RGB and alpha, filled tile by tile.
//!
//! Each tile owns its pixels; a pixel's samples are always added in sample order by the
//! one thread that owns its tile, so the sums, and the image, are the same bytes for any
//! thread count (STYLE.md §8).

/// Tile edge in pixels.
pub const TILE: u32 = 16;

/// A rectangle of pixels with its own sums.
#[derive(Clone, Debug)]
pub struct Tile {
    /// Left pixel column.
    pub x0: u32,
    /// Top pixel row.
    pub y0: u32,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `[r, g, b, alpha]` sums, row-major within the tile.
    pub sums: Vec<[f64; 4]>,
}

/// The image being rendered: the sums over all samples so far.
#[derive(Clone, Debug)]
pub struct Film {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Tiles in row-major tile order.
    pub tiles: Vec<Tile>,
}

impl Film {
    /// An empty film cut into [`TILE`]-sized tiles.
    #[must_use]
    pub fn new(width: u32, height: u32) -> Film {
        let mut tiles = Vec::new();
        for y0 in (0..height).step_by(TILE as usize) {
            for x0 in (0..width).step_by(TILE as usize) {
                let (w, h) = (TILE.min(width - x0), TILE.min(height - y0));
                tiles.push(Tile { x0, y0, width: w, height: h, sums: vec![[0.0; 4]; (w * h) as usize] });
            }
        }
        Film { width, height, tiles }
    }

    /// Per-pixel averages `sums / spp` as `f32` RGBA, row-major.
    #[must_use]
    pub fn average(&self, spp: u64) -> Vec<[f32; 4]> {
        let inv = if spp > 0 { 1.0 / spp as f64 } else { 0.0 };
        let mut out = vec![[0.0f32; 4]; (self.width * self.height) as usize];
        for t in &self.tiles {
            for ty in 0..t.height {
                for tx in 0..t.width {
                    let s = t.sums[(ty * t.width + tx) as usize];
                    out[((t.y0 + ty) * self.width + t.x0 + tx) as usize] = s.map(|v| (v * inv) as f32);
                }
            }
        }
        out
    }
}
