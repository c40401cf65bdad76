//! Pinhole camera: pixel coordinates → world rays.
//!
//! Image x grows to the right and y downwards; pixel `(x, y)` covers `[x, x+1) × [y, y+1)`
//! (one-pixel box filter). The field of view is horizontal.

use glam::DVec3;

use crate::error::{Error, Result};
use crate::volume::field::Ray;

/// A pinhole camera.
#[derive(Clone, Copy, Debug)]
pub struct Camera {
    /// Eye position, world.
    pub origin: DVec3,
    forward: DVec3,
    right: DVec3,
    up: DVec3,
    tan_half_x: f64,
    tan_half_y: f64,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

impl Camera {
    /// A camera at `from` looking at `at`, with `up` hint and horizontal field of view
    /// `fov_degrees`.
    ///
    /// # Errors
    /// Coincident `from`/`at`, `up` parallel to the view direction, a field of view
    /// outside (0, 180) degrees, or a zero image size.
    pub fn look_at(from: DVec3, at: DVec3, up: DVec3, fov_degrees: f64, width: u32, height: u32) -> Result<Camera> {
        if !(from.is_finite() && at.is_finite() && up.is_finite()) {
            return Err(Error::invalid("camera.from/camera.at/camera.up", "components must be finite"));
        }
        let forward = (at - from).try_normalize().ok_or_else(|| Error::invalid("camera.at", "must differ from camera.from"))?;
        let right = forward.cross(up).try_normalize().ok_or_else(|| Error::invalid("camera.up", "must not be zero or parallel to the view direction"))?;
        if !(fov_degrees > 0.0 && fov_degrees < 180.0) {
            return Err(Error::invalid("camera.fov", format!("{fov_degrees} is not in (0, 180) degrees")));
        }
        if width == 0 || height == 0 {
            return Err(Error::invalid("camera.width/camera.height", "image size must be at least 1x1"));
        }
        let tan_half_x = (fov_degrees.to_radians() * 0.5).tan();
        let tan_half_y = tan_half_x * f64::from(height) / f64::from(width);
        Ok(Camera { origin: from, forward, right, up: right.cross(forward), tan_half_x, tan_half_y, width, height })
    }

    /// Frame a world box: look at its centre from direction `view_dir` (towards the
    /// camera), far enough that the bounding sphere fits both fields of view.
    ///
    /// # Errors
    /// As [`Camera::look_at`].
    pub fn frame_bounds(lo: DVec3, hi: DVec3, view_dir: DVec3, up: DVec3, fov_degrees: f64, width: u32, height: u32) -> Result<Camera> {
        let centre = 0.5 * (lo + hi);
        let radius = (0.5 * (hi - lo).length()).max(1e-12);
        let half_x = (fov_degrees.to_radians() * 0.5).min(1.5);
        let half_y = (half_x.tan() * f64::from(height) / f64::from(width.max(1))).atan();
        let half = half_x.min(half_y).max(1e-6);
        let distance = radius / half.sin() * 1.02;
        Camera::look_at(centre + view_dir.normalize() * distance, centre, up, fov_degrees, width, height)
    }

    /// The ray through image position `(x, y)` in pixels (continuous).
    #[inline]
    #[must_use]
    pub fn ray(&self, x: f64, y: f64) -> Ray {
        let sx = (2.0 * x / f64::from(self.width) - 1.0) * self.tan_half_x;
        let sy = (1.0 - 2.0 * y / f64::from(self.height)) * self.tan_half_y;
        let d = (self.forward + self.right * sx + self.up * sy).normalize();
        Ray { origin: self.origin, direction: d }
    }
}
