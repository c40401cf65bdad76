//! Colour: the [`Rgb`] type (linear Rec.709) and blackbody emission.

pub mod blackbody;
pub mod cie1931;

use std::ops::{Add, AddAssign, Div, Mul, MulAssign};

/// Rec.709 luminance of an `f64` triple: the weights of [`Rgb::luminance`], in `f64`.
#[must_use]
#[inline]
pub fn rec709_luminance(rgb: [f64; 3]) -> f64 {
    0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]
}

/// Linear Rec.709 RGB triple (radiance or emission density; never a position).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Rgb(pub [f32; 3]);

impl Rgb {
    /// Black.
    pub const ZERO: Rgb = Rgb([0.0; 3]);
    /// White (1, 1, 1).
    pub const ONE: Rgb = Rgb([1.0; 3]);

    /// A grey of value `v`.
    #[must_use]
    pub const fn splat(v: f32) -> Rgb {
        Rgb([v, v, v])
    }

    /// Luminance `Y = 0.2126 R + 0.7152 G + 0.0722 B` (Rec.709 / sRGB primaries, D65).
    #[must_use]
    pub fn luminance(self) -> f32 {
        0.2126 * self.0[0] + 0.7152 * self.0[1] + 0.0722 * self.0[2]
    }

    /// Largest component.
    #[must_use]
    pub fn max_component(self) -> f32 {
        self.0[0].max(self.0[1]).max(self.0[2])
    }

    /// True when all components are zero.
    #[must_use]
    pub fn is_black(self) -> bool {
        self.0 == [0.0; 3]
    }

    /// True when every component is finite.
    #[must_use]
    pub fn is_finite(self) -> bool {
        self.0.iter().all(|c| c.is_finite())
    }

    /// As `f64` components.
    #[must_use]
    pub fn to_f64(self) -> [f64; 3] {
        self.0.map(f64::from)
    }
}

impl Add for Rgb {
    type Output = Rgb;
    fn add(self, o: Rgb) -> Rgb {
        Rgb([self.0[0] + o.0[0], self.0[1] + o.0[1], self.0[2] + o.0[2]])
    }
}
impl AddAssign for Rgb {
    fn add_assign(&mut self, o: Rgb) {
        *self = *self + o;
    }
}
impl Mul for Rgb {
    type Output = Rgb;
    fn mul(self, o: Rgb) -> Rgb {
        Rgb([self.0[0] * o.0[0], self.0[1] * o.0[1], self.0[2] * o.0[2]])
    }
}
impl Mul<f32> for Rgb {
    type Output = Rgb;
    fn mul(self, s: f32) -> Rgb {
        Rgb(self.0.map(|c| c * s))
    }
}
impl MulAssign<f32> for Rgb {
    fn mul_assign(&mut self, s: f32) {
        *self = *self * s;
    }
}
impl Div<f32> for Rgb {
    type Output = Rgb;
    fn div(self, s: f32) -> Rgb {
        Rgb(self.0.map(|c| c / s))
    }
}
