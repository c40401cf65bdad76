//! Optics: the medium's coefficients, emission models and free-path tracking with the
//! emission estimators of METHOD.md §3–4. This module consumes only
//! [`plume_volume::Segment`]s; it never indexes a voxel.
//!
//! Units: `sigma_t` is per world unit (metre) per unit density, so `μ_t = σ_t ρ`;
//! `μ_s = a μ_t`, `μ_a = (1 − a) μ_t`. Emission density `L_e` is radiance added per unit
//! length (W m⁻³ sr⁻¹ per RGB channel) and already contains its coefficient.

pub mod emission;
pub mod forced;
pub mod null_tracking;
pub mod tracking;

pub use emission::{Convention, Emission, EmissionKind, TemperatureMap};
pub use forced::Collision;
pub use tracking::{track, DistanceSample, Estimator, TrackResult};

/// Coefficients and emission of the volume's medium.
#[derive(Clone, Copy, Debug)]
pub struct Medium {
    /// σ_t: extinction per metre per unit density (the `--density-scale`).
    pub sigma_t: f64,
    /// Single-scattering albedo `a = μ_s / μ_t`, in `[0, 1]`.
    pub albedo: f32,
    /// Henyey–Greenstein asymmetry `g ∈ (−1, 1)`.
    pub g: f64,
    /// Emission model.
    pub emission: Emission,
}

impl Medium {
    /// μ_t for a density value, per metre.
    #[inline]
    #[must_use]
    pub fn mu_t(&self, density: f32) -> f64 {
        self.sigma_t * f64::from(density)
    }
}
