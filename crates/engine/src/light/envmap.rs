//! Lat-long (equirectangular) environment maps: lookup and importance sampling.
//!
//! **Convention** (Blender Cycles' equirectangular, +Z up), in the map's *local* frame. A
//! `W × H` map (`W = 2H`) has pixel column `i`, row `j` (row 0 at the top) covering
//! `u ∈ [i/W, (i+1)/W)`, `v ∈ [j/H, (j+1)/H)`, centre `((i+½)/W, (j+½)/H)`, and
//!
//! ```text
//!   θ = π v              polar angle from +Z          v = θ / π = acos(d_z) / π
//!   φ = π (1 − 2u)       azimuth, atan2(d_y, d_x)     u = (1 − φ/π) / 2
//!   d = (sin θ cos φ, sin θ sin φ, cos θ)
//! ```
//!
//! so `u = ½` looks along +X, `u = ¼` along +Y, `u = 0` and `u = 1` (the seam) along −X,
//! `v = 0` (the top row) at +Z and `v = 1` at −Z.
//!
//! **Lookup is piecewise constant**: [`EnvironmentMap::eval`] returns the pixel that
//! contains `d`, like Cycles' "Closest" interpolation. Radiance is then constant over each
//! pixel, so the sampling density below is exactly proportional to each pixel's weight
//! in `(u, v)`; a bilinear lookup would blur light across pixel edges that the density
//! does not follow, and the estimator would carry that mismatch as extra variance.
//!
//! **Change of variables.** With `dω = sin θ dθ dφ`, `dθ = π dv` and `|dφ| = 2π du`,
//!
//! ```text
//!   dω = 2π² sin θ du dv,      p_ω(d) = p_uv(u, v) / (2π² sin θ).
//! ```
//!
//! **Sampling ∝ luminance · sin θ.** The `(u, v)` density is a
//! [`Distribution2D`] over the weights `Y(pixel) · sin θ_j`, with `θ_j = π (j + ½)/H` at the
//! row's centre. A pixel's solid angle is `Ω_ij = (2π/W)(cos θ_j⁻ − cos θ_j⁺)
//! = (4π/W) sin θ_j sin(π/2H)`, exactly proportional to `sin θ_j`: so **a pixel is chosen
//! with probability exactly `Y_ij Ω_ij / Σ Y Ω`**, its share of the map's luminous power,
//! and rows near the poles, which cover little of the sphere, are not oversampled as a
//! plain `(u, v)` density would oversample them. Within a pixel the point is uniform in
//! `(u, v)`, so `p_ω` varies as `sin θ_j / sin θ` across it: not perfectly ∝ `L`, but the
//! estimator `L/p_ω = L · 2π² sin θ / p_uv` stays bounded.
//!
//! **No floor on the weights.** Pixels are validated non-negative and every luminance
//! coefficient is positive, so (computed in `f64`, where no `f32` component underflows)
//! `Y > 0` exactly when the pixel is not black: every pixel that gives light can be
//! sampled, and black pixels, which [`eval`](EnvironmentMap::eval) returns as zero, are
//! never sampled. An all-black map has no distribution: `sample` gives `None` and `pdf` 0.
//!
//! **The poles.** Pixel centres are never at a pole (`sin θ_j ≥ sin(π/2H) > 0`), so the
//! top and bottom rows get their share like any other. The solid-angle density grows as
//! `1/sin θ` towards the pole inside those rows (their `(u, v)` area squeezes into a
//! vanishing solid angle) but stays integrable, and `L/p_ω → 0` there. Exactly at a pole
//! (`sin θ = 0`), `p_ω` is reported as 0, and `sample` returns `None` for the
//! measure-zero draw that lands there.
//!
//! **Consistency.** `sample` computes its radiance and pdf from the direction it returns,
//! through the same lookup as [`eval`](EnvironmentMap::eval) and
//! [`pdf`](EnvironmentMap::pdf), so for every sample `s`, `pdf(s.direction) == s.pdf`
//! and `eval(s.direction) == s.radiance` bit for bit (MIS depends on it). `sin θ` is
//! always `√(d_x² + d_y²)` of the direction, never `sin(π v)`.

use std::f64::consts::PI;
use std::io::BufReader;
use std::path::Path;

use glam::DVec3;

use plume_core::color::{rec709_luminance, Rgb};
use plume_core::error::{Error, Result};
use plume_core::sampling::distribution2d::{bin_of, Distribution2D};

/// `dω = 2π² sin θ du dv`.
const TWO_PI_SQUARED: f64 = 2.0 * PI * PI;

/// A direction drawn from an [`EnvironmentMap`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnvSample {
    /// Direction towards the environment, in the map's local frame, unit length.
    pub direction: DVec3,
    /// Radiance arriving from `direction`; equal to [`EnvironmentMap::eval`]`(direction)`.
    pub radiance: Rgb,
    /// Density with respect to solid angle; bit-identical to
    /// [`EnvironmentMap::pdf`]`(direction)` and always positive.
    pub pdf: f64,
}

/// A lat-long environment map with its sampling distribution (see the module docs).
#[derive(Clone, Debug)]
pub struct EnvironmentMap {
    width: u32,
    height: u32,
    /// Row-major, row 0 at the top (`v = 0`, +Z).
    pixels: Vec<Rgb>,
    /// Over `Y · sin θ_j`; `None` for an all-black map.
    distribution: Option<Distribution2D>,
    /// `∫ Y(L(ω)) dω`.
    luminance_integral: f64,
}

/// The unit direction of lat-long coordinates `(u, v)` (module docs).
fn direction(u: f64, v: f64) -> DVec3 {
    let (sin_theta, cos_theta) = (PI * v).sin_cos();
    let (sin_phi, cos_phi) = (PI * (1.0 - 2.0 * u)).sin_cos();
    DVec3::new(sin_theta * cos_phi, sin_theta * sin_phi, cos_theta)
}

/// The lat-long coordinates `(u, v) ∈ [0, 1]²` of a unit direction (module docs).
fn uv(d: DVec3) -> [f64; 2] {
    let phi = d.y.atan2(d.x);
    let theta = d.z.clamp(-1.0, 1.0).acos();
    [0.5 * (1.0 - phi / PI), theta / PI]
}

/// `sin θ` of a unit direction, accurate near the poles (where `acos` is not).
fn sin_theta(d: DVec3) -> f64 {
    (d.x * d.x + d.y * d.y).sqrt()
}

/// Luminance in `f64` ([`rec709_luminance`]); positive for any non-negative, non-black
/// pixel.
fn luminance(p: Rgb) -> f64 {
    rec709_luminance(p.to_f64())
}

impl EnvironmentMap {
    /// Load a lat-long map from the first layer of an EXR: its `R`, `G` and `B` channels
    /// (`A` and any others ignored), any pixel type, the largest mip level, the data
    /// window's pixels with row 0 at the top.
    ///
    /// # Errors
    /// [`Error::Open`] when the file cannot be opened; [`Error::InvalidInput`] naming the
    /// file when it is not a readable EXR, lacks `R`, `G` or `B` (or sub-samples them),
    /// is not lat-long (`width ≠ 2 · height`), or has a negative, NaN or infinite pixel
    /// (named by column and row from the top).
    pub fn load(path: &Path) -> Result<EnvironmentMap> {
        use exr::prelude::*;
        // the prelude's glob brings exr's own `Error`; this one wins over it
        use plume_core::error::Error;
        let file = std::fs::File::open(path)
            .map_err(|source| Error::Open { path: path.to_path_buf(), source })?;
        let what = format!("environment map {}", path.display());
        let bad = |message: String| Error::InvalidInput { what: what.clone(), message };
        let image = read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .first_valid_layer()
            .all_attributes()
            .non_parallel()
            .from_buffered(BufReader::new(file))
            .map_err(|e| bad(format!("not a readable EXR: {e}")))?;
        let layer = &image.layer_data;
        let (width, height) = (layer.size.0, layer.size.1);
        let count = width * height;
        let mut rgb = Vec::with_capacity(3);
        for name in ["R", "G", "B"] {
            let Some(channel) = layer.channel_data.list.iter().find(|c| c.name.to_string() == name)
            else {
                let names: Vec<String> =
                    layer.channel_data.list.iter().map(|c| c.name.to_string()).collect();
                return Err(bad(format!(
                    "no {name} channel (needs R, G and B; has {})",
                    names.join(", ")
                )));
            };
            if channel.sample_data.len() != count {
                return Err(bad(format!(
                    "channel {name} is sub-sampled ({} samples for {width}x{height} pixels)",
                    channel.sample_data.len()
                )));
            }
            rgb.push(channel.sample_data.values_as_f32().collect::<Vec<f32>>());
        }
        let pixels = (0..count).map(|k| Rgb([rgb[0][k], rgb[1][k], rgb[2][k]])).collect();
        let (Ok(width), Ok(height)) = (u32::try_from(width), u32::try_from(height)) else {
            return Err(bad(format!("{width}x{height} pixels is too large")));
        };
        EnvironmentMap::from_pixels(width, height, pixels, &what)
    }

    /// A lat-long map from pixels in memory: `width × height` of them, row-major, row 0 at
    /// the top. `what` names the source in errors (e.g. `environment map sky.exr`).
    ///
    /// # Errors
    /// [`Error::InvalidInput`] when the map is empty or not lat-long (`width ≠ 2 · height`),
    /// when `pixels` has the wrong length, or when a pixel has a negative, NaN or infinite
    /// component (the first such pixel, by column and row from the top).
    pub fn from_pixels(
        width: u32,
        height: u32,
        pixels: Vec<Rgb>,
        what: &str,
    ) -> Result<EnvironmentMap> {
        let bad = |message: String| Error::InvalidInput { what: what.to_string(), message };
        if height == 0 || u64::from(width) != 2 * u64::from(height) {
            return Err(bad(format!("{width}x{height} pixels is not a lat-long map (the width must be twice the height)")));
        }
        let (w, h) = (width as usize, height as usize);
        if pixels.len() != w * h {
            return Err(bad(format!("{} pixels for a {width}x{height} map", pixels.len())));
        }
        if let Some(k) = pixels.iter().position(|p| !p.0.iter().all(|c| c.is_finite() && *c >= 0.0))
        {
            let [r, g, b] = pixels[k].0;
            let why = if pixels[k].is_finite() { "negative" } else { "NaN or infinite" };
            return Err(bad(format!(
                "pixel ({}, {}) (column, row from the top) is {why}: R G B = {r} {g} {b}",
                k % w,
                k / w
            )));
        }
        let mut weights = Vec::with_capacity(w * h);
        let mut luminance_integral = 0.0;
        // Ω_ij = (4π/W) sin θ_j sin(π/2H): the pixel's exact solid angle
        let pixel_solid_angle = 4.0 * PI / w as f64 * (PI / (2.0 * h as f64)).sin();
        for (j, row) in pixels.chunks_exact(w).enumerate() {
            let sin_theta_j = (PI * (j as f64 + 0.5) / h as f64).sin();
            let mut row_luminance = 0.0;
            for &p in row {
                let y = luminance(p);
                row_luminance += y;
                weights.push(y * sin_theta_j);
            }
            luminance_integral += row_luminance * sin_theta_j * pixel_solid_angle;
        }
        // None only for an all-black map: the weights are validated finite and non-negative
        let distribution = Distribution2D::new(&weights, w, h);
        Ok(EnvironmentMap { width, height, pixels, distribution, luminance_integral })
    }

    /// Width in pixels (`2 · height`).
    #[must_use]
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    #[must_use]
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The pixel `[column, row]` containing unit local direction `d`.
    fn pixel(&self, d: DVec3) -> [usize; 2] {
        let [u, v] = uv(d);
        [bin_of(u, self.width as usize), bin_of(v, self.height as usize)]
    }

    /// Radiance arriving from unit local direction `d`: the pixel containing it (no
    /// interpolation; module docs).
    #[must_use]
    pub fn eval(&self, d: DVec3) -> Rgb {
        let [i, j] = self.pixel(d);
        self.pixels[j * self.width as usize + i]
    }

    /// Density with respect to solid angle of [`sample`](Self::sample) giving unit local
    /// direction `d`: `p_uv / (2π² sin θ)`; 0 for black pixels, at the poles, and for an
    /// all-black map.
    #[must_use]
    pub fn pdf(&self, d: DVec3) -> f64 {
        debug_assert!((d.length_squared() - 1.0).abs() < 1e-6, "direction {d} is not unit");
        let Some(distribution) = &self.distribution else { return 0.0 };
        let sin_theta = sin_theta(d);
        if sin_theta == 0.0 {
            return 0.0;
        }
        distribution.cell_pdf(self.pixel(d)) / (TWO_PI_SQUARED * sin_theta)
    }

    /// Draw a direction ∝ `Y(pixel) · sin θ` from a uniform `u ∈ [0, 1)²` (`u[1]` picks the
    /// row, `u[0]` the column; module docs).
    ///
    /// Returns `None` for an all-black map, and for the measure-zero draws that land
    /// exactly on a pole or, by rounding, in a black pixel.
    #[must_use]
    pub fn sample(&self, u: [f64; 2]) -> Option<EnvSample> {
        let s = self.distribution.as_ref()?.sample(u);
        let direction = direction(s.uv[0], s.uv[1]);
        let pdf = self.pdf(direction);
        (pdf > 0.0).then(|| EnvSample { direction, radiance: self.eval(direction), pdf })
    }

    /// `∫ Y(L(ω)) dω` over the sphere, exact for the piecewise-constant lookup:
    /// `Σ Y_ij Ω_ij` (for choosing between lights by power).
    #[must_use]
    pub fn luminance_integral(&self) -> f64 {
        self.luminance_integral
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: DVec3, b: DVec3) -> bool {
        (a - b).length() < 1e-12
    }

    #[test]
    fn convention_axes() {
        assert!(close(direction(0.5, 0.5), DVec3::X));
        assert!(close(direction(0.25, 0.5), DVec3::Y));
        assert!(close(direction(0.75, 0.5), -DVec3::Y));
        assert!(close(direction(0.0, 0.5), -DVec3::X));
        assert!(close(direction(0.3, 0.0), DVec3::Z));
        assert!(close(direction(0.3, 1.0), -DVec3::Z));
        assert_eq!(uv(DVec3::X), [0.5, 0.5]);
        assert_eq!(uv(DVec3::Y), [0.25, 0.5]);
        assert_eq!(uv(DVec3::Z)[1], 0.0);
        assert_eq!(uv(-DVec3::Z)[1], 1.0);
    }

    #[test]
    fn direction_and_uv_are_inverse() {
        let mut s = plume_core::sampling::Sampler::new(9, 0, 0);
        for _ in 0..1000 {
            let (u, v) = (s.next_f64(), s.next_f64());
            let d = direction(u, v);
            assert!((d.length() - 1.0).abs() < 1e-15);
            let [u2, v2] = uv(d);
            assert!((u2 - u).abs() < 1e-12 && (v2 - v).abs() < 1e-7, "({u}, {v}) -> ({u2}, {v2})");
            assert!((sin_theta(d) - (PI * v).sin()).abs() < 1e-15);
        }
    }

    #[test]
    fn validation_names_the_source_and_pixel() {
        let err = |w, h, pixels: Vec<Rgb>| {
            EnvironmentMap::from_pixels(w, h, pixels, "map m").unwrap_err().to_string()
        };
        assert!(err(3, 3, vec![Rgb::ONE; 9]).starts_with("map m: 3x3 pixels is not a lat-long map"));
        assert!(err(0, 0, vec![]).contains("not a lat-long map"));
        assert!(err(4, 2, vec![Rgb::ONE; 7]).contains("7 pixels for a 4x2 map"));
        let mut pixels = vec![Rgb::ONE; 8];
        pixels[6] = Rgb([1.0, -0.5, 0.0]);
        assert_eq!(
            err(4, 2, pixels.clone()),
            "map m: pixel (2, 1) (column, row from the top) is negative: R G B = 1 -0.5 0"
        );
        pixels[5] = Rgb([f32::INFINITY, 0.0, 0.0]);
        assert!(err(4, 2, pixels)
            .contains("pixel (1, 1) (column, row from the top) is NaN or infinite"));
        let e = EnvironmentMap::from_pixels(2, 2, vec![Rgb::ONE; 4], "m").unwrap_err();
        assert_eq!(e.exit_code(), plume_core::error::exit::INPUT);
    }

    #[test]
    fn black_map_has_no_samples() {
        let map = EnvironmentMap::from_pixels(4, 2, vec![Rgb::ZERO; 8], "black").unwrap();
        assert!(map.sample([0.3, 0.6]).is_none());
        assert_eq!(map.pdf(DVec3::X), 0.0);
        assert_eq!(map.luminance_integral(), 0.0);
        assert_eq!(map.eval(DVec3::Y), Rgb::ZERO);
    }

    #[test]
    fn luminance_integral_of_a_constant_map_is_four_pi_y() {
        let l = Rgb([0.5, 1.0, 2.0]);
        let map = EnvironmentMap::from_pixels(64, 32, vec![l; 64 * 32], "grey").unwrap();
        let expected = 4.0 * PI * luminance(l);
        assert!(
            (map.luminance_integral() / expected - 1.0).abs() < 1e-13,
            "{} vs {expected}",
            map.luminance_integral()
        );
    }

    #[test]
    fn pole_pdf_is_zero() {
        let map = EnvironmentMap::from_pixels(4, 2, vec![Rgb::ONE; 8], "white").unwrap();
        assert_eq!(map.pdf(DVec3::Z), 0.0);
        assert_eq!(map.pdf(-DVec3::Z), 0.0);
        assert!(map.pdf(DVec3::new(1e-9, 0.0, 1.0).normalize()) > 0.0);
        // u[1] = 0 samples v = 0 exactly: the pole
        assert!(map.sample([0.4, 0.0]).is_none());
    }
}
