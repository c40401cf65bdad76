//! Integrators: radiance along camera rays.
//!
//! The emission–absorption integrator estimates, per camera ray,
//! `L = ∫₀^d τ(s) L_e(s) ds` with the chosen [`Estimator`] and reports `α = 1 − τ(d)`
//! (estimated: the escape indicator, or the exact ray-marched transmittance).

use crate::camera::Camera;
use crate::medium::{track, Estimator, Medium};
use crate::sampling::Sampler;
use crate::volume::field::{Field, Ray};

/// Everything a render reads: immutable and `Sync`, built once.
#[derive(Debug)]
pub struct Scene<F: Field> {
    /// The volume (or an analytic field in tests).
    pub field: F,
    /// Coefficients and emission.
    pub medium: Medium,
    /// The camera.
    pub camera: Camera,
}

/// Integer counters gathered per tile and summed in tile order.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Counters {
    /// Camera samples taken.
    pub samples: u64,
    /// Segments visited by tracking.
    pub segments: u64,
    /// Real collisions sampled.
    pub collisions: u64,
    /// Samples dropped because they were NaN or infinite.
    pub nonfinite_samples: u64,
    /// The first dropped sample as `(x, y, sample)`, for `--debug-pixel`.
    pub first_nonfinite: Option<(u32, u32, u64)>,
}

impl Counters {
    /// Add another tile's counters (keeps the first non-finite sample of `self`).
    pub fn merge(&mut self, o: &Counters) {
        self.samples += o.samples;
        self.segments += o.segments;
        self.collisions += o.collisions;
        self.nonfinite_samples += o.nonfinite_samples;
        if self.first_nonfinite.is_none() {
            self.first_nonfinite = o.first_nonfinite;
        }
    }
}

/// How radiance is estimated.
#[derive(Clone, Copy, Debug)]
pub struct Integrator {
    /// Emission estimator for every free-path segment.
    pub estimator: Estimator,
}

impl Integrator {
    /// Radiance and alpha `[r, g, b, α]` along `ray`.
    pub fn li<F: Field>(&self, scene: &Scene<F>, ray: &Ray, sampler: &mut Sampler, counters: &mut Counters) -> [f64; 4] {
        let u = sampler.next_f64();
        let r = track(&scene.field, &scene.medium, ray, f64::INFINITY, self.estimator, false, u, sampler);
        counters.segments += u64::from(r.segments);
        if matches!(r.event, crate::medium::DistanceSample::Collided { .. }) {
            counters.collisions += 1;
        }
        [r.emission[0], r.emission[1], r.emission[2], 1.0 - r.transmittance]
    }
}
