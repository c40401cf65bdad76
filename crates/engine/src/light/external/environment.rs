//! Environment lights: radiance arriving from infinitely far away in every direction,
//! either constant (`lights.environment`) or from a lat-long map (an EXR, or the built-in
//! sky tabulated as one).
//!
//! A map lives in its own frame, +Z its zenith (Cycles' convention, `light::envmap`). The
//! scene's up axis (`camera.up_axis`) is the zenith, and `rotation` turns the map about
//! it counter-clockwise seen from above: world `ω` is looked up at
//! `R_up(−rotation) · M · ω`, `M` the change from the world's axes to the map's (identity
//! for +Z up; `(x, y, z) ↦ (x, −z, y)` for +Y up, as Blender imports a Y-up scene).
//!
//! **Sampling.** A constant environment: uniform on the sphere, `p = 1/4π`. A map: the
//! map's own importance sampling ∝ luminance · sin θ (`light::envmap`), rotated.

use glam::{DMat3, DVec3};

use super::sample::LightSample;
use crate::light::envmap::EnvironmentMap;
use plume_core::color::Rgb;

/// The rotation from world directions to a map's frame (+Z its zenith): the axis change
/// taking unit `up` to +Z, then a turn by `rotation` radians about it (module docs).
#[must_use]
pub fn world_to_map(up: DVec3, rotation: f64) -> DMat3 {
    let axes = if (up - DVec3::Z).length_squared() < 1e-24 {
        DMat3::IDENTITY
    } else if (up - DVec3::Y).length_squared() < 1e-24 {
        // (x, y, z) ↦ (x, −z, y), as Blender imports a Y-up scene
        DMat3::from_cols(DVec3::X, DVec3::Z, -DVec3::Y)
    } else {
        // Any other up: the rotation taking `up` to +Z about their common normal
        let axis = up.cross(DVec3::Z);
        let s = axis.length();
        if s < 1e-12 {
            DMat3::from_diagonal(DVec3::new(1.0, -1.0, -1.0)) // up = −Z
        } else {
            DMat3::from_axis_angle(axis / s, s.atan2(up.dot(DVec3::Z)))
        }
    };
    DMat3::from_rotation_z(-rotation) * axes
}

/// Where the radiance comes from.
#[derive(Debug)]
pub enum Radiance {
    /// The same radiance from every direction.
    Constant(Rgb),
    /// A lat-long map.
    Map(Box<EnvironmentMap>),
}

/// An environment light.
#[derive(Debug)]
pub struct Environment {
    radiance: Radiance,
    /// Multiplies the radiance (Cycles' Background *Strength*).
    intensity: f64,
    /// World → map frame.
    to_local: DMat3,
    /// Map frame → world (the transpose).
    to_world: DMat3,
    /// Whether camera rays see it (scattered light always does).
    visible: bool,
}

impl Environment {
    /// An environment of `radiance` times `intensity`, its zenith `up` (unit, world), turned
    /// by `rotation` radians about it, seen by camera rays when `visible`.
    #[must_use]
    pub fn new(
        radiance: Radiance,
        intensity: f64,
        up: DVec3,
        rotation: f64,
        visible: bool,
    ) -> Environment {
        let to_local = world_to_map(up, rotation);
        Environment { radiance, intensity, to_local, to_world: to_local.transpose(), visible }
    }

    /// Whether camera rays see it.
    #[must_use]
    pub fn visible(&self) -> bool {
        self.visible
    }

    /// `∫ Y(L(ω)) dω` over the sphere (for choosing between lights by power).
    #[must_use]
    pub fn luminance_integral(&self) -> f64 {
        let base = match &self.radiance {
            Radiance::Constant(c) => 4.0 * std::f64::consts::PI * f64::from(c.luminance()),
            Radiance::Map(m) => m.luminance_integral(),
        };
        self.intensity * base
    }

    /// Radiance arriving along unit world `direction` (towards the environment).
    #[must_use]
    pub fn radiance(&self, direction: DVec3) -> [f64; 3] {
        let c = match &self.radiance {
            Radiance::Constant(c) => *c,
            Radiance::Map(m) => m.eval(self.to_local * direction),
        };
        c.to_f64().map(|v| v * self.intensity)
    }

    /// Sample a direction (unit, world).
    #[must_use]
    pub fn sample(&self, u: [f64; 2]) -> Option<LightSample> {
        match &self.radiance {
            Radiance::Constant(c) => {
                let z = 1.0 - 2.0 * u[0];
                let r = (1.0 - z * z).max(0.0).sqrt();
                let phi = std::f64::consts::TAU * u[1];
                let direction = DVec3::new(r * phi.cos(), r * phi.sin(), z);
                let inv_pdf = 4.0 * std::f64::consts::PI;
                Some(LightSample {
                    direction,
                    distance: f64::INFINITY,
                    value: c.to_f64().map(|v| v * self.intensity * inv_pdf),
                    pdf: 1.0 / inv_pdf,
                })
            }
            Radiance::Map(m) => {
                let s = m.sample(u)?;
                if s.pdf <= 0.0 {
                    return None;
                }
                let value = s.radiance.to_f64().map(|v| v * self.intensity / s.pdf);
                Some(LightSample {
                    direction: self.to_world * s.direction,
                    distance: f64::INFINITY,
                    value,
                    pdf: s.pdf,
                })
            }
        }
    }

    /// Solid-angle pdf of [`Environment::sample`] giving unit world `direction`.
    #[must_use]
    pub fn pdf(&self, direction: DVec3) -> f64 {
        match &self.radiance {
            Radiance::Constant(_) => 1.0 / (4.0 * std::f64::consts::PI),
            Radiance::Map(m) => m.pdf(self.to_local * direction),
        }
    }
}
