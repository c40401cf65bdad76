//! How a collision scatters ([`Phase`]): with one medium's Henyey–Greenstein lobe, or,
//! where several volumes overlap, with the mixture of their scattering classes.
//!
//! A collision in several volumes carries each class's share `w_k = μ_k/μ_t`
//! (`volume::overlap`), class `k` scattering with colour `C_k` and asymmetry `g_k`. The
//! in-scattering operator is `Σ_k w_k C_k,c p_k(ω)` per channel `c`, exactly the sum of
//! the volumes'. It is applied as:
//!
//! ```text
//! albedo   α_c    = Σ_k w_k C_k,c                  (multiplies the throughput at the vertex)
//! phase    φ_c(ω) = Σ_k s_k,c p_k(ω),  s_k,c = w_k C_k,c / α_c   (normalized per channel)
//! sampling q(ω)   = Σ_k λ_k p_k(ω),    λ_k ∝ w_k · mean_c C_k,c
//! ```
//!
//! Phase sampling picks lobe `k` with probability `λ_k` (the direction's first number,
//! rescaled, picks the lobe; the lobe's own inversion uses the rest) and weighs the
//! direction by `φ_c(ω)/q(ω)` per channel; light sampling evaluates `φ_c(ω)` and takes
//! `q(ω)` as the phase technique's pdf for MIS. Where every class has the same colour
//! (or there is one), `φ_c = q` and the weight is 1: the choice of METHOD.md §14 by
//! `μ_s^i/μ_s`. One medium's [`Phase::Hg`] is today's arithmetic, bit for bit.

use glam::DVec3;

use plume_core::sampling::phase::{hg_pdf, sample_hg};
use plume_volume::field::{ClassWeights, ScatterClass};
use plume_volume::overlap::MAX_CLASSES;

/// The phase function at a scattering vertex (held once per vertex and lent by
/// reference, so the mixture's size costs one lobe's vertices nothing).
#[derive(Clone, Copy, Debug)]
#[allow(clippy::large_enum_variant, reason = "one per vertex, on the stack, passed by reference")]
pub enum Phase {
    /// One medium's Henyey–Greenstein lobe.
    Hg(f64),
    /// Several volumes' classes.
    Mixture(Mixture),
}

/// The lobes of a collision in several volumes (see the module docs).
#[derive(Clone, Copy, Debug)]
pub struct Mixture {
    /// Lobes with a share: asymmetry, per-channel share `s_k,c`, sampling probability `λ_k`.
    lobes: [Lobe; MAX_CLASSES],
    count: usize,
}

#[derive(Clone, Copy, Debug, Default)]
struct Lobe {
    g: f64,
    share: [f64; 3],
    lambda: f64,
}

/// A phase function's value for a direction: per channel (equal for one lobe) and the
/// density of phase sampling.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhaseValue {
    /// `φ_c(ω)` per channel.
    pub f: [f64; 3],
    /// `q(ω)`, the density with which [`Phase::sample`] draws `ω`.
    pub pdf: f64,
}

/// A direction drawn by [`Phase::sample`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhaseDraw {
    /// Unit direction.
    pub direction: DVec3,
    /// Its density `q(ω)`.
    pub pdf: f64,
    /// `φ_c(ω)/q(ω)` per channel; `None` where it is 1 (one lobe).
    pub weight: Option<[f64; 3]>,
}

/// The albedo `α_c` and phase of a collision with class shares `w` among `classes`.
#[must_use]
pub fn mixture(classes: &[ScatterClass], w: &ClassWeights) -> ([f64; 3], Phase) {
    let mut albedo = [0.0f64; 3];
    let mut lobes = [Lobe::default(); MAX_CLASSES];
    let mut count = 0;
    let mut total = 0.0f64;
    for (class, &wk) in classes.iter().zip(&w.0) {
        if wk <= 0.0 {
            continue;
        }
        let s = class.color.map(|c| f64::from(wk) * f64::from(c));
        let lambda = (s[0] + s[1] + s[2]) / 3.0;
        if lambda <= 0.0 {
            continue;
        }
        (0..3).for_each(|c| albedo[c] += s[c]);
        lobes[count] = Lobe { g: class.g, share: s, lambda };
        total += lambda;
        count += 1;
    }
    for lobe in &mut lobes[..count] {
        lobe.lambda /= total;
        lobe.share =
            std::array::from_fn(|c| if albedo[c] > 0.0 { lobe.share[c] / albedo[c] } else { 0.0 });
    }
    (albedo, Phase::Mixture(Mixture { lobes, count }))
}

impl Phase {
    /// `φ_c` and `q` for the angle with cosine `cos_theta` to the incoming direction.
    #[inline]
    #[must_use]
    pub fn eval(&self, cos_theta: f64) -> PhaseValue {
        match self {
            Phase::Hg(g) => {
                let p = hg_pdf(*g, cos_theta);
                PhaseValue { f: [p; 3], pdf: p }
            }
            Phase::Mixture(m) => {
                let mut f = [0.0f64; 3];
                let mut pdf = 0.0f64;
                for lobe in &m.lobes[..m.count] {
                    let p = hg_pdf(lobe.g, cos_theta);
                    pdf += lobe.lambda * p;
                    (0..3).for_each(|c| f[c] += lobe.share[c] * p);
                }
                PhaseValue { f, pdf }
            }
        }
    }

    /// A new direction from `incoming` with the numbers `u`.
    #[must_use]
    pub fn sample(&self, incoming: DVec3, u: [f64; 2]) -> PhaseDraw {
        match self {
            Phase::Hg(g) => {
                let s = sample_hg(*g, incoming, u);
                PhaseDraw { direction: s.direction, pdf: s.pdf, weight: None }
            }
            Phase::Mixture(m) => {
                let lobes = &m.lobes[..m.count];
                // The lobe from the first number, which is then rescaled to [0, 1)
                let (mut k, mut below) = (0, 0.0f64);
                while k + 1 < lobes.len() && u[0] >= below + lobes[k].lambda {
                    below += lobes[k].lambda;
                    k += 1;
                }
                let v = ((u[0] - below) / lobes[k].lambda).clamp(0.0, 1.0 - f64::EPSILON);
                let s = sample_hg(lobes[k].g, incoming, [v, u[1]]);
                let value = self.eval(incoming.dot(s.direction));
                let weight =
                    if value.pdf > 0.0 { value.f.map(|f| f / value.pdf) } else { [0.0; 3] };
                PhaseDraw { direction: s.direction, pdf: value.pdf, weight: Some(weight) }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use plume_core::sampling::Sampler;

    fn classes() -> Vec<ScatterClass> {
        vec![
            ScatterClass { color: [0.9, 0.5, 0.1], g: 0.7 },
            ScatterClass { color: [0.2, 0.4, 0.8], g: -0.4 },
        ]
    }

    fn weights(a: f32, b: f32) -> ClassWeights {
        let mut w = [0.0; MAX_CLASSES];
        (w[0], w[1]) = (a, b);
        ClassWeights(w)
    }

    /// `E_q[φ_c/q · h(ω)] = ∫ φ_c h`: the sampled weights integrate a test function as
    /// the per-channel phase does (here h = 1 + cos, whose integral against a normalized
    /// HG lobe is 1 + g).
    #[test]
    fn sampled_mixture_is_unbiased_per_channel() {
        let (albedo, phase) = mixture(&classes(), &weights(0.3, 0.5));
        let incoming = DVec3::new(0.0, 0.6, 0.8);
        let mut s = Sampler::new(7, 0, 0);
        let n = 400_000;
        let mut sum = [0.0f64; 3];
        for _ in 0..n {
            let d = phase.sample(incoming, [s.next_f64(), s.next_f64()]);
            let w = d.weight.unwrap();
            (0..3).for_each(|c| sum[c] += w[c] * (1.0 + incoming.dot(d.direction)));
        }
        for c in 0..3 {
            let (s0, s1) = (0.3 * classes()[0].color[c] as f64, 0.5 * classes()[1].color[c] as f64);
            assert!((albedo[c] - (s0 + s1)).abs() < 1e-7);
            let expected = (s0 * 1.7 + s1 * 0.6) / (s0 + s1);
            let mean = sum[c] / f64::from(n);
            assert!((mean - expected).abs() < 0.01 * expected, "channel {c}: {mean} vs {expected}");
        }
    }

    #[test]
    fn one_colour_weighs_one_and_one_lobe_is_hg() {
        let same = vec![
            ScatterClass { color: [0.5; 3], g: 0.3 },
            ScatterClass { color: [0.5; 3], g: -0.6 },
        ];
        let (_, phase) = mixture(&same, &weights(0.2, 0.7));
        let d = phase.sample(DVec3::Z, [0.37, 0.81]);
        for w in d.weight.unwrap() {
            assert!((w - 1.0).abs() < 1e-12, "{w}");
        }
        let v = Phase::Hg(0.4).eval(0.25);
        assert_eq!(v.f, [hg_pdf(0.4, 0.25); 3]);
        assert_eq!(v.pdf, hg_pdf(0.4, 0.25));
    }
}
