//! What a pixel's error estimate needs besides its sums (`noise`): the sums of its
//! samples' squared colour, its sample count, and its two most recent **sample levels**.
//!
//! A square `v²` is rounded to units of 2^−F like a value (`film::to_fixed`) and added in
//! `i128`, so moments, like sums, are exact integers whatever the split of the work. A
//! square beyond the `i128` range (|v| ≥ 2^31.5) saturates the sum; the pixel's error is
//! then infinite.
//!
//! **Levels.** Sample `s ≥ 1` lies in level `⌊log₂ s⌋`, the samples `[2^ℓ, 2^{ℓ+1})`;
//! sample 0 in level −1. With Owen-scrambled Sobol points the samples `[0, 2^k)` of a pixel
//! are a stratified net, and so are those of each level. A pixel keeps the colour sums of
//! the highest level it holds a sample of (`upper`, level `top`) and of the one below
//! (`lower`): with `n ≥ 3` samples, `lower` is complete and the samples before it,
//! `[0, 2^{top−1})`, are a net of the same size, so the two halves measure how much a net
//! of that size actually varies, Sobol gain included (`noise`). The two highest levels
//! are a function of which samples a pixel holds, not of their order, so parts rendered
//! as sample ranges merge to them exactly ([`Moments::plus`]).

/// The level of sample `s`: `⌊log₂ s⌋`, and −1 for sample 0.
#[must_use]
#[inline]
pub fn level(s: u64) -> i32 {
    if s == 0 {
        -1
    } else {
        63 - s.leading_zeros() as i32
    }
}

/// A pixel's moments (module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Moments {
    /// `Σ r²`, `Σ g²`, `Σ b²` over the pixel's samples, in units of 2^−F.
    pub squares: [i128; 3],
    /// Samples the pixel holds, dropped non-finite ones included (they count as zero,
    /// as in the pixel's mean).
    pub count: u64,
    /// The highest level the pixel holds a sample of (−2: none).
    pub top: i32,
    /// The colour sums of level `top − 1`, in units of 2^−F.
    pub lower: [i128; 3],
    /// The colour sums of level `top`, in units of 2^−F.
    pub upper: [i128; 3],
}

impl Default for Moments {
    fn default() -> Moments {
        Moments { squares: [0; 3], count: 0, top: -2, lower: [0; 3], upper: [0; 3] }
    }
}

/// Names of a pixel's moments as exact `i128` channels, in [`Moments::to_values`] order:
/// the squares, the count, the lower and upper level sums and the top level.
pub const CHANNELS: [&str; 11] =
    ["R2", "G2", "B2", "n", "lowerR", "lowerG", "lowerB", "upperR", "upperG", "upperB", "top"];

impl Moments {
    /// The moments as the `i128` values of [`CHANNELS`].
    #[must_use]
    pub fn to_values(&self) -> [i128; 11] {
        let [r2, g2, b2] = self.squares;
        let [lr, lg, lb] = self.lower;
        let [ur, ug, ub] = self.upper;
        [r2, g2, b2, i128::from(self.count), lr, lg, lb, ur, ug, ub, i128::from(self.top)]
    }

    /// The moments from the `i128` values of [`CHANNELS`] (`None` for a count or level
    /// out of range).
    #[must_use]
    pub fn from_values(v: [i128; 11]) -> Option<Moments> {
        Some(Moments {
            squares: [v[0], v[1], v[2]],
            count: u64::try_from(v[3]).ok()?,
            lower: [v[4], v[5], v[6]],
            upper: [v[7], v[8], v[9]],
            top: i32::try_from(v[10]).ok().filter(|t| (-2..64).contains(t))?,
        })
    }

    /// Add sample `s` with colour `rgb` (fixed point) and squares `squares`.
    #[inline]
    pub fn add(&mut self, s: u64, rgb: [i128; 3], squares: [i128; 3]) {
        for (a, v) in self.squares.iter_mut().zip(squares) {
            *a = a.saturating_add(v);
        }
        self.count += 1;
        self.add_to_level(level(s), rgb);
    }

    /// Count sample `s`, dropped (non-finite): a zero in the mean, in its level too.
    #[inline]
    pub fn add_dropped(&mut self, s: u64) {
        self.count += 1;
        self.add_to_level(level(s), [0; 3]);
    }

    /// Add `rgb` to level `l`, moving the two kept levels up when `l` is above them.
    #[inline]
    fn add_to_level(&mut self, l: i32, rgb: [i128; 3]) {
        if l > self.top {
            self.lower = if l == self.top + 1 { self.upper } else { [0; 3] };
            self.upper = [0; 3];
            self.top = l;
        }
        let into = if l == self.top {
            &mut self.upper
        } else if l == self.top - 1 {
            &mut self.lower
        } else {
            return;
        };
        for (a, v) in into.iter_mut().zip(rgb) {
            *a = a.saturating_add(v);
        }
    }

    /// Add the moments of another, disjoint set of samples of the same pixel (merging
    /// parts, whose sample ranges join into one).
    #[must_use]
    pub fn plus(self, other: Moments) -> Moments {
        let mut out = Moments {
            squares: std::array::from_fn(|c| self.squares[c].saturating_add(other.squares[c])),
            count: self.count + other.count,
            ..Moments::default()
        };
        for m in [self, other] {
            if m.top > -2 {
                out.add_to_level(m.top - 1, m.lower);
                out.add_to_level(m.top, m.upper);
            }
        }
        out
    }

    /// Two halves of the pixel's samples that are nets of the same size, as colour sums
    /// and that size: `(A, B, h)` with `A` the samples `[0, h)` and `B` the level
    /// `[h, 2h)` (`rgb` is the pixel's total colour sum). When the pixel holds exactly
    /// `2^{top+1}` samples, its whole top level is `B` (`h = 2^top`); otherwise the level
    /// below it (`h = 2^{top−1}`). `None` with fewer than two samples.
    #[must_use]
    pub fn halves(&self, rgb: [i128; 3]) -> Option<([i128; 3], [i128; 3], u64)> {
        if self.top >= 0 && self.count == 1u64 << (self.top + 1) {
            let a = std::array::from_fn(|c| rgb[c].saturating_sub(self.upper[c]));
            return Some((a, self.upper, 1u64 << self.top));
        }
        if self.top < 1 {
            return None;
        }
        let a = std::array::from_fn(|c| {
            rgb[c].saturating_sub(self.upper[c]).saturating_sub(self.lower[c])
        });
        Some((a, self.lower, 1u64 << (self.top - 1)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pixel(samples: impl Iterator<Item = u64>) -> Moments {
        let mut m = Moments::default();
        for s in samples {
            let v = i128::from(s) + 1;
            m.add(s, [v, 2 * v, 3 * v], [v * v; 3]);
        }
        m
    }

    #[test]
    fn values_round_trip() {
        let m = pixel(0..37);
        assert_eq!(Moments::from_values(m.to_values()), Some(m));
        assert_eq!(Moments::from_values(Moments::default().to_values()), Some(Moments::default()));
        let mut bad = m.to_values();
        bad[3] = -1;
        assert_eq!(Moments::from_values(bad), None);
    }

    #[test]
    fn levels_are_powers_of_two() {
        let got: Vec<i32> = (0..9).map(level).collect();
        assert_eq!(got, [-1, 0, 1, 1, 2, 2, 2, 2, 3]);
    }

    /// The two top levels and the halves of 0..11: top level 3 ([8, 11)), level 2
    /// ([4, 8)) below it, A = [0, 4).
    #[test]
    fn halves_are_the_net_before_the_top_level_and_the_level_below() {
        let m = pixel(0..11);
        assert_eq!((m.top, m.count), (3, 11));
        let value = |r: std::ops::Range<u64>| r.map(|s| i128::from(s) + 1).sum::<i128>();
        assert_eq!(m.upper[0], value(8..11));
        assert_eq!(m.lower[0], value(4..8));
        let total = value(0..11);
        let (a, b, h) = m.halves([total, 2 * total, 3 * total]).unwrap();
        assert_eq!((a[0], b[0], h), (value(0..4), value(4..8), 4));
        // 16 samples: the whole top level [8, 16) against [0, 8)
        let m = pixel(0..16);
        let total = value(0..16);
        let (a, b, h) = m.halves([total; 3]).unwrap();
        assert_eq!((a[0], b[0], h), (value(0..8), value(8..16), 8));
        assert!(pixel(0..1).halves([0; 3]).is_none());
    }

    /// Order does not matter, and parts as sample ranges merge to the whole.
    #[test]
    fn any_order_and_any_split_give_the_same_moments() {
        let whole = pixel(0..100);
        assert_eq!(pixel((0..100).rev()), whole);
        for cut in [1, 3, 37, 64, 65, 99] {
            assert_eq!(pixel(0..cut).plus(pixel(cut..100)), whole, "cut at {cut}");
            assert_eq!(pixel(cut..100).plus(pixel(0..cut)), whole, "cut at {cut}, reversed");
        }
        let three = pixel(0..20).plus(pixel(20..70)).plus(pixel(70..100));
        assert_eq!(three, whole);
    }
}
