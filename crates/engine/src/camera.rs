//! Pinhole camera: pixel coordinates → world rays; optionally moving within the shutter
//! (a path of placements, linear between knots; motion blur).
//!
//! Image x grows to the right and y downwards; pixel `(x, y)` covers `[x, x+1) × [y, y+1)`
//! (one-pixel box filter). The field of view is horizontal.

use glam::DVec3;

use plume_core::error::{Error, Result};
use plume_volume::field::Ray;

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
            width,
            height,
            motion: None,
        })
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
            .map_or(*self, |c| Camera { motion: self.motion, ..c })
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
