//! Splitting one frame across processes: pixel crops (`--crop`, `--tile i/n`) and sample
//! ranges (`--sample-range a..b`). Every pixel sample is a pure function of (seed, pixel,
//! sample index) and the film sums are exact integers, so any split merges
//! (`plume merge`) to the bits of the unsplit render.

use std::ops::Range;

use crate::pixels::Crop;

/// Parse `--tile i/n` (0-based `i`, `0 ≤ i < n`).
///
/// # Errors
/// A message when the text is not `i/n` with `i < n`.
pub fn parse_tile(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("expected i/n with 0 ≤ i < n (tiles are numbered from 0), got {s:?}");
    let (i, n) = s.split_once('/').ok_or_else(bad)?;
    let (i, n): (u32, u32) =
        (i.trim().parse().map_err(|_| bad())?, n.trim().parse().map_err(|_| bad())?);
    if n == 0 || i >= n {
        return Err(bad());
    }
    Ok((i, n))
}

/// The pixels of tile `i` of `n` over a `width × height` image: a grid of `cols × rows`
/// tiles, `rows` the largest divisor of `n` not above √n (more columns than rows for a
/// landscape image, the other way round for a portrait one), numbered row by row from
/// the top left. Tile edges are `⌊k · width / cols⌋`, so the tiles cover the image exactly;
/// with `align` > 1 inner edges are rounded to the nearest multiple of it (adaptive
/// sampling's blocks).
///
/// # Errors
/// A message when the grid has more columns or rows than the image has pixels (or blocks).
pub fn tile_crop(i: u32, n: u32, width: u32, height: u32, align: u32) -> Result<Crop, String> {
    let small = (1..=n)
        .filter(|d| n % d == 0 && u64::from(*d) * u64::from(*d) <= u64::from(n))
        .max()
        .unwrap_or(1);
    let (cols, rows) = if width >= height { (n / small, small) } else { (small, n / small) };
    if cols > width || rows > height {
        return Err(format!("{n} tiles ({cols}x{rows}) do not fit a {width}x{height} image"));
    }
    let (c, r) = (i % cols, i / cols);
    let align = align.max(1);
    let edge = |k: u32, count: u32, size: u32| {
        let e = (u64::from(k) * u64::from(size) / u64::from(count)) as u32;
        if k == count {
            size
        } else {
            ((e + align / 2) / align * align).min(size)
        }
    };
    let blocks = |size: u32| size.div_ceil(align);
    if align > 1 && (cols > blocks(width) || rows > blocks(height)) {
        return Err(format!(
            "{n} tiles ({cols}x{rows}) do not fit a {width}x{height} image in blocks of {align} pixels (adaptive sampling)"
        ));
    }
    Ok(Crop {
        x0: edge(c, cols, width),
        x1: edge(c + 1, cols, width),
        y0: edge(r, rows, height),
        y1: edge(r + 1, rows, height),
    })
}

/// Parse `--sample-range a..b`: sample indices a to b − 1.
///
/// # Errors
/// A message when the text is not `a..b` with `a < b`.
pub fn parse_sample_range(s: &str) -> Result<Range<u64>, String> {
    let bad = || format!("expected a..b (samples a to b−1, a < b), got {s:?}");
    let (a, b) = s.split_once("..").ok_or_else(bad)?;
    let (a, b): (u64, u64) =
        (a.trim().parse().map_err(|_| bad())?, b.trim().parse().map_err(|_| bad())?);
    if a >= b {
        return Err(bad());
    }
    Ok(a..b)
}

/// `a..b`, the `--sample-range` syntax.
#[must_use]
pub fn format_range(r: &Range<u64>) -> String {
    format!("{}..{}", r.start, r.end)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_cover_the_image_exactly() {
        for (n, w, h) in [(4, 33, 17), (6, 40, 30), (5, 20, 50), (1, 7, 7), (12, 64, 64)] {
            let mut count = vec![0u8; (w * h) as usize];
            for i in 0..n {
                let c = tile_crop(i, n, w, h, 1).unwrap();
                assert!(!c.is_empty());
                for y in c.y0..c.y1 {
                    for x in c.x0..c.x1 {
                        count[(y * w + x) as usize] += 1;
                    }
                }
            }
            assert!(count.iter().all(|&k| k == 1), "{n} tiles over {w}x{h}");
        }
        assert_eq!(tile_crop(3, 4, 32, 16, 1).unwrap(), Crop { x0: 16, y0: 8, x1: 32, y1: 16 });
        // Aligned to blocks of 16: inner edges at multiples of 16, the image edges kept
        assert_eq!(tile_crop(1, 2, 50, 20, 16).unwrap(), Crop { x0: 32, y0: 0, x1: 50, y1: 20 });
        assert!(tile_crop(0, 4, 40, 20, 16).is_ok());
        assert!(tile_crop(0, 8, 40, 20, 16).is_err(), "4 columns of 16 do not fit 40");
        assert!(tile_crop(0, 8, 3, 100, 1).is_ok(), "8 = 2x4 fits as 2 columns");
        assert!(tile_crop(0, 64, 4, 4, 1).is_err());
    }

    #[test]
    fn parses_tiles_and_sample_ranges() {
        assert_eq!(parse_tile("3/4").unwrap(), (3, 4));
        assert!(parse_tile("4/4").unwrap_err().contains("from 0"));
        assert!(parse_tile("1").is_err());
        assert_eq!(parse_sample_range("32..64").unwrap(), 32..64);
        assert!(parse_sample_range("5..5").is_err());
        assert!(parse_sample_range("5-9").is_err());
        assert_eq!(format_range(&(3..9)), "3..9");
    }
}
