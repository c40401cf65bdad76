//! Forced collisions on the expected-value walk (ray-march): every ray that meets the
//! medium may scatter, not only the few whose free path ends in it.
//!
//! **Why.** In thin media most camera rays cross without colliding (on the Mantaflow
//! explosions at their own density all but a few per cent). With an analog free path the
//! scattered light of a pixel then rests on whether a handful of its samples collide: at
//! one or two samples per pixel that Bernoulli trial is most of the image's error, and
//! splitting a collision into several paths does not touch it.
//!
//! **The estimator.** An analog walk collides with probability `P = 1 − τ(d)`, at a point
//! of density `μ_t(t) τ(t)` on `[0, d]`. The ray-march walk visits every piece `i` of the
//! ray anyway (until its roulette ends it) and knows each piece's *collision mass*
//! `m_i = τ̂(a_i) (1 − e^{−x_i})`, `x_i` its optical depth and `τ̂` the walk's
//! roulette-weighted transmittance, so that `W = Σ m_i` is an unbiased estimate of `P`.
//! The forced walk then collides with probability `q = min(1, K W)` ([`BOOST`] `K`), at a
//! point of density `μ_t τ̂ / W` (the analog law, conditioned on a collision), and weights
//! it `W / q`:
//!
//! `E[(W/q) g(t) · 1{collide}] = Σ_i m_i E_i[g] = ∫₀^d μ_t τ g dt`,
//!
//! the analog expectation of any `g` of the collision, so everything that follows a
//! collision stays unbiased. `K = 1` draws as many collisions as the analog walk; a large
//! `K` collides wherever `W > 1/K`, while rays that barely touch the medium keep
//! colliding rarely (a path costs the same whatever its weight). Roulette at the path's
//! first vertex compares `β` with the path's start, so a collision weighted well below 1
//! is played for there, after its first light sample.
//!
//! **One number, inverted.** `u < q` collides; then `u W / q` is located on the running
//! sum of the masses, and its place within piece `i` gives the optical depth
//! `y = −ln(1 − v (1 − e^{−x_i}))` into the piece, solved for the distance by the piece's
//! own free-path rule. This map is monotone in `u`, so Sobol points stratify the collision
//! as they stratify an analog free path. (A streaming reservoir choice, with no pieces
//! kept, has a larger error: its rescaled number is not stratified.)
//!
//! **Split paths start apart** ([`ForcedCollision::draw_split`]). When `n` paths leave
//! the camera collision (`--split`), each draws its own first vertex from the same
//! masses: with `v = u/q` (uniform given a collision), path `k` takes the place
//! `v_k = (k + v)/n` on the running sum, one stratum of the collision law each. Every
//! `v_k` is uniform on its stratum, so `(1/n) Σ_k g(t_k)` has the expectation of
//! `g(t)` under the analog law, and each path keeps the weight `W/q`: unbiased as one
//! shared vertex was, but the paths no longer share where along the ray they scatter,
//! which a shared vertex left to the pixel's samples alone. On the demo scene this
//! lowers the error for the cost of `n` inversions per camera collision
//! (docs/BENCHMARKS.md, "Forced camera collisions").
//! With one path (`n = 1`) its vertex is the walk's own collision, bit for bit.

use super::coefficients::Medium;
use super::free_path::{analog_collision, DistanceSample};
pub use plume_scene::sets::Collision;
use plume_volume::field::Piece;

/// `K`: a forced walk collides with probability `min(1, K W)`. On the three Mantaflow
/// explosions at albedo 0.8, 4 and 16 give the same error at every budget, and 4 costs
/// less CPU (docs/BENCHMARKS.md, "Forced camera collisions").
pub const BOOST: f64 = 4.0;

/// The split paths of a forced camera collision: how many, and where their first vertices
/// go (one stratum of the collision law each; "Split paths start apart").
#[derive(Debug)]
pub(crate) struct SplitFirsts<'a> {
    /// Paths leaving the collision.
    pub(crate) paths: u32,
    /// Their first vertices, appended by the walk.
    pub(crate) firsts: &'a mut Vec<Forced>,
}

/// The pieces of a forced walk with positive collision mass, and the running sum of their
/// masses.
pub(crate) struct ForcedCollision<P> {
    /// Each piece, its optical depth, the optical depth at its start, and the running mass
    /// through it.
    pieces: Vec<(P, f64, f64, f64)>,
    total: f64,
}

/// A collision the forced walk drew.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Forced {
    pub event: DistanceSample,
    /// Optical depth from the ray's origin to the collision.
    pub optical_depth: f64,
    /// `W / q`.
    pub weight: f64,
}

impl<P: Piece> ForcedCollision<P> {
    pub(crate) fn new() -> Self {
        ForcedCollision { pieces: Vec::with_capacity(32), total: 0.0 }
    }

    /// A piece of optical depth `x`, starting at optical depth `od` with roulette-weighted
    /// transmittance `tau`.
    #[inline]
    pub(crate) fn push(&mut self, piece: &P, x: f64, od: f64, tau: f64) {
        let mass = tau * -(-x).exp_m1();
        if mass > 0.0 {
            self.total += mass;
            self.pieces.push((*piece, x, od, self.total));
        }
    }

    /// The probability `q` of a collision, and whether the walk's number `u` collides.
    fn collides(&self, u: f64) -> (f64, bool) {
        let q = (BOOST * self.total).min(1.0);
        // Written so that a NaN number collides nowhere
        (q, !self.pieces.is_empty() && u.partial_cmp(&q) == Some(std::cmp::Ordering::Less))
    }

    /// The collision for the walk's number `u ∈ [0, 1)`, if it collides.
    pub(crate) fn draw(&self, medium: &Medium, u: f64) -> Option<Forced> {
        let (q, collides) = self.collides(u);
        collides.then(|| self.at(medium, u / q, q))
    }

    /// The first vertices of `n` split paths for the walk's number `u` (module docs: path
    /// `k` at `(k + u/q)/n` of the masses), appended to `out`; nothing if it does not
    /// collide. For `n = 1`, [`ForcedCollision::draw`]'s collision.
    pub(crate) fn draw_split(&self, medium: &Medium, u: f64, n: u32, out: &mut Vec<Forced>) {
        let (q, collides) = self.collides(u);
        if collides {
            let v = u / q;
            let n_f = f64::from(n);
            out.extend((0..n).map(|k| self.at(medium, (f64::from(k) + v) / n_f, q)));
        }
    }

    /// The collision at `place ∈ [0, 1)` of the running masses, weighted `W/q`.
    fn at(&self, medium: &Medium, place: f64, q: f64) -> Forced {
        let target = place * self.total;
        let k = self.pieces.partition_point(|p| p.3 <= target).min(self.pieces.len() - 1);
        let (piece, x, od, through) = self.pieces[k];
        let before = if k == 0 { 0.0 } else { self.pieces[k - 1].3 };
        // Uniform in [0, 1) within the piece's mass (rounding can put target a hair outside)
        let v = ((target - before) / (through - before)).clamp(0.0, 1.0 - f64::EPSILON / 2.0);
        let y = -(v * (-x).exp_m1()).ln_1p();
        Forced {
            event: analog_collision(&piece, medium, y),
            optical_depth: od + y,
            weight: self.total / q,
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::medium::tracking::{track, track_split};
    use crate::medium::{Emission, Estimator};
    use plume_core::sampling::Sampler;
    use plume_synth::{explosion, ExplosionParams};
    use plume_volume::field::{Constant, Field, Ray};
    use plume_volume::trilinear::Trilinear;
    use plume_volume::Volume;

    /// The collision law needs only the density: no emission.
    fn medium(sigma_t: f64) -> Medium {
        Medium {
            sigma_t,
            albedo: plume_core::color::Rgb::splat(0.8),
            g: 0.0,
            emission: Emission::none(),
            extinction: Default::default(),
        }
    }

    /// `n` first vertices of a forced walk with number `u`, and the walk's own result.
    fn split<F: Field>(
        field: &F,
        medium: &Medium,
        ray: &Ray,
        n: u32,
        seed: u64,
        i: u64,
    ) -> (Vec<Forced>, crate::medium::TrackResult) {
        let mut firsts = Vec::new();
        let mut sampler = Sampler::new(seed, 0, i);
        let u = sampler.next_f64();
        let r = track_split(
            field,
            medium,
            ray,
            f64::INFINITY,
            Estimator::RayMarch,
            Collision::Forced,
            u,
            &mut sampler,
            SplitFirsts { paths: n, firsts: &mut firsts },
        );
        (firsts, r)
    }

    #[test]
    fn one_split_path_starts_at_the_walk_s_own_collision() {
        // Bit for bit, on a trilinear explosion (many polynomial pieces, roulette): a
        // render with one path per collision is the render before split paths started apart
        let ex = explosion(&ExplosionParams { resolution: 16, seed: 3, ..Default::default() });
        let m = medium(20.0);
        let vol = Volume::build(&ex.density, None, |v| v).unwrap();
        let field = Trilinear::new(vol);
        let ray = Ray {
            origin: DVec3::new(-3.0, 0.1, 0.05),
            direction: DVec3::new(1.0, 0.02, -0.03).normalize(),
        };
        let mut collided = 0;
        for i in 0..2000 {
            let (firsts, r) = split(&field, &m, &ray, 1, 9, i);
            let mut sampler = Sampler::new(9, 0, i);
            let u = sampler.next_f64();
            let own = track(
                &field,
                &m,
                &ray,
                f64::INFINITY,
                Estimator::RayMarch,
                Collision::Forced,
                u,
                &mut sampler,
            );
            assert_eq!(
                format!("{:?}", (r.event, r.emission, r.collision_weight)),
                format!("{:?}", (own.event, own.emission, own.collision_weight))
            );
            match own.event {
                DistanceSample::Collided { .. } => {
                    collided += 1;
                    assert_eq!(firsts.len(), 1);
                    assert_eq!(
                        format!("{:?}", (firsts[0].event, firsts[0].weight)),
                        format!("{:?}", (own.event, own.collision_weight)),
                        "walk {i}"
                    );
                }
                DistanceSample::Escaped => {
                    assert!(firsts.is_empty(), "walk {i}: a first vertex without a collision")
                }
            }
        }
        assert!(collided > 200, "only {collided} of 2000 walks collided");
    }

    #[test]
    fn split_first_vertices_have_the_analog_law_one_per_stratum() {
        // A homogeneous box of optical depth 3 (τ = 0.05, no roulette, every walk
        // collides): the weighted first vertices of 3 paths, `E[Σ_k (W/q)/3 · 1{t_k ∈ bin}]
        // = τ(a) − τ(b)` in each of 24 bins (the walk's draws are correlated, so each
        // walk's sum is one observation); |z| < 3.9 (Šidák at α = 0.01 over 24). And path
        // k lies in stratum k of the collision law: `(1 − τ(t_k))/(1 − τ(d)) ∈ [k/3, (k+1)/3]`
        let field =
            Constant { lo: DVec3::ZERO, hi: DVec3::new(2.0, 1.0, 1.0), density: 1.5, source: 1.0 };
        let m = medium(1.0);
        let ray = Ray { origin: DVec3::new(-1.0, 0.5, 0.5), direction: DVec3::X };
        let (n, walks, bins) = (3u32, 40_000u64, 24usize);
        let tau = |t: f64| (-1.5 * (t - 1.0).clamp(0.0, 2.0)).exp();
        let (mut sum, mut sum_sq) = (vec![0.0f64; bins], vec![0.0f64; bins]);
        for i in 0..walks {
            let (firsts, r) = split(&field, &m, &ray, n, 12, i);
            assert_eq!(firsts.len(), n as usize, "walk {i}: every walk collides here");
            let mut own = vec![0.0f64; bins];
            for (k, first) in firsts.iter().enumerate() {
                let DistanceSample::Collided { t, .. } = first.event else {
                    panic!("walk {i}: path {k} escaped")
                };
                assert_eq!(first.weight, r.collision_weight, "every path keeps the walk's weight");
                let place = (1.0 - tau(t)) / (1.0 - tau(3.0));
                let (lo, hi) = (k as f64 / f64::from(n), (k + 1) as f64 / f64::from(n));
                assert!(
                    place >= lo - 1e-9 && place <= hi + 1e-9,
                    "walk {i}: path {k} at {place}, outside [{lo}, {hi}]"
                );
                own[((t - 1.0) / 2.0 * bins as f64).clamp(0.0, bins as f64 - 1.0) as usize] +=
                    first.weight / f64::from(n);
            }
            for (b, w) in own.into_iter().enumerate() {
                sum[b] += w;
                sum_sq[b] += w * w;
            }
        }
        let nf = walks as f64;
        for b in 0..bins {
            let expected = tau(1.0 + 2.0 * b as f64 / bins as f64)
                - tau(1.0 + 2.0 * (b + 1) as f64 / bins as f64);
            let mean = sum[b] / nf;
            let se = ((sum_sq[b] / nf - mean * mean).max(0.0) / nf).sqrt();
            let z = (mean - expected) / se.max(1e-15);
            assert!(
                z.abs() < 3.9,
                "bin {b}: weighted mass {mean} ± {se} vs exact {expected} (z = {z:.2})"
            );
        }
    }
}
