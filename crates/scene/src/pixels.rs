//! Pixels: a rectangle of the full image ([`Crop`], the `--crop` syntax `x0,y0,x1,y1`) and
//! the key of one pixel sample ([`SampleId`], the `--debug-pixel` syntax `x,y,s`).

use std::fmt;
use std::str::FromStr;

/// The key of one pixel sample: sample `sample` of pixel `(x, y)` of the full image.
/// Displayed as `x,y,sample`, the form `--debug-pixel` takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub struct SampleId {
    /// Pixel column, from the left of the full image.
    pub x: u32,
    /// Pixel row, from the top of the full image.
    pub y: u32,
    /// Sample index within the pixel.
    pub sample: u64,
}

impl SampleId {
    /// Keep in `first` the earlier of it and `self` in (row, column, sample) order: the
    /// order in which a single-threaded render would meet them.
    pub fn keep_earliest(self, first: &mut Option<SampleId>) {
        if first.is_none_or(|f| (self.y, self.x, self.sample) < (f.y, f.x, f.sample)) {
            *first = Some(self);
        }
    }
}

impl std::fmt::Display for SampleId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{},{},{}", self.x, self.y, self.sample)
    }
}

impl std::str::FromStr for SampleId {
    type Err = String;

    /// Parse `x,y,s` (pixel column, row, sample index), the `--debug-pixel` syntax.
    fn from_str(s: &str) -> Result<SampleId, String> {
        let p: Vec<&str> = s.split(',').map(str::trim).collect();
        let bad = || format!("expected X,Y,S (pixel column, row, sample index), got {s:?}");
        if p.len() != 3 {
            return Err(bad());
        }
        Ok(SampleId {
            x: p[0].parse().map_err(|_| bad())?,
            y: p[1].parse().map_err(|_| bad())?,
            sample: p[2].parse().map_err(|_| bad())?,
        })
    }
}

/// A pixel rectangle `[x0, x1) × [y0, y1)` of the full image (a crop or a film tile).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Crop {
    /// First column.
    pub x0: u32,
    /// First row.
    pub y0: u32,
    /// One past the last column.
    pub x1: u32,
    /// One past the last row.
    pub y1: u32,
}

impl Crop {
    /// The whole `width × height` image.
    #[must_use]
    pub fn full(width: u32, height: u32) -> Crop {
        Crop { x0: 0, y0: 0, x1: width, y1: height }
    }

    /// Width in pixels.
    #[must_use]
    pub fn width(&self) -> u32 {
        self.x1.saturating_sub(self.x0)
    }

    /// Height in pixels.
    #[must_use]
    pub fn height(&self) -> u32 {
        self.y1.saturating_sub(self.y0)
    }

    /// Number of pixels.
    #[must_use]
    pub fn area(&self) -> u64 {
        u64::from(self.width()) * u64::from(self.height())
    }

    /// True when the rectangle has no pixels.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.area() == 0
    }

    /// True when the rectangle lies inside a `width × height` image.
    #[must_use]
    pub fn fits(&self, width: u32, height: u32) -> bool {
        self.x0 <= self.x1 && self.y0 <= self.y1 && self.x1 <= width && self.y1 <= height
    }

    /// True when `other` lies inside `self`.
    #[must_use]
    pub fn contains(&self, other: &Crop) -> bool {
        other.x0 >= self.x0 && other.x1 <= self.x1 && other.y0 >= self.y0 && other.y1 <= self.y1
    }

    /// The common pixels of two rectangles, if any.
    #[must_use]
    pub fn intersection(&self, other: &Crop) -> Option<Crop> {
        let c = Crop {
            x0: self.x0.max(other.x0),
            y0: self.y0.max(other.y0),
            x1: self.x1.min(other.x1),
            y1: self.y1.min(other.y1),
        };
        (c.x0 < c.x1 && c.y0 < c.y1).then_some(c)
    }
}

impl fmt::Display for Crop {
    /// `x0,y0,x1,y1`, the `--crop` syntax.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{},{},{},{}", self.x0, self.y0, self.x1, self.y1)
    }
}

impl FromStr for Crop {
    type Err = String;

    /// Parse `x0,y0,x1,y1` (pixels, half-open: columns x0 to x1−1, rows y0 to y1−1).
    fn from_str(s: &str) -> Result<Crop, String> {
        let v: Vec<&str> = s.split(',').map(str::trim).collect();
        let bad = || format!("expected x0,y0,x1,y1 in pixels (x1 > x0, y1 > y0), got {s:?}");
        if v.len() != 4 {
            return Err(bad());
        }
        let n: Vec<u32> =
            v.iter().map(|p| p.parse::<u32>()).collect::<Result<_, _>>().map_err(|_| bad())?;
        let c = Crop { x0: n[0], y0: n[1], x1: n[2], y1: n[3] };
        if c.x1 <= c.x0 || c.y1 <= c.y0 {
            return Err(bad());
        }
        Ok(c)
    }
}
