//! One piece of several overlapping volumes ([`OverlapPiece`]): over a stretch where no
//! volume's own piece ends, the sums `μ_t(u) = Σ_i σ_i ρ_i(u)` and
//! `L_e(u) = Σ_i L_e,i(ρ_i(u), s_i(u))` as cubics in the distance `u` into the stretch, and
//! each scattering class's `μ_k(u)`, the same sum over the volumes of class `k`.
//!
//! The piece is *optical*: it already holds coefficients and emission, so a scene of
//! several volumes is walked with the unit medium (`σ_t = 1`; `Volumes::medium`), and
//! the `σ_t` and `le` the estimators hand its methods are that medium's (`σ_t` multiplies,
//! `le` is not read). It is never [`Piece::constant`]: the estimators take their
//! polynomial forms, which are exact for constant members too (a cubic of degree 0), and
//! free paths solve the summed cubic (`trilinear::poly::solve_integral`, exact in one step
//! where it is linear).

use plume_core::color::Rgb;
use plume_volume::field::{ClassWeights, Piece, PieceCubics, Segment};
use plume_volume::overlap::MAX_CLASSES;
use plume_volume::trilinear::poly;

/// The sum of the volumes' pieces over `[t0, t1]` (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OverlapPiece {
    /// Entry distance.
    pub t0: f64,
    /// Exit distance.
    pub t1: f64,
    /// `μ_t(u)`, per world unit.
    pub mu: [f64; 4],
    /// `L_e(u)` per channel.
    pub emission: [[f64; 4]; 3],
    /// `μ_k(u)` per scattering class (the reference extinction of the class's volumes).
    pub classes: [[f64; 4]; MAX_CLASSES],
    /// Whether any volume's piece may emit.
    pub emits: bool,
}

impl OverlapPiece {
    /// An empty stretch `[t0, t1]` (no volume, or volumes empty there), to which
    /// [`OverlapPiece::add`] adds each volume's piece.
    #[must_use]
    pub fn empty(t0: f64, t1: f64) -> OverlapPiece {
        OverlapPiece {
            t0,
            t1,
            mu: [0.0; 4],
            emission: [[0.0; 4]; 3],
            classes: [[0.0; 4]; MAX_CLASSES],
            emits: false,
        }
    }

    /// Add one volume's values: its cubics (from where this piece starts), its `σ_t` and
    /// its scattering class, if its medium scatters.
    pub fn add(&mut self, cubics: &PieceCubics, sigma_t: f64, class: Option<usize>) {
        let mu: [f64; 4] = cubics.density.map(|a| sigma_t * a);
        for (s, a) in self.mu.iter_mut().zip(mu) {
            *s += a;
        }
        if let Some(k) = class {
            for (s, a) in self.classes[k].iter_mut().zip(mu) {
                *s += a;
            }
        }
        if cubics.emits {
            for (channel, add) in self.emission.iter_mut().zip(&cubics.emission) {
                for (s, a) in channel.iter_mut().zip(add) {
                    *s += a;
                }
            }
            self.emits = true;
        }
    }

    /// `μ_t(u) ≥ 0`.
    #[inline]
    fn mu_at(&self, u: f64) -> f64 {
        poly::eval(&self.mu, u).max(0.0)
    }
}

impl Piece for OverlapPiece {
    #[inline]
    fn t0(&self) -> f64 {
        self.t0
    }

    #[inline]
    fn t1(&self) -> f64 {
        self.t1
    }

    #[inline]
    fn constant(&self) -> Option<Segment> {
        None
    }

    #[inline]
    fn optical_depth(&self, sigma_t: f64, u: f64) -> f64 {
        sigma_t * poly::integral(&self.mu, u)
    }

    #[inline]
    fn optical_depths<const N: usize>(&self, sigma_t: f64, u: [f64; N]) -> [f64; N] {
        u.map(|u| self.optical_depth(sigma_t, u))
    }

    #[inline]
    fn free_path(&self, sigma_t: f64, od: f64) -> f64 {
        poly::solve_integral(&self.mu, self.length(), od / sigma_t)
    }

    /// `μ_t(u)`: the unit medium's density.
    #[inline]
    fn density_at(&self, u: f64) -> f32 {
        self.mu_at(u) as f32
    }

    /// Several volumes report no one source: 0.
    #[inline]
    fn source_at(&self, _u: f64) -> f32 {
        0.0
    }

    /// 1: the collision's classes carry the albedo ([`Piece::class_weights`]).
    #[inline]
    fn albedo_at(&self, _u: f64) -> f32 {
        1.0
    }

    #[inline]
    fn emission_at(&self, _le: &impl Fn(f32, f32) -> Rgb, u: f64) -> [f64; 3] {
        if !self.emits {
            return [0.0; 3];
        }
        self.emission.map(|c| poly::eval(&c, u))
    }

    #[inline]
    fn emission_integral(&self, _le: &impl Fn(f32, f32) -> Rgb, u: f64) -> [f64; 3] {
        if !self.emits {
            return [0.0; 3];
        }
        self.emission.map(|c| poly::integral(&c, u))
    }

    #[inline]
    fn may_emit(&self) -> bool {
        self.emits
    }

    fn cubics(&self, _le: &impl Fn(f32, f32) -> Rgb, offset: f64) -> PieceCubics {
        let shift = |a: &[f64; 4]| shifted(a, offset);
        PieceCubics {
            density: shift(&self.mu),
            emission: self.emission.map(|c| shift(&c)),
            emits: self.emits,
        }
    }

    /// `w_k = μ_k(u)/μ_t(u)`, each in `[0, 1]` (all 0 where `μ_t` is).
    fn class_weights(&self, u: f64) -> Option<ClassWeights> {
        let mu = self.mu_at(u);
        Some(ClassWeights(std::array::from_fn(|k| {
            let m = poly::eval(&self.classes[k], u).max(0.0);
            if mu > 0.0 {
                (m / mu).min(1.0) as f32
            } else {
                0.0
            }
        })))
    }
}

/// The cubic `a` re-expanded about `offset`: `b(v) = a(v + offset)` (Taylor's coefficients).
fn shifted(a: &[f64; 4], offset: f64) -> [f64; 4] {
    if offset == 0.0 {
        return *a;
    }
    let o = offset;
    [poly::eval(a, o), a[1] + o * (2.0 * a[2] + o * 3.0 * a[3]), a[2] + 3.0 * a[3] * o, a[3]]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shifted_cubic_is_the_same_polynomial() {
        let a = [0.3, -1.2, 2.5, 0.7];
        for o in [0.0, 0.25, 1.5] {
            let b = shifted(&a, o);
            for v in [0.0, 0.1, 0.9, 2.0] {
                let (x, y) = (poly::eval(&a, v + o), poly::eval(&b, v));
                assert!((x - y).abs() < 1e-12 * (1.0 + x.abs()), "{o} {v}: {x} vs {y}");
            }
        }
    }

    #[test]
    fn sums_coefficients_and_splits_classes() {
        let c = |rho: f64, le: f64| PieceCubics {
            density: [rho, 0.0, 0.0, 0.0],
            emission: [[le, 0.0, 0.0, 0.0]; 3],
            emits: le > 0.0,
        };
        let mut p = OverlapPiece::empty(1.0, 3.0);
        p.add(&c(2.0, 0.0), 0.5, Some(0)); // μ 1
        p.add(&c(1.0, 4.0), 3.0, Some(1)); // μ 3, emits 4
        p.add(&c(1.0, 0.0), 1.0, None); // μ 1, absorbs only
        assert_eq!(p.density_at(0.5), 5.0);
        assert_eq!(p.optical_depth(1.0, 2.0), 10.0);
        assert_eq!(p.emission_integral(&|_, _| Rgb::ZERO, 2.0), [8.0; 3]);
        assert!((p.free_path(1.0, 5.0) - 1.0).abs() < 1e-12);
        let w = p.class_weights(1.0).unwrap().0;
        assert_eq!(&w[..3], &[0.2, 0.6, 0.0]);
        assert!(p.constant().is_none());
    }
}
