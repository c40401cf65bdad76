//! Integrators: radiance along camera rays.
//!
//! [`Integrator`] (in `volpath.rs`) traces forward paths with line-integrated emission and
//! optional NEE/FNEE; with `max_depth = 0` or albedo 0 it is the emission–absorption
//! integrator `L = ∫₀^d τ(s) L_e(s) ds`. Alpha is `1 − τ(d)` of the camera segment
//! (estimated: the escape indicator, or the exact ray-marched transmittance).

pub mod volpath;

use crate::camera::Camera;
use crate::medium::Medium;
use crate::volume::field::Field;

pub use volpath::{light_power, Integrator, LightSampling, Lights, MisHeuristic};

/// Everything a render reads: immutable and `Sync`, built once.
#[derive(Debug)]
pub struct Scene<F: Field> {
    /// The volume (or an analytic field in tests).
    pub field: F,
    /// Coefficients and emission.
    pub medium: Medium,
    /// The camera.
    pub camera: Camera,
    /// Light-sampling structures (NEE distribution, FNEE proxy), when used.
    pub lights: Lights,
}

/// Integer counters gathered per tile and summed in tile order.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Counters {
    /// Camera samples taken.
    pub samples: u64,
    /// Segments visited by tracking (after merging equal neighbours).
    pub segments: u64,
    /// Voxel steps of all traversals (voxels crossed plus skipped pyramid nodes).
    pub voxel_steps: u64,
    /// Real collisions sampled.
    pub collisions: u64,
    /// FNEE direction samples taken.
    pub fnee_samples: u64,
    /// Classic NEE samples taken.
    pub nee_samples: u64,
    /// Samples dropped because they were NaN or infinite.
    pub nonfinite_samples: u64,
    /// The first dropped sample, for `--debug-pixel` (serialized as
    /// `{"x": …, "y": …, "sample": …}`, or `null`).
    pub first_nonfinite: Option<crate::render::SampleId>,
}

impl Counters {
    /// Add another tile's counters (keeps the first non-finite sample of `self`).
    pub fn merge(&mut self, o: &Counters) {
        self.samples += o.samples;
        self.segments += o.segments;
        self.voxel_steps += o.voxel_steps;
        self.collisions += o.collisions;
        self.fnee_samples += o.fnee_samples;
        self.nee_samples += o.nee_samples;
        self.nonfinite_samples += o.nonfinite_samples;
        if self.first_nonfinite.is_none() {
            self.first_nonfinite = o.first_nonfinite;
        }
    }
}

/// Receives a path's events when a sample is replayed with `--debug-pixel`. The render
/// loop uses [`NoTrace`], which compiles to nothing.
pub trait Trace {
    /// Record one event; `message` is only called when tracing.
    fn event(&mut self, message: impl FnOnce() -> String);
}

/// Tracing off.
pub struct NoTrace;

impl Trace for NoTrace {
    #[inline(always)]
    fn event(&mut self, _message: impl FnOnce() -> String) {}
}

/// Tracing into a list of lines.
#[derive(Default)]
pub struct LineTrace(pub Vec<String>);

impl Trace for LineTrace {
    fn event(&mut self, message: impl FnOnce() -> String) {
        self.0.push(message());
    }
}
