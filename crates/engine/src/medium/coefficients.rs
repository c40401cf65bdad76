//! The medium's coefficients and emission model ([`Medium`]).

use super::emission::Emission;

/// Coefficients and emission of the volume's medium.
#[derive(Clone, Copy, Debug)]
pub struct Medium {
    /// σ_t: extinction per metre per unit density (the `--density-scale`).
    pub sigma_t: f64,
    /// Single-scattering albedo `a = μ_s / μ_t` per channel, in `[0, 1]` (extinction is
    /// grey: a channel's `1 − a` is absorbed).
    pub albedo: plume_core::color::Rgb,
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
