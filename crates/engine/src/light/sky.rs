//! A physical daylight sky: Preetham, Shirley & Smits (1999), "A Practical Analytic
//! Model for Daylight" (SIGGRAPH 99), with the sun disc of its appendix ([`sun`]), and
//! plume's lat-long environment-map convention ([`latlong_direction`], [`latlong_uv`]).
//!
//! # Frame and conventions
//!
//! The sky's local frame has +Z at the zenith. The sun at elevation `e` and azimuth `a`
//! (degrees; azimuth from +X towards +Y) lies towards `s = (cos e cos a, cos e sin a,
//! sin e)`, at θs = 90° − e from the zenith. A view direction `d` is θ from the zenith
//! (cos θ = d.z) and γ from the sun (cos γ = d·s).
//!
//! # The model
//!
//! Each of luminance Y and chromaticities x, y follows the Perez et al. (1993)
//! distribution, relative to its value at the zenith:
//!
//! ```text
//! F(θ, γ) = (1 + A e^{B / cos θ}) (1 + C e^{D γ} + E cos² γ)
//! Y(θ, γ) = Y_z F_Y(θ, γ) / F_Y(0, θs)       (likewise x, y)
//! ```
//!
//! with A…E linear in the turbidity T (paper, appendix A.2; [`perez_coefficients`]), the
//! zenith luminance in kcd m⁻²
//!
//! ```text
//! Y_z = (4.0453 T − 4.9710) tan χ − 0.2155 T + 2.4192,   χ = (4/9 − T/120)(π − 2 θs)
//! ```
//!
//! and the zenith chromaticities `x_z = [T² T 1] M_x [θs³ θs² θs 1]ᵀ` (θs in radians;
//! likewise y_z with M_y; [`zenith`]). Then `X = x Y / y`, `Z = (1 − x − y) Y / y`, and
//! linear Rec.709 `C = M₇₀₉ (X, Y, Z)` ([`plume_core::color::blackbody::xyz_to_rec709`]).
//!
//! # Units
//!
//! plume's radiance unit is W m⁻² sr⁻¹ per linear Rec.709 channel, scaled so that the
//! luminance `0.2126 R + 0.7152 G + 0.0722 B` is the photometric luminance / 683
//! (cd m⁻² ÷ 683 lm/W). The model's Y in kcd m⁻² therefore enters as `1000 Y / 683`.
//! (`M₇₀₉`'s rounding makes the Rec.709 luminance differ from Y by ≈ 2e-4.)
//!
//! # Validity and what is approximated
//!
//! - The fit covers T ∈ [1.7, 10] (outside it the coefficients go unphysical;
//!   [`Sky::new`] refuses them) and θs ∈ [0°, 90°].
//! - Near the horizon `1/cos θ` diverges: cos θ is clamped to at least
//!   [`COS_THETA_MIN`] = 1e-3 (0.06° elevation). Over the fitted range B ≤ −0.11, so
//!   `e^{B / cos θ}` is then below e^{−110}: the clamp only keeps the division finite.
//! - **Below the horizon** (d.z < 0) the radiance is zero: a black ground. Nothing
//!   reflects or scatters from below.
//! - **Sun below the horizon** (e < 0): the fit does not cover twilight. The sky is the
//!   model's sky for a sun on the horizon (θs = 90° for Y_z, x_z, y_z and F(0, θs); γ
//!   from the true sun direction), dimmed linearly to black at e = −6° (the end of civil
//!   twilight) so that a sunset does not jump. This fade is plume's, not the paper's.
//!   The sun disc is zero below the horizon.
//! - Colours outside the Rec.709 gamut (a low sun's deep red; rarely the sky) are
//!   desaturated towards the grey of the same luminance until the smallest channel is 0
//!   ([`rec709_in_gamut`]): luminance is kept, saturation is lost.
//! - Against measurements the fit is rough: Zotti, Wilkie & Purgathofer (2007, "A Critical
//!   Review of the Preetham Skylight Model", WSCG) compare it with the CIE standard skies
//!   and measured clear skies. For T = 2–3 and a sun 30–60° high it gives 24–32 klux of
//!   sky illuminance on a horizontal plane (typical measured clear skies: ≈ 10–25 klux),
//!   most of the excess from a bright band near the horizon (T = 2, sun 30° high: the
//!   horizon 90° from the sun is ≈ 4.5× the zenith). Above T ≈ 8.2 (A_Y > 0) the fit darkens the horizon instead.
//! - The sun disc ([`sun`]): a 5778 K blackbody scaled to 1361 W m⁻², uniform over
//!   0.53°, attenuated by Rayleigh and Ångström aerosol scattering and ozone, mixed-gas
//!   and water-vapour absorption along Kasten's air mass.
//! - Copies of M_x differ in one entry, −0.03202 or −0.03203; we use −0.03202 (the
//!   difference in x_z is below 1e-5).
//!
//! # Environment map
//!
//! [`Sky::image`] samples the sky at lat-long pixel centres. The sun disc (0.53°) is
//! usually smaller than a pixel, so it is added to the one pixel containing the sun
//! direction, scaled by (disc solid angle / pixel solid angle): the image then carries
//! the sun's exact energy ([`latlong_pixel_solid_angle`]). A sun exactly on the horizon
//! goes to the row above it.

pub mod sun;

use std::f64::consts::PI;

use glam::DVec3;
use rayon::prelude::*;

use plume_core::color::blackbody::xyz_to_rec709;
use plume_core::color::Rgb;
use plume_core::error::Result;
pub use plume_scene::lights::{SkyParams, TURBIDITY_RANGE};

/// Smallest cos θ used in the Perez gradation term `e^{B / cos θ}` (see the module docs).
pub const COS_THETA_MIN: f64 = 1e-3;

/// Sun elevation, degrees, at which the twilight fade reaches black (civil twilight).
pub const TWILIGHT_END_DEGREES: f64 = -6.0;

/// Luminous efficacy of radiation at 555 nm, lm/W: plume units = cd m⁻² / 683.
pub const LUMENS_PER_WATT: f64 = 683.0;

/// Coefficients A…E of one Perez distribution.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Perez {
    /// Horizon darkening or brightening.
    pub a: f64,
    /// Luminance gradient near the horizon.
    pub b: f64,
    /// Circumsolar region intensity.
    pub c: f64,
    /// Circumsolar region width.
    pub d: f64,
    /// Backscattered light.
    pub e: f64,
}

impl Perez {
    /// `F(θ, γ) = (1 + A e^{B / cos θ})(1 + C e^{D γ} + E cos² γ)`, with cos θ clamped to
    /// at least [`COS_THETA_MIN`]; γ in radians.
    #[must_use]
    pub fn f(&self, cos_theta: f64, gamma: f64) -> f64 {
        let gradation = 1.0 + self.a * (self.b / cos_theta.max(COS_THETA_MIN)).exp();
        let cos_gamma = gamma.cos();
        let indicatrix = 1.0 + self.c * (self.d * gamma).exp() + self.e * cos_gamma * cos_gamma;
        gradation * indicatrix
    }
}

/// The three Perez distributions of the model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SkyCoefficients {
    /// For the luminance Y.
    pub luminance: Perez,
    /// For the chromaticity x.
    pub x: Perez,
    /// For the chromaticity y.
    pub y: Perez,
}

/// Preetham's Perez coefficients at turbidity `t` (paper, appendix A.2).
#[must_use]
pub fn perez_coefficients(t: f64) -> SkyCoefficients {
    // Rows A…E: (slope, intercept) in T.
    let linear = |rows: [(f64, f64); 5]| {
        let [a, b, c, d, e] = rows.map(|(slope, intercept)| slope * t + intercept);
        Perez { a, b, c, d, e }
    };
    SkyCoefficients {
        luminance: linear([
            (0.1787, -1.4630),
            (-0.3554, 0.4275),
            (-0.0227, 5.3251),
            (0.1206, -2.5771),
            (-0.0670, 0.3703),
        ]),
        x: linear([
            (-0.0193, -0.2592),
            (-0.0665, 0.0008),
            (-0.0004, 0.2125),
            (-0.0641, -0.8989),
            (-0.0033, 0.0452),
        ]),
        y: linear([
            (-0.0167, -0.2608),
            (-0.0950, 0.0092),
            (-0.0079, 0.2102),
            (-0.0441, -1.6537),
            (-0.0109, 0.0529),
        ]),
    }
}

/// Sky values at the zenith.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Zenith {
    /// Luminance Y_z, kcd m⁻².
    pub luminance: f64,
    /// CIE 1931 chromaticity x_z.
    pub x: f64,
    /// CIE 1931 chromaticity y_z.
    pub y: f64,
}

/// Zenith chromaticity matrix M_x (rows T², T, 1; columns θs³, θs², θs, 1).
const ZENITH_X: [[f64; 4]; 3] = [
    [0.00166, -0.00375, 0.00209, 0.0],
    [-0.02903, 0.06377, -0.03202, 0.00394],
    [0.11693, -0.21196, 0.06052, 0.25886],
];

/// Zenith chromaticity matrix M_y.
const ZENITH_Y: [[f64; 4]; 3] = [
    [0.00275, -0.00610, 0.00317, 0.0],
    [-0.04214, 0.08970, -0.04153, 0.00516],
    [0.15346, -0.26756, 0.06670, 0.26688],
];

/// Zenith luminance and chromaticity at turbidity `t`, sun `theta_s` radians from the
/// zenith (paper, appendix A.2).
#[must_use]
pub fn zenith(t: f64, theta_s: f64) -> Zenith {
    let chi = (4.0 / 9.0 - t / 120.0) * (PI - 2.0 * theta_s);
    let luminance = (4.0453 * t - 4.9710) * chi.tan() - 0.2155 * t + 2.4192;
    let turbidity_powers = [t * t, t, 1.0];
    let angle_powers = [theta_s.powi(3), theta_s * theta_s, theta_s, 1.0];
    let bilinear = |m: &[[f64; 4]; 3]| -> f64 {
        m.iter()
            .zip(turbidity_powers)
            .map(|(row, t_power)| {
                t_power
                    * row
                        .iter()
                        .zip(angle_powers)
                        .map(|(c, angle_power)| c * angle_power)
                        .sum::<f64>()
            })
            .sum()
    };
    Zenith { luminance, x: bilinear(&ZENITH_X), y: bilinear(&ZENITH_Y) }
}

/// A daylight sky and its sun, ready to evaluate (see the module docs).
#[derive(Clone, Debug)]
pub struct Sky {
    params: SkyParams,
    /// Unit direction towards the sun.
    sun: DVec3,
    coefficients: SkyCoefficients,
    zenith: Zenith,
    /// `[Y_z / F_Y(0, θs), x_z / F_x(0, θs), y_z / F_y(0, θs)]`, Y_z in plume units.
    zenith_over_f0: [f64; 3],
    /// Twilight fade, 1 with the sun above the horizon.
    fade: f64,
    sun_radiance: Rgb,
}

impl Sky {
    /// Angular diameter of the sun disc, degrees.
    pub const SUN_ANGULAR_DIAMETER: f64 = plume_scene::lights::SUN_ANGULAR_DIAMETER;

    /// A sky for `p`.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] naming `lights.sky.turbidity`, `lights.sky.elevation` or
    /// `lights.sky.azimuth` for a non-finite value, a turbidity outside [1.7, 10] or an
    /// elevation outside [−90, 90].
    pub fn new(p: &SkyParams) -> Result<Sky> {
        p.validate()?;
        let (e, a) = (p.elevation.to_radians(), p.azimuth.to_radians());
        let sun = DVec3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin());
        // The fit's θs: a sun below the horizon is modelled on it (module docs).
        let theta_s = (PI / 2.0 - e).min(PI / 2.0);
        let coefficients = perez_coefficients(p.turbidity);
        let zenith = zenith(p.turbidity, theta_s);
        let zenith_over_f0 = [
            zenith.luminance * 1000.0 / LUMENS_PER_WATT / coefficients.luminance.f(1.0, theta_s),
            zenith.x / coefficients.x.f(1.0, theta_s),
            zenith.y / coefficients.y.f(1.0, theta_s),
        ];
        let fade = (1.0 - p.elevation / TWILIGHT_END_DEGREES).clamp(0.0, 1.0);
        let sun_radiance = if p.elevation < 0.0 {
            Rgb::ZERO
        } else {
            let m = sun::relative_optical_mass(PI / 2.0 - e);
            let xyz = sun::disc_xyz(m, p.turbidity, Self::SUN_ANGULAR_DIAMETER);
            rec709_in_gamut(xyz)
        };
        Ok(Sky { params: *p, sun, coefficients, zenith, zenith_over_f0, fade, sun_radiance })
    }

    /// The parameters this sky was built from.
    #[must_use]
    pub fn params(&self) -> SkyParams {
        self.params
    }

    /// The model's Perez coefficients at this turbidity.
    #[must_use]
    pub fn coefficients(&self) -> SkyCoefficients {
        self.coefficients
    }

    /// The model's zenith values (for a sun below the horizon: those of a sun on it, before
    /// the twilight fade).
    #[must_use]
    pub fn zenith(&self) -> Zenith {
        self.zenith
    }

    /// Unit direction towards the sun in the sky's local frame (+Z = zenith):
    /// `d = (cos e·cos a, cos e·sin a, sin e)`, azimuth a measured from +X towards +Y.
    #[must_use]
    pub fn sun_direction(&self) -> DVec3 {
        self.sun
    }

    /// Solid angle of the sun disc, sr (≈ 6.72e-5).
    #[must_use]
    pub fn sun_solid_angle() -> f64 {
        sun::disc_solid_angle(Self::SUN_ANGULAR_DIAMETER)
    }

    /// Sky radiance (sun disc excluded) towards unit direction `d` (local frame, +Z up),
    /// W m⁻² sr⁻¹ per linear Rec.709 channel (luminance = cd m⁻² / 683). Zero below the
    /// horizon (d.z < 0: black ground).
    #[must_use]
    pub fn radiance(&self, d: DVec3) -> Rgb {
        if d.z < 0.0 || self.fade == 0.0 || !d.is_finite() {
            return Rgb::ZERO;
        }
        let gamma = d.dot(self.sun).clamp(-1.0, 1.0).acos();
        let c = &self.coefficients;
        let [y_scale, x_scale, chroma_y_scale] = self.zenith_over_f0;
        let luminance = y_scale * c.luminance.f(d.z, gamma) * self.fade;
        let x = x_scale * c.x.f(d.z, gamma);
        let y = chroma_y_scale * c.y.f(d.z, gamma);
        rec709_in_gamut([x / y * luminance, luminance, (1.0 - x - y) / y * luminance])
    }

    /// Radiance of the sun disc (uniform over [`Sky::SUN_ANGULAR_DIAMETER`]), in the units
    /// of [`Sky::radiance`], after the atmosphere along the sun's path ([`sun`]). Zero
    /// with the sun below the horizon.
    #[must_use]
    pub fn sun_radiance(&self) -> Rgb {
        self.sun_radiance
    }

    /// The sky as a lat-long environment map ([`latlong_direction`]), `width × height`
    /// pixels, rows from the zenith down, each the radiance at its centre direction. With
    /// `with_sun`, the disc is added to the pixel containing the sun direction as
    /// `sun_radiance × (disc solid angle / pixel solid angle)`, which preserves its energy
    /// (module docs). Empty when either size is 0.
    #[must_use]
    pub fn image(&self, width: u32, height: u32, with_sun: bool) -> Vec<Rgb> {
        let (w, h) = (width as usize, height as usize);
        let mut pixels = vec![Rgb::ZERO; w * h];
        if w == 0 || h == 0 {
            return pixels;
        }
        pixels.par_chunks_mut(w).enumerate().for_each(|(j, row)| {
            let v = (j as f64 + 0.5) / f64::from(height);
            for (i, pixel) in row.iter_mut().enumerate() {
                *pixel = self.radiance(latlong_direction((i as f64 + 0.5) / f64::from(width), v));
            }
        });
        if with_sun && !self.sun_radiance.is_black() {
            let p = self.sun_pixel(width, height);
            let scale = Self::sun_solid_angle() / latlong_pixel_solid_angle(width, height, p.row);
            pixels[p.row as usize * w + p.column as usize] += self.sun_radiance * scale as f32;
        }
        pixels
    }

    /// The pixel of a `width × height` lat-long map that [`Sky::image`] puts the sun in:
    /// the one containing its direction, or the row above for a sun exactly on the horizon.
    #[must_use]
    pub fn sun_pixel(&self, width: u32, height: u32) -> LatLongPixel {
        let p = latlong_pixel(self.sun, width, height);
        let row_top_is_below_horizon = 2 * u64::from(p.row) >= u64::from(height);
        if self.sun.z >= 0.0 && p.row > 0 && row_top_is_below_horizon {
            return LatLongPixel { row: p.row - 1, ..p };
        }
        p
    }
}

/// CIE XYZ → linear Rec.709 ([`xyz_to_rec709`]); a colour outside the gamut is mixed with
/// the grey of its own Rec.709 luminance Y, `c' = Y + s (c − Y)` with the largest `s ≤ 1`
/// that leaves no channel negative, so Y is kept. Black when Y ≤ 0.
#[must_use]
pub fn rec709_in_gamut(xyz: [f64; 3]) -> Rgb {
    let rgb = xyz_to_rec709(xyz);
    let y = 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
    if y.is_nan() || y <= 0.0 {
        return Rgb::ZERO;
    }
    let min = rgb[0].min(rgb[1]).min(rgb[2]);
    let s = if min < 0.0 { y / (y - min) } else { 1.0 };
    Rgb(rgb.map(|c| (y + s * (c - y)).max(0.0) as f32))
}

/// A pixel of a lat-long map: column from the left, row from the top.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LatLongPixel {
    /// Column i, from u = 0.
    pub column: u32,
    /// Row j, from the top (v = 0, +Z).
    pub row: u32,
}

/// plume's lat-long convention (Blender Cycles' equirectangular, +Z up): the unit
/// direction at (u, v) ∈ [0, 1]², `θ = π v` from +Z, `φ = π (1 − 2u)` (= atan2(y, x)),
/// `d = (sin θ cos φ, sin θ sin φ, cos θ)`. So u = ½ is +X, u = ¼ is +Y, v = 0 is +Z.
/// Pixel (i, j) of a W×H map has its centre at ((i+½)/W, (j+½)/H).
#[must_use]
pub fn latlong_direction(u: f64, v: f64) -> DVec3 {
    let (theta, phi) = (PI * v, PI * (1.0 - 2.0 * u));
    let (sin_theta, cos_theta) = theta.sin_cos();
    DVec3::new(sin_theta * phi.cos(), sin_theta * phi.sin(), cos_theta)
}

/// Inverse of [`latlong_direction`]: (u, v) with u in [0, 1) and v in [0, 1], for any
/// non-zero `d` (need not be unit). The poles give u = ½.
#[must_use]
pub fn latlong_uv(d: DVec3) -> (f64, f64) {
    let theta = d.x.hypot(d.y).atan2(d.z);
    let u = 0.5 * (1.0 - d.y.atan2(d.x) / PI);
    (if u >= 1.0 { u - 1.0 } else { u }, theta / PI)
}

/// The pixel of a `width × height` lat-long map (both non-zero) whose area contains `d`.
#[must_use]
pub fn latlong_pixel(d: DVec3, width: u32, height: u32) -> LatLongPixel {
    let (u, v) = latlong_uv(d);
    let index = |t: f64, n: u32| ((t * f64::from(n)) as u32).min(n - 1);
    LatLongPixel { column: index(u, width), row: index(v, height) }
}

/// Solid angle of any pixel in row `row` of a `width × height` lat-long map, sr:
/// `(2π / W)(cos θ_top − cos θ_bottom)`, θ_top = π j / H; the rows sum to 4π.
#[must_use]
pub fn latlong_pixel_solid_angle(width: u32, height: u32, row: u32) -> f64 {
    let h = f64::from(height);
    let (top, bottom) = (PI * f64::from(row) / h, PI * f64::from(row + 1) / h);
    2.0 * PI / f64::from(width) * (top.cos() - bottom.cos())
}

#[cfg(test)]
mod tests;
