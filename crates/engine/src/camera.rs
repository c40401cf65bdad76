//! The camera: pixel coordinates → world rays; optionally moving within the shutter (a
//! path of placements, linear between knots; motion blur).
//!
//! Image x grows to the right and y downwards; pixel `(x, y)` covers `[x, x+1) × [y, y+1)`
//! (one-pixel box filter). The field of view is horizontal.
//!
//! **Lenses** ([`Lens`]). A pinhole sends every ray from the position. A thin lens of
//! aperture radius `r` focused at distance `d` (along the view direction) sends the ray
//! of image point `s` from a point `o + r (u_x right + u_y up)` of the lens, `u` uniform on
//! the unit disk (Shirley and Chiu's concentric map of a 2-D sample), towards the point
//! where the pinhole ray of `s` meets the plane in focus, `o + d ω_s / (ω_s · forward)`:
//! points on that plane are sharp, others blur into a disk that grows with `r` and their
//! distance from it (pbrt-v4's `PerspectiveCamera`; Cycles' `aperture_size` is `r`). An
//! orthographic camera sends parallel rays along the view direction from the image plane
//! through the position, `2 half_width` world units across.

use glam::DVec3;

use plume_core::error::{Error, Result};
use plume_volume::field::Ray;

/// How rays leave the camera (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Lens {
    /// Every ray from the position.
    Pinhole,
    /// A thin lens.
    Thin {
        /// Aperture radius, world units (> 0).
        radius: f64,
        /// Distance of the plane in focus along the view direction, world units.
        focus_distance: f64,
    },
    /// Parallel rays along the view direction.
    Orthographic {
        /// Half the image's width, world units.
        half_width: f64,
        /// Half the image's height, world units.
        half_height: f64,
    },
}

/// A camera.
#[derive(Clone, Copy, Debug)]
pub struct Camera {
    /// Eye position, world.
    pub origin: DVec3,
    forward: DVec3,
    right: DVec3,
    up: DVec3,
    tan_half_x: f64,
    tan_half_y: f64,
    /// How rays leave it.
    pub lens: Lens,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// A camera that moves within the shutter (`camera.keys`); `None`: still.
    pub motion: Option<CameraMotion>,
}

/// A camera's placement: position, point looked at, up hint, horizontal field of view
/// (degrees).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LookAt {
    /// Position.
    pub from: DVec3,
    /// Point looked at.
    pub at: DVec3,
    /// Up hint.
    pub up: DVec3,
    /// Horizontal field of view, degrees.
    pub fov: f64,
}

impl LookAt {
    /// The placement a fraction `f` of the way from `self` to `o` (each part linearly).
    #[must_use]
    pub fn lerp(&self, o: &LookAt, f: f64) -> LookAt {
        LookAt {
            from: self.from.lerp(o.from, f),
            at: self.at.lerp(o.at, f),
            up: self.up.lerp(o.up, f),
            fov: self.fov + f * (o.fov - self.fov),
        }
    }
}

/// Most knots of a camera path within one shutter.
pub const MAX_CAMERA_KNOTS: usize = 8;

/// A camera path over the shutter: placements at increasing times (seconds relative to
/// the frame), linear between them; the first knot is the shutter's opening, the last its
/// closing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraMotion {
    knots: [(f64, LookAt); MAX_CAMERA_KNOTS],
    len: usize,
}

impl CameraMotion {
    /// A path through `knots` (2 to [`MAX_CAMERA_KNOTS`], times increasing).
    ///
    /// # Errors
    /// Too few or too many knots, times not increasing, or a placement that is not a
    /// camera (as [`Camera::look_at`]).
    pub fn new(knots: &[(f64, LookAt)], width: u32, height: u32) -> Result<CameraMotion> {
        if knots.len() < 2 || knots.len() > MAX_CAMERA_KNOTS {
            return Err(Error::invalid(
                "camera.keys",
                format!(
                    "{} camera keys within one shutter; at most {}",
                    knots.len(),
                    MAX_CAMERA_KNOTS - 2
                ),
            ));
        }
        for w in knots.windows(2) {
            if w[0].0 >= w[1].0 || w[0].0.is_nan() || w[1].0.is_nan() {
                return Err(Error::invalid("camera.keys", "keys must be at increasing frames"));
            }
        }
        for (_, k) in knots {
            Camera::look_at(k.from, k.at, k.up, k.fov, width, height)?;
        }
        let mut all = [knots[0]; MAX_CAMERA_KNOTS];
        all[..knots.len()].copy_from_slice(knots);
        Ok(CameraMotion { knots: all, len: knots.len() })
    }

    /// The shutter: first and last knot times (seconds).
    #[must_use]
    pub fn shutter(&self) -> [f64; 2] {
        [self.knots[0].0, self.knots[self.len - 1].0]
    }

    /// The placement at time `t` (clamped to the shutter).
    #[must_use]
    pub fn at(&self, t: f64) -> LookAt {
        let k = &self.knots[..self.len];
        let i = k.iter().rposition(|(kt, _)| *kt <= t).unwrap_or(0).min(self.len - 2);
        let (t0, a) = k[i];
        let (t1, b) = k[i + 1];
        a.lerp(&b, ((t - t0) / (t1 - t0)).clamp(0.0, 1.0))
    }
}

impl Camera {
    /// A camera at `from` looking at `at`, with `up` hint and horizontal field of view
    /// `fov_degrees`.
    ///
    /// # Errors
    /// Coincident `from`/`at`, `up` parallel to the view direction, a field of view
    /// outside (0, 180) degrees, or a zero image size.
    pub fn look_at(
        from: DVec3,
        at: DVec3,
        up: DVec3,
        fov_degrees: f64,
        width: u32,
        height: u32,
    ) -> Result<Camera> {
        if !(from.is_finite() && at.is_finite() && up.is_finite()) {
            return Err(Error::invalid(
                "camera.from/camera.at/camera.up",
                "components must be finite",
            ));
        }
        let forward = (at - from)
            .try_normalize()
            .ok_or_else(|| Error::invalid("camera.at", "must differ from camera.from"))?;
        let right = forward.cross(up).try_normalize().ok_or_else(|| {
            Error::invalid("camera.up", "must not be zero or parallel to the view direction")
        })?;
        if !(fov_degrees > 0.0 && fov_degrees < 180.0) {
            return Err(Error::invalid(
                "camera.fov",
                format!("{fov_degrees} is not in (0, 180) degrees"),
            ));
        }
        if width == 0 || height == 0 {
            return Err(Error::invalid(
                "camera.width/camera.height",
                "image size must be at least 1x1",
            ));
        }
        let tan_half_x = (fov_degrees.to_radians() * 0.5).tan();
        let tan_half_y = tan_half_x * f64::from(height) / f64::from(width);
        Ok(Camera {
            origin: from,
            forward,
            right,
            up: right.cross(forward),
            tan_half_x,
            tan_half_y,
            lens: Lens::Pinhole,
            width,
            height,
            motion: None,
        })
    }

    /// The same placement through a thin lens of aperture `radius` focused at
    /// `focus_distance` (world units); a pinhole for radius 0.
    ///
    /// # Errors
    /// A negative or non-finite radius, a focus distance that is not positive and finite.
    pub fn with_thin_lens(self, radius: f64, focus_distance: f64) -> Result<Camera> {
        if !(radius.is_finite() && radius >= 0.0) {
            return Err(Error::invalid(
                "camera.aperture_radius",
                format!("{radius} must be 0 or more"),
            ));
        }
        if !(focus_distance.is_finite() && focus_distance > 0.0) {
            return Err(Error::invalid(
                "camera.focus_distance",
                format!("{focus_distance} must be positive and finite"),
            ));
        }
        let lens = if radius > 0.0 { Lens::Thin { radius, focus_distance } } else { Lens::Pinhole };
        Ok(Camera { lens, ..self })
    }

    /// The same placement as an orthographic camera `width` world units across.
    ///
    /// # Errors
    /// A width that is not positive and finite.
    pub fn orthographic(self, width: f64) -> Result<Camera> {
        if !(width.is_finite() && width > 0.0) {
            return Err(Error::invalid(
                "camera.ortho_width",
                format!("{width} must be positive and finite"),
            ));
        }
        let half_width = 0.5 * width;
        let half_height = half_width * f64::from(self.height) / f64::from(self.width);
        Ok(Camera { lens: Lens::Orthographic { half_width, half_height }, ..self })
    }

    /// The view direction (unit).
    #[must_use]
    pub fn forward(&self) -> DVec3 {
        self.forward
    }

    /// Whether a ray needs a lens sample ([`Camera::ray_through_lens`]).
    #[must_use]
    pub fn needs_lens_sample(&self) -> bool {
        matches!(self.lens, Lens::Thin { .. })
    }

    /// Frame a world box: look at its centre from direction `view_dir` (towards the
    /// camera), far enough that the bounding sphere fits both fields of view.
    ///
    /// # Errors
    /// As [`Camera::look_at`].
    pub fn frame_bounds(
        lo: DVec3,
        hi: DVec3,
        view_dir: DVec3,
        up: DVec3,
        fov_degrees: f64,
        width: u32,
        height: u32,
    ) -> Result<Camera> {
        let centre = 0.5 * (lo + hi);
        let radius = (0.5 * (hi - lo).length()).max(1e-12);
        let half_x = (fov_degrees.to_radians() * 0.5).min(1.5);
        let half_y = (half_x.tan() * f64::from(height) / f64::from(width.max(1))).atan();
        let half = half_x.min(half_y).max(1e-6);
        let distance = radius / half.sin() * 1.02;
        Camera::look_at(
            centre + view_dir.normalize() * distance,
            centre,
            up,
            fov_degrees,
            width,
            height,
        )
    }

    /// The camera at time `t` (seconds relative to the frame): itself when still.
    #[must_use]
    pub fn at_time(&self, t: f64) -> Camera {
        let Some(m) = &self.motion else { return *self };
        let k = m.at(t);
        // Every knot is a camera (checked); a point between two can coincide only where
        // `from` passes through `at`: keep the frame's camera there
        Camera::look_at(k.from, k.at, k.up, k.fov, self.width, self.height)
            .map_or(*self, |c| Camera { motion: self.motion, lens: self.lens, ..c })
    }

    /// The ray through image position `(x, y)` in pixels (continuous), from the lens's
    /// centre.
    #[inline]
    #[must_use]
    pub fn ray(&self, x: f64, y: f64) -> Ray {
        let (ix, iy) =
            (2.0 * x / f64::from(self.width) - 1.0, 1.0 - 2.0 * y / f64::from(self.height));
        if let Lens::Orthographic { half_width, half_height } = self.lens {
            let origin =
                self.origin + self.right * (ix * half_width) + self.up * (iy * half_height);
            return Ray { origin, direction: self.forward };
        }
        let (sx, sy) = (ix * self.tan_half_x, iy * self.tan_half_y);
        let d = (self.forward + self.right * sx + self.up * sy).normalize();
        Ray { origin: self.origin, direction: d }
    }

    /// The ray through image position `(x, y)` from the lens point of the uniform 2-D
    /// sample `u` ([`Camera::ray`] for a pinhole or an orthographic camera).
    #[inline]
    #[must_use]
    pub fn ray_through_lens(&self, x: f64, y: f64, u: [f64; 2]) -> Ray {
        let centre = self.ray(x, y);
        let Lens::Thin { radius, focus_distance } = self.lens else { return centre };
        let focus = centre.origin
            + centre.direction * (focus_distance / centre.direction.dot(self.forward));
        let [dx, dy] = concentric_disk(u);
        let origin = self.origin + (self.right * dx + self.up * dy) * radius;
        Ray { origin, direction: (focus - origin).normalize() }
    }
}

/// Shirley and Chiu's concentric map of the unit square onto the unit disk: uniform, and
/// strata stay compact.
#[inline]
fn concentric_disk(u: [f64; 2]) -> [f64; 2] {
    let (a, b) = (2.0 * u[0] - 1.0, 2.0 * u[1] - 1.0);
    if a == 0.0 && b == 0.0 {
        return [0.0, 0.0];
    }
    let (r, theta) = if a.abs() > b.abs() {
        (a, std::f64::consts::FRAC_PI_4 * (b / a))
    } else {
        (b, std::f64::consts::FRAC_PI_2 - std::f64::consts::FRAC_PI_4 * (a / b))
    };
    [r * theta.cos(), r * theta.sin()]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        Camera::look_at(
            DVec3::new(0.3, -4.0, 1.0),
            DVec3::new(0.1, 0.2, 0.4),
            DVec3::Z,
            35.0,
            64,
            48,
        )
        .unwrap()
    }

    /// Low-discrepancy points of the unit square (a 2-D Halton sequence).
    fn square(n: u32) -> impl Iterator<Item = [f64; 2]> {
        let radical = |mut i: u32, b: u32| {
            let (mut f, mut r) = (1.0, 0.0);
            while i > 0 {
                f /= f64::from(b);
                r += f * f64::from(i % b);
                i /= b;
            }
            r
        };
        (1..=n).map(move |i| [radical(i, 2), radical(i, 3)])
    }

    #[test]
    fn thin_lens_rays_meet_on_the_plane_in_focus() {
        let pinhole = camera();
        let lens = pinhole.with_thin_lens(0.25, 3.0).unwrap();
        for (x, y) in [(0.5, 0.5), (31.2, 20.7), (63.9, 47.1)] {
            let centre = pinhole.ray(x, y);
            assert_eq!(lens.ray(x, y), centre, "the lens's centre ray is the pinhole's");
            // Where the pinhole ray crosses the plane 3 units ahead
            let t = 3.0 / centre.direction.dot(pinhole.forward());
            let focus = centre.origin + centre.direction * t;
            let (mut sum, mut sum_r2) = (DVec3::ZERO, 0.0);
            let n = 4096;
            for u in square(n) {
                let r = lens.ray_through_lens(x, y, u);
                let offset = r.origin - pinhole.origin;
                assert!(offset.dot(pinhole.forward()).abs() < 1e-12, "lens points lie on the lens");
                assert!(offset.length() <= 0.25 + 1e-12);
                // The ray passes through the focus point
                let s = (focus - r.origin).dot(r.direction);
                assert!((r.origin + r.direction * s - focus).length() < 1e-9);
                sum += offset;
                sum_r2 += offset.length_squared();
            }
            // Uniform on the disk: centred, E[ρ²] = R²/2
            assert!((sum / f64::from(n)).length() < 1e-3);
            assert!((sum_r2 / f64::from(n) - 0.25 * 0.25 / 2.0).abs() < 1e-3);
        }
    }

    #[test]
    fn a_zero_aperture_is_a_pinhole_and_bad_lenses_are_refused() {
        let c = camera().with_thin_lens(0.0, 2.0).unwrap();
        assert_eq!(c.lens, Lens::Pinhole);
        assert!(!c.needs_lens_sample());
        assert!(camera().with_thin_lens(-1.0, 2.0).is_err());
        assert!(camera().with_thin_lens(0.1, 0.0).is_err());
        assert!(camera().orthographic(0.0).is_err());
    }

    #[test]
    fn orthographic_rays_are_parallel_and_span_the_width() {
        let c = camera().orthographic(2.0).unwrap();
        let (left, right) = (c.ray(0.0, 24.0), c.ray(64.0, 24.0));
        assert_eq!(left.direction, c.forward());
        assert_eq!(right.direction, c.forward());
        assert!(((right.origin - left.origin).length() - 2.0).abs() < 1e-12);
        let (top, bottom) = (c.ray(32.0, 0.0), c.ray(32.0, 48.0));
        assert!(((top.origin - bottom.origin).length() - 1.5).abs() < 1e-12, "48/64 of the width");
        assert!((c.ray(32.0, 24.0).origin - c.origin).length() < 1e-12);
        assert_eq!(c.ray_through_lens(10.0, 10.0, [0.3, 0.9]), c.ray(10.0, 10.0));
    }

    #[test]
    fn the_concentric_map_covers_the_disk_uniformly() {
        // Equal-area rings and sectors of the disk get equal shares of a stratified square
        let n = 1 << 14;
        let mut bins = [0u32; 16];
        for u in square(n) {
            let [x, y] = concentric_disk(u);
            let r2 = x * x + y * y;
            assert!(r2 <= 1.0 + 1e-12);
            let ring = ((r2 * 4.0) as usize).min(3);
            let sector = (((y.atan2(x) + std::f64::consts::PI) / std::f64::consts::FRAC_PI_2)
                as usize)
                .min(3);
            bins[ring * 4 + sector] += 1;
        }
        let expected = f64::from(n) / 16.0;
        for b in bins {
            assert!((f64::from(b) - expected).abs() < 0.02 * expected, "{bins:?}");
        }
    }
}
