//! A sphere light of radius `r` at `c` with uniform radiance `L` over its surface; `r = 0`
//! is a point light.
//!
//! **Units.** Given its power `Φ` (W per linear Rec.709 channel; Cycles' point-light
//! *Power* with soft falloff off), a sphere of uniform radiance emits `Φ = 4π r² · π L`,
//! so `L = Φ / (4π² r²)`; a point light has intensity `I = Φ / 4π` (W·sr⁻¹) and gives
//! `E = I / d²` at distance `d`. An intensity `I` may be given instead: `Φ = 4π I`.
//!
//! **Sampling** (seen from `x` outside the sphere, `d = |c − x|`): uniform in the cone of
//! directions that hit it, `sin²θ_max = r²/d²`, `p(ω) = 1 / (2π(1 − cos θ_max))`, with
//! `1 − cos θ_max = sin²θ_max / (1 + cos θ_max)` (no cancellation for small or far
//! spheres). The sampled direction's distance is that of its first hit on the sphere.
//! The light is opaque: forward rays that hit it stop there. A point inside the sphere
//! receives nothing (it is inside an opaque emitter).

use glam::DVec3;

use super::sample::{frame, LightSample};
use plume_core::color::Rgb;
use plume_volume::field::Ray;

/// A sphere (or point) light.
#[derive(Clone, Debug)]
pub struct Sphere {
    centre: DVec3,
    radius: f64,
    /// Radiance of the surface (sphere) or intensity (point), per channel.
    value: [f64; 3],
    power: Rgb,
}

impl Sphere {
    /// A light at `centre` with `radius ≥ 0` emitting `power` in all (W).
    #[must_use]
    pub fn new(centre: DVec3, radius: f64, power: Rgb) -> Sphere {
        let pi = std::f64::consts::PI;
        let p = power.to_f64();
        let value = if radius > 0.0 {
            p.map(|c| c / (4.0 * pi * pi * radius * radius))
        } else {
            p.map(|c| c / (4.0 * pi))
        };
        Sphere { centre, radius, value, power }
    }

    /// Emitted power.
    #[must_use]
    pub fn power(&self) -> Rgb {
        self.power
    }

    /// Whether this is a point light (a delta in position).
    #[must_use]
    pub fn is_point(&self) -> bool {
        self.radius == 0.0
    }

    /// `(sin²θ_max, 1 − cos θ_max)` of the cone seen from a point at squared distance
    /// `d2 > r²`.
    fn cone(&self, d2: f64) -> (f64, f64) {
        let sin2 = (self.radius * self.radius / d2).min(1.0);
        let cos_max = (1.0 - sin2).max(0.0).sqrt();
        (sin2, sin2 / (1.0 + cos_max))
    }

    /// Sample a direction from `x` towards the light; `None` from inside the sphere.
    #[must_use]
    pub fn sample(&self, x: DVec3, u: [f64; 2]) -> Option<LightSample> {
        let to_c = self.centre - x;
        let d2 = to_c.length_squared();
        if d2 <= self.radius * self.radius || d2 == 0.0 {
            return None;
        }
        let d = d2.sqrt();
        let w = to_c / d;
        if self.is_point() {
            return Some(LightSample {
                direction: w,
                distance: d,
                value: self.value.map(|c| c / d2),
                pdf: 0.0,
            });
        }
        let (_, h) = self.cone(d2);
        let one_minus_cos = u[0] * h;
        let cos_t = 1.0 - one_minus_cos;
        let sin_t = (one_minus_cos * (2.0 - one_minus_cos)).max(0.0).sqrt();
        let phi = std::f64::consts::TAU * u[1];
        let (t, b) = frame(w);
        let direction = (t * (sin_t * phi.cos()) + b * (sin_t * phi.sin()) + w * cos_t).normalize();
        // First hit along the sampled direction (it hits by construction; a grazing
        // direction that rounding moved off the sphere gets the tangent distance)
        let distance = self.intersect(&Ray { origin: x, direction }).unwrap_or(d * cos_t);
        let pdf = 1.0 / (std::f64::consts::TAU * h);
        Some(LightSample { direction, distance, value: self.value.map(|c| c / pdf), pdf })
    }

    /// Solid-angle pdf of [`Sphere::sample`] from `x` giving unit `direction` (0 for a
    /// point light, from inside, or off the sphere).
    #[must_use]
    pub fn pdf(&self, x: DVec3, direction: DVec3) -> f64 {
        let to_c = self.centre - x;
        let d2 = to_c.length_squared();
        if self.is_point() || d2 <= self.radius * self.radius {
            return 0.0;
        }
        let (_, h) = self.cone(d2);
        // Inside the cone: the angle to the centre is at most θ_max
        let w = to_c / d2.sqrt();
        if 0.5 * (direction - w).length_squared() <= h {
            1.0 / (std::f64::consts::TAU * h)
        } else {
            0.0
        }
    }

    /// Distance to the first hit of `ray` (unit direction) on the sphere, if it is ahead.
    #[must_use]
    pub fn intersect(&self, ray: &Ray) -> Option<f64> {
        if self.is_point() {
            return None;
        }
        // |o + t d − c|² = r²: t² − 2 t b + c2 = 0 with b = d·(c − o), c2 = |c − o|² − r²,
        // discriminant from the perpendicular distance (Hearn–Baker/pbrt-v4 form, stable)
        let oc = self.centre - ray.origin;
        let b = ray.direction.dot(oc);
        let perp = oc - ray.direction * b;
        let disc = self.radius * self.radius - perp.length_squared();
        if disc < 0.0 {
            return None;
        }
        let q = disc.sqrt();
        let c2 = oc.length_squared() - self.radius * self.radius;
        if c2 <= 0.0 {
            return None; // the origin is inside the light
        }
        if b <= 0.0 {
            return None; // the sphere is behind
        }
        // Near root via the product of roots (no cancellation): t₀ t₁ = c2
        let far = b + q;
        Some(c2 / far)
    }

    /// Radiance of the surface (area light).
    #[must_use]
    pub fn radiance(&self) -> [f64; 3] {
        self.value
    }
}
