//! The medium's coefficients and emission model ([`Medium`]).

use super::emission::Emission;
use super::extinction::{Chromatic, Extinction};
use plume_core::color::Rgb;

/// Coefficients and emission of the volume's medium.
#[derive(Clone, Copy, Debug)]
pub struct Medium {
    /// σ_t: extinction per metre per unit density (the `--density-scale`); a chromatic
    /// medium's channels scale it (`extinction`).
    pub sigma_t: f64,
    /// Single-scattering albedo `a = μ_s / μ_t` per channel, in `[0, 1]`, where extinction
    /// is grey (a channel's `1 − a` is absorbed); where it is chromatic, the scattering
    /// colour `C = μ_s^c / μ_t` relative to the reference `μ_t = σ_t ρ`.
    pub albedo: Rgb,
    /// Henyey–Greenstein asymmetry `g ∈ (−1, 1)`.
    pub g: f64,
    /// Emission model.
    pub emission: Emission,
    /// Grey or chromatic extinction (`medium::extinction`).
    pub extinction: Extinction,
}

impl Medium {
    /// μ_t for a density value, per metre (the reference extinction of a chromatic
    /// medium, whose channel `c` has `k_c` times it).
    #[inline]
    #[must_use]
    pub fn mu_t(&self, density: f32) -> f64 {
        self.sigma_t * f64::from(density)
    }

    /// Cycles' Principled Volume inputs: density scale `σ_t` (its *Density*), scattering
    /// colour `color` (*Color*) and `absorption_color` (*Absorption Color*): per channel
    /// `μ_s = σ_t ρ C` and `μ_t = σ_t ρ (C + (1 − C)(1 − √A))`. A black absorption colour
    /// is today's grey medium with albedo `C`, bit for bit; one whose channels give the
    /// same `k` is a grey medium of extinction `k σ_t` and albedo `C/k`; anything else is
    /// chromatic.
    #[must_use]
    pub fn principled(
        sigma_t: f64,
        color: [f32; 3],
        absorption_color: [f32; 3],
        g: f64,
        emission: Emission,
    ) -> Medium {
        let grey =
            Medium { sigma_t, albedo: Rgb(color), g, emission, extinction: Extinction::Grey };
        if absorption_color == [0.0; 3] {
            return grey;
        }
        let k: [f64; 3] = std::array::from_fn(|c| {
            let (s, a) = (f64::from(color[c]), f64::from(absorption_color[c]));
            s + (1.0 - s).max(0.0) * (1.0 - a.sqrt()).max(0.0)
        });
        if k[0] == k[1] && k[1] == k[2] {
            let albedo =
                if k[0] > 0.0 { color.map(|s| (f64::from(s) / k[0]) as f32) } else { [0.0; 3] };
            return Medium { sigma_t: sigma_t * k[0], albedo: Rgb(albedo), ..grey };
        }
        Medium { extinction: Extinction::Chromatic(Chromatic::new(k)), ..grey }
    }
}
