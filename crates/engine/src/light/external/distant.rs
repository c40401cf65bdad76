//! A distant light (a sun): radiance `L` from every direction within a cone of half-angle
//! `α` around the direction towards the light, `−d` (`d` the direction the light travels).
//!
//! **Units.** The light is given by its irradiance `E` on a surface facing it (W·m⁻² per
//! linear Rec.709 channel; Cycles' Sun *Strength*). A uniform disc of half-angle `α`
//! gives `E = ∫_cone L cos θ dω = π L sin²α`, so `L = E / (π sin²α)`. With `α = 0` the
//! light is a delta in direction and carries `E` itself.
//!
//! **Sampling.** Uniform in the cone: `cos θ = 1 − u₀ h` with `h = 1 − cos α = 2 sin²(α/2)`
//! (computed so, because for the sun `1 − cos α ≈ 1.1·10⁻⁵` loses half its digits), `φ = 2π
//! u₁`; `p(ω) = 1 / (2π h)`. With `sin²θ = (1 − cos θ)(1 + cos θ)` every quantity keeps
//! full precision down to arc-second discs.

use glam::DVec3;

use super::sample::{frame, LightSample};
use plume_core::color::Rgb;

/// A distant light.
#[derive(Clone, Debug)]
pub struct Distant {
    /// Unit direction from the scene towards the light (`−d`).
    to_light: DVec3,
    /// `1 − cos α`; 0 for a delta light.
    h: f64,
    /// Radiance inside the cone (area light) or irradiance (delta light).
    value: [f64; 3],
    /// Irradiance on a surface facing the light, for choosing between lights.
    irradiance: Rgb,
}

impl Distant {
    /// A light travelling along unit `direction` with irradiance `irradiance` on a surface
    /// facing it and angular diameter `angle` radians (`0 ≤ angle < π`).
    #[must_use]
    pub fn new(direction: DVec3, irradiance: Rgb, angle: f64) -> Distant {
        let alpha = 0.5 * angle;
        let half = (0.5 * alpha).sin();
        let h = 2.0 * half * half;
        let e = irradiance.to_f64();
        let value = if h > 0.0 {
            let s = alpha.sin();
            e.map(|c| c / (std::f64::consts::PI * s * s))
        } else {
            e
        };
        Distant { to_light: -direction.normalize(), h, value, irradiance }
    }

    /// Irradiance on a surface facing the light.
    #[must_use]
    pub fn irradiance(&self) -> Rgb {
        self.irradiance
    }

    /// Whether the light is a delta in direction (zero angular diameter).
    #[must_use]
    pub fn is_delta(&self) -> bool {
        self.h == 0.0
    }

    /// Sample a direction towards the light.
    #[must_use]
    pub fn sample(&self, u: [f64; 2]) -> LightSample {
        if self.is_delta() {
            return LightSample {
                direction: self.to_light,
                distance: f64::INFINITY,
                value: self.value,
                pdf: 0.0,
            };
        }
        let one_minus_cos = u[0] * self.h;
        let cos_t = 1.0 - one_minus_cos;
        let sin_t = (one_minus_cos * (2.0 - one_minus_cos)).max(0.0).sqrt();
        let phi = std::f64::consts::TAU * u[1];
        let (t, b) = frame(self.to_light);
        let direction =
            (t * (sin_t * phi.cos()) + b * (sin_t * phi.sin()) + self.to_light * cos_t).normalize();
        let pdf = self.pdf_in_cone();
        LightSample { direction, distance: f64::INFINITY, value: self.value.map(|c| c / pdf), pdf }
    }

    fn pdf_in_cone(&self) -> f64 {
        1.0 / (std::f64::consts::TAU * self.h)
    }

    /// `1 − cos θ` of unit `direction` against the direction towards the light, kept
    /// precise near 0: `|ω − ω_l|² / 2`.
    fn one_minus_cos(&self, direction: DVec3) -> f64 {
        0.5 * (direction - self.to_light).length_squared()
    }

    /// Solid-angle pdf of [`Distant::sample`] giving unit `direction` (0 outside the cone and
    /// for a delta light).
    #[must_use]
    pub fn pdf(&self, direction: DVec3) -> f64 {
        if !self.is_delta() && self.one_minus_cos(direction) <= self.h {
            self.pdf_in_cone()
        } else {
            0.0
        }
    }

    /// Radiance arriving along unit `direction` (towards the light): `L` inside the cone.
    #[must_use]
    pub fn radiance(&self, direction: DVec3) -> Option<[f64; 3]> {
        (!self.is_delta() && self.one_minus_cos(direction) <= self.h).then_some(self.value)
    }
}
