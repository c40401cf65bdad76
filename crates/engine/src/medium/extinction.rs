//! Extinction per colour channel (METHOD.md §15): grey, as most media are, or chromatic.
//!
//! A chromatic medium (Cycles' Principled Volume with an *Absorption Color*) has, per
//! channel `c`, `μ_t^c = k_c μ` and `μ_s^c = C_c μ`, where `μ = σ_t ρ` is the medium's
//! reference extinction ([`super::Medium::mu_t`]), `C` the scattering colour (the
//! medium's `albedo`) and `k_c = C_c + (1 − C_c)(1 − √A_c)` (Cycles' `color + absorption`
//! with `absorption = max(1 − C, 0) · max(1 − √A, 0)`). The channels share one density
//! field, so channel `c`'s optical depth is `k_c OD` with `OD = ∫ μ`, the one a grey walk
//! sums: `τ_c = e^{−k_c OD}`.
//!
//! **Hero-channel free paths** (one-sample MIS over channels, balance heuristic; Wilkie
//! et al. 2014, pbrt-v4's spectral MIS): a channel `h` is picked uniformly and the free
//! path is drawn exactly with `μ_t^h`, i.e. a grey walk to `OD = E/k_h`. The law drawn is
//! the mixture `p̄(t) = μ(t) k̄(OD)`, `k̄(OD) = ⅓ Σ_j k_j e^{−k_j OD}`, escaping with
//! `τ̄(OD) = ⅓ Σ_j e^{−k_j OD}`. So channel `c` of
//! - a collision is weighted `μ_s^c τ_c / p̄ = C_c e^{−k_c OD} / k̄(OD)`
//!   ([`Chromatic::collision_weights`], times `C_c`);
//! - an escape is weighted `τ_c / τ̄` ([`Chromatic::escape_weights`]);
//! - the line estimator's emission at `s` before the collision is weighted
//!   `τ_c(s)/τ̄(s)`, since `Pr{t > s} = τ̄(s)` (`medium::chromatic`).
//!
//! Every weight is at most 3. They are formed relative to the least attenuated channel,
//! `e^{−(k_c − k_min) OD}`, so no ratio is `0/0` however deep the walk.

/// How extinction depends on the colour channel.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Extinction {
    /// The same in every channel: `μ_t = σ_t ρ`.
    #[default]
    Grey,
    /// `μ_t^c = k_c σ_t ρ`, with `k` not the same in every channel.
    Chromatic(Chromatic),
}

impl Extinction {
    /// The optical depth (`OD = ∫ σ_t ρ`) past which every channel's transmittance is 0
    /// in `f64`: `745 / k_min` (unbounded where a channel is not attenuated).
    #[inline]
    #[must_use]
    pub fn od_stop(&self) -> f64 {
        match self {
            Extinction::Grey => 745.0,
            Extinction::Chromatic(c) if c.k_min > 0.0 => 745.0 / c.k_min,
            Extinction::Chromatic(_) => f64::INFINITY,
        }
    }

    /// The free-path density per unit `μ` at a collision after optical depth `od`:
    /// `e^{−OD}` when grey, the hero-channel mixture `k̄(OD)` when chromatic (point NEE's
    /// MIS partner, `integrator::scatter`).
    #[inline]
    #[must_use]
    pub fn collision_density(&self, od: f64) -> f64 {
        match self {
            Extinction::Grey => (-od).exp(),
            Extinction::Chromatic(c) => c.mixture(od),
        }
    }

    /// [`Extinction::collision_density`] from a shadow ray's transmittance and its
    /// channels (`τ_c = tau · channels[c]`): `tau` when grey, `⅓ Σ k_c τ_c` when chromatic.
    #[inline]
    #[must_use]
    pub fn collision_density_of(&self, tau: f64, channels: [f64; 3]) -> f64 {
        match self {
            Extinction::Grey => tau,
            Extinction::Chromatic(c) => {
                (c.k[0] * channels[0] + c.k[1] * channels[1] + c.k[2] * channels[2]) * tau / 3.0
            }
        }
    }
}

/// The channels' extinction factors `k` of a chromatic medium.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Chromatic {
    k: [f64; 3],
    k_min: f64,
}

impl Chromatic {
    /// A medium whose channel `c` has extinction `k[c] · σ_t ρ` (`k ≥ 0`, finite).
    #[must_use]
    pub fn new(k: [f64; 3]) -> Chromatic {
        Chromatic { k, k_min: k[0].min(k[1]).min(k[2]) }
    }

    /// The factors `k`.
    #[must_use]
    pub fn factors(&self) -> [f64; 3] {
        self.k
    }

    /// The hero channel and the free path's own uniform number, both from the free
    /// path's `u ∈ [0, 1)`: channel `⌊3u⌋`, then `3u − ⌊3u⌋` (below 1), so the Sobol
    /// dimension that stratified the free path stratifies both.
    #[inline]
    #[must_use]
    pub fn hero(u: f64) -> (usize, f64) {
        let v = u * 3.0;
        let h = (v as usize).min(2);
        (h, (v - h as f64).clamp(0.0, 1.0 - f64::EPSILON / 2.0))
    }

    /// The hero channel's free path, as a grey walk's target optical depth: `E / k_h`
    /// (infinite where the channel is not attenuated: it never collides).
    #[inline]
    #[must_use]
    pub fn target(&self, hero: usize, exponential: f64) -> f64 {
        if self.k[hero] > 0.0 {
            exponential / self.k[hero]
        } else {
            f64::INFINITY
        }
    }

    /// `e^{−(k_c − k_min) OD}` per channel.
    #[inline]
    fn relative(&self, od: f64) -> [f64; 3] {
        self.k.map(|k| (-(k - self.k_min) * od).exp())
    }

    /// Each channel's transmittance `e^{−k_c OD}`.
    #[inline]
    #[must_use]
    pub fn transmittances(&self, od: f64) -> [f64; 3] {
        self.k.map(|k| (-k * od).exp())
    }

    /// Each channel's transmittance at optical depth `od` times `weight`, as their mean and
    /// each channel's ratio to it (`τ_c · weight = mean · ratio_c`; ratios 1 where the mean
    /// is 0): what a walk reports as `transmittance` and its channels.
    #[inline]
    #[must_use]
    pub fn transmittance_ratios(&self, od: f64, weight: f64) -> (f64, [f64; 3]) {
        let taus = self.transmittances(od).map(|t| t * weight);
        let mean = (taus[0] + taus[1] + taus[2]) / 3.0;
        (mean, if mean > 0.0 { taus.map(|t| t / mean) } else { [1.0; 3] })
    }

    /// `τ_c / τ̄` at optical depth `od`: an escape's weights, and the line estimator's
    /// ratio at a point before the collision.
    #[inline]
    #[must_use]
    pub fn escape_weights(&self, od: f64) -> [f64; 3] {
        let r = self.relative(od);
        let mean = (r[0] + r[1] + r[2]) / 3.0;
        r.map(|v| v / mean)
    }

    /// `e^{−k_c OD} / k̄(OD)` at a collision after optical depth `od`; channel `c`'s
    /// throughput is multiplied by `C_c` times this.
    #[inline]
    #[must_use]
    pub fn collision_weights(&self, od: f64) -> [f64; 3] {
        let r = self.relative(od);
        let mixture = (self.k[0] * r[0] + self.k[1] * r[1] + self.k[2] * r[2]) / 3.0;
        if mixture > 0.0 {
            r.map(|v| v / mixture)
        } else {
            [0.0; 3]
        }
    }

    /// `k̄(OD) = ⅓ Σ_j k_j e^{−k_j OD}`.
    #[inline]
    #[must_use]
    pub fn mixture(&self, od: f64) -> f64 {
        let t = self.transmittances(od);
        (self.k[0] * t[0] + self.k[1] * t[1] + self.k[2] * t[2]) / 3.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hero_channel_and_its_number_cover_the_unit_interval() {
        assert_eq!(Chromatic::hero(0.0), (0, 0.0));
        let (h, v) = Chromatic::hero(0.5);
        assert_eq!(h, 1);
        assert!((v - 0.5).abs() < 1e-15);
        let (h, v) = Chromatic::hero(1.0 - f64::EPSILON / 2.0);
        assert_eq!(h, 2);
        assert!(v < 1.0);
    }

    #[test]
    fn weights_are_the_balance_heuristic_and_average_to_one() {
        let c = Chromatic::new([1.0, 0.5, 0.1]);
        for od in [0.0, 0.3, 2.0, 40.0, 1e4] {
            let t = c.transmittances(od);
            let mean = t.iter().sum::<f64>() / 3.0;
            let w = c.escape_weights(od);
            // E over the hero of the escape weight: each channel's own transmittance
            if mean > 1e-300 {
                for ch in 0..3 {
                    assert!((w[ch] * mean - t[ch]).abs() <= 1e-12 * t[ch].max(1e-300), "{od}");
                }
            }
            assert!(w.iter().all(|v| v.is_finite() && *v <= 3.0 + 1e-12));
            let cw = c.collision_weights(od);
            assert!(cw.iter().all(|v| v.is_finite()), "{od} {cw:?}");
        }
        // A channel that is not attenuated keeps every ratio finite
        let c = Chromatic::new([0.0, 1.0, 1.0]);
        assert_eq!(c.escape_weights(1e6), [3.0, 0.0, 0.0]);
        assert_eq!(Extinction::Chromatic(c).od_stop(), f64::INFINITY);
    }
}
