//! Closed-form and statistical checks of regular tracking and the emission estimators
//! (METHOD.md §3, §4, §11.1, §11.4) on analytic fields. Fixed seeds; Monte Carlo means are
//! compared with k·σ tolerances using the sample standard error.

use crate::common;

use common::{grid_emission, mean_stderr_from_sums};
use glam::DVec3;
use plume_core::color::Rgb;
use plume_core::sampling::Sampler;
use plume_engine::medium::tracking::{phi, sample_exponential};
use plume_engine::medium::{
    track, Collision, Convention, DistanceSample, Emission, EmissionKind, Estimator, Medium,
    TemperatureMap,
};
use plume_volume::field::{Constant, Ray, Segment, Strip};
use plume_volume::Field;

fn medium(sigma_t: f64, convention: Convention) -> Medium {
    Medium {
        sigma_t,
        albedo: plume_core::color::Rgb::splat(0.0),
        g: 0.0,
        emission: grid_emission(convention),
        extinction: Default::default(),
    }
}

const ALL: [Estimator; 4] =
    [Estimator::Point, Estimator::Line, Estimator::RayMarch, Estimator::Blend { kappa: 4.0 }];

/// Mean and standard error of the red channel of F over `n` independent samples.
fn mc_emission<F: Field>(
    field: &F,
    m: &Medium,
    ray: &Ray,
    est: Estimator,
    n: u64,
    seed: u64,
) -> (f64, f64, f64) {
    let (mut s, mut s2, mut tr) = (0.0, 0.0, 0.0);
    for i in 0..n {
        let mut sampler = Sampler::new(seed, 0, i);
        let u = sampler.next_f64();
        let r = track(field, m, ray, f64::INFINITY, est, Collision::Skip, u, &mut sampler);
        s += r.emission[0];
        s2 += r.emission[0] * r.emission[0];
        tr += r.transmittance;
    }
    let (mean, se) = mean_stderr_from_sums(s, s2, n);
    (mean, se, tr / n as f64)
}

/// Exact `∫ τ L_e ds` and `τ(d)` along a ray, from its segments (METHOD §4 expected value).
fn exact<F: Field<Piece = Segment>>(field: &F, m: &Medium, ray: &Ray) -> (f64, f64) {
    let (mut od, mut f) = (0.0f64, 0.0f64);
    for s in field.segments(ray, 0.0, f64::INFINITY) {
        let mu = m.mu_t(s.density);
        let x = mu * s.length();
        f += (-od).exp() * f64::from(m.emission.le(s.density, s.source).0[0]) * s.length() * phi(x);
        od += x;
    }
    (f, (-od).exp())
}

fn box_ray() -> Ray {
    Ray { origin: DVec3::new(-1.0, 0.5, 0.5), direction: DVec3::X }
}

#[test]
fn homogeneous_box_matches_closed_form_for_every_estimator() {
    // L = L_e (1 − e^{−μd}) / μ with d = 2, for thin, medium and dense boxes.
    let le = 3.0f32;
    for &(density, sigma_t) in &[(0.05f32, 1.0f64), (1.0, 1.0), (5.0, 2.0)] {
        let field =
            Constant { lo: DVec3::ZERO, hi: DVec3::new(2.0, 1.0, 1.0), density, source: le };
        for conv in [Convention::Cycles, Convention::Physical] {
            let m = medium(sigma_t, conv);
            let mu = sigma_t * f64::from(density);
            let le_eff = f64::from(m.emission.le(density, le).0[0]);
            let closed = le_eff * (1.0 - (-mu * 2.0).exp()) / mu;
            let (ev, tau) = exact(&field, &m, &box_ray());
            assert!(
                (ev - closed).abs() <= 1e-12 * closed,
                "expected-value closed form {ev} vs {closed}"
            );
            assert!((tau - (-mu * 2.0).exp()).abs() < 1e-15);
            for est in ALL {
                let (mean, se, tr) = mc_emission(&field, &m, &box_ray(), est, 40_000, 7);
                // Relative floor: in the dense box every sample collides (escape odds e^-20), so the
                // sample variance of point is 0 while its mean differs from closed by e^-20.
                let tol = 4.0 * se + 1e-6 * closed;
                assert!(
                    (mean - closed).abs() <= tol,
                    "{est:?} ρ={density}: {mean} vs {closed} (4σ = {tol})"
                );
                assert!(
                    (tr - tau).abs() <= 4.0 * (tau * (1.0 - tau) / 40_000.0).sqrt() + 1e-3,
                    "{est:?} transmittance {tr} vs {tau}"
                );
            }
        }
    }
}

#[test]
fn thin_limit_is_emission_times_length() {
    // μ_t → 0: L → L_e d for every estimator but point (which needs collisions).
    let field =
        Constant { lo: DVec3::ZERO, hi: DVec3::new(2.0, 1.0, 1.0), density: 1e-9, source: 2.0 };
    let m = medium(1.0, Convention::Cycles);
    for est in [Estimator::Line, Estimator::RayMarch] {
        let (mean, _, _) = mc_emission(&field, &m, &box_ray(), est, 100, 1);
        assert!((mean - 4.0).abs() < 1e-6, "{est:?}: {mean}");
    }
}

#[test]
fn free_path_samples_invert_optical_depth() {
    // A linear ramp of densities (plus empty cells): OD(t) at the sampled collision equals
    // E = −ln(1 − u) to float precision.
    let mut cells: Vec<(f32, f32)> = (0..32).map(|i| (i as f32 * 0.1, 0.0)).collect();
    cells[5] = (0.0, 0.0);
    cells[17] = (0.0, 0.0);
    let field = Strip { lo: DVec3::ZERO, hi: DVec3::new(8.0, 1.0, 1.0), cells: cells.clone() };
    let m = medium(0.7, Convention::Physical);
    let ray = Ray { origin: DVec3::new(-0.5, 0.5, 0.5), direction: DVec3::X };
    let width = 8.0 / 32.0;
    let od_at = |t: f64| -> f64 {
        let x = t - 0.5; // distance into the strip
        let mut od = 0.0;
        for (i, c) in cells.iter().enumerate() {
            let a = i as f64 * width;
            let b = a + width;
            od += 0.7 * f64::from(c.0) * (x.min(b) - a).max(0.0);
        }
        od
    };
    let total = od_at(1e9);
    let mut sampler = Sampler::new(3, 0, 0);
    let mut collided = 0;
    for i in 0..2000 {
        let u = (i as f64 + 0.5) / 2000.0;
        let r = track(
            &field,
            &m,
            &ray,
            f64::INFINITY,
            Estimator::Line,
            Collision::Skip,
            u,
            &mut sampler,
        );
        let e = sample_exponential(u);
        match r.event {
            DistanceSample::Collided { t, density, .. } => {
                collided += 1;
                assert!(e < total);
                assert!((od_at(t) - e).abs() < 1e-9 * (1.0 + e), "u={u}: OD(t)={} E={e}", od_at(t));
                assert!(density > 0.0, "never collides in a zero-density cell");
            }
            DistanceSample::Escaped => {
                assert!(e >= total - 1e-12, "escaped with E={e} < OD={total}")
            }
        }
    }
    assert!(collided > 1000);
}

#[test]
fn linear_ramp_transmittance_is_exact() {
    // Densities 0, 0.1, …, 3.1 over 8 m: OD = σ_t Σ ρ_i w = 0.7 · 49.6 · 0.25.
    let cells: Vec<(f32, f32)> = (0..32).map(|i| (i as f32 * 0.1, 0.0)).collect();
    let field = Strip { lo: DVec3::ZERO, hi: DVec3::new(8.0, 1.0, 1.0), cells };
    let m = medium(0.7, Convention::Physical);
    let ray = Ray { origin: DVec3::new(-0.5, 0.5, 0.5), direction: DVec3::X };
    let expected_od = 0.7 * (0..32).map(|i| f64::from(i as f32 * 0.1)).sum::<f64>() * 0.25;
    let mut sampler = Sampler::new(0, 0, 0);
    let r = track(
        &field,
        &m,
        &ray,
        f64::INFINITY,
        Estimator::RayMarch,
        Collision::Skip,
        0.5,
        &mut sampler,
    );
    // OD ≈ 8.7: τ = 1.7e-4 is below the roulette threshold, so the estimate is either 0 or
    // τ·(1/q); its mean over many runs is τ.
    let mut mean = 0.0;
    let n = 20_000;
    for i in 0..n {
        let mut s = Sampler::new(1, 0, i);
        mean += track(
            &field,
            &m,
            &ray,
            f64::INFINITY,
            Estimator::RayMarch,
            Collision::Skip,
            0.5,
            &mut s,
        )
        .transmittance;
    }
    mean /= n as f64;
    let tau = (-expected_od).exp();
    assert!((mean - tau).abs() < 0.1 * tau, "{mean} vs {tau}");
    assert!(r.transmittance == 0.0 || (r.transmittance - 1e-2).abs() < 1e-2);
    // A thinner ramp stays above the threshold: exact.
    let m = medium(0.07, Convention::Physical);
    let r = track(
        &field,
        &m,
        &ray,
        f64::INFINITY,
        Estimator::RayMarch,
        Collision::Skip,
        0.5,
        &mut sampler,
    );
    assert!((r.transmittance - (-expected_od / 10.0).exp()).abs() < 1e-12);
}

/// A random strip: random densities (some zero, some huge), random emission (some zero).
fn random_strip(seed: u64, scale: f32) -> Strip {
    let mut s = Sampler::new(seed, 99, 0);
    let cells = (0..64)
        .map(|_| {
            let d = if s.next_f64() < 0.2 { 0.0 } else { s.next_f32() * scale };
            let e = if s.next_f64() < 0.3 { 0.0 } else { s.next_f32() * 5.0 };
            (d, e)
        })
        .collect();
    Strip { lo: DVec3::ZERO, hi: DVec3::new(8.0, 1.0, 1.0), cells }
}

#[test]
fn all_estimators_agree_in_expectation_on_random_strips() {
    // METHOD §11.4: point, line, blend and expected value vs Σ τ(a_i) L_e,i Δ_i φ(x_i),
    // thin, medium and dense strips, with empty cells and zero-density cells.
    for (k, scale) in [0.05f32, 1.0, 20.0].into_iter().enumerate() {
        for seed in 0..3 {
            let field = random_strip(seed * 10 + k as u64, scale);
            // Physical: emission ∝ density, so point is unbiased too.
            let m = medium(1.0, Convention::Physical);
            let ray = Ray { origin: DVec3::new(-0.25, 0.5, 0.5), direction: DVec3::X };
            let (reference, _) = exact(&field, &m, &ray);
            for est in ALL {
                let (mean, se, _) = mc_emission(&field, &m, &ray, est, 20_000, 100 + seed);
                assert!(
                    (mean - reference).abs() <= 4.5 * se + 1e-9 * reference,
                    "{est:?} scale={scale} seed={seed}: {mean} vs {reference} (se {se})"
                );
            }
        }
    }
}

#[test]
fn line_integration_collects_emission_where_density_is_zero() {
    // Cycles convention: emission in an empty cell. Line and ray-march see it; this is the
    // case where the point estimator is undefined (METHOD §4).
    let field = Strip {
        lo: DVec3::ZERO,
        hi: DVec3::new(2.0, 1.0, 1.0),
        cells: vec![(0.0, 3.0), (1.0, 0.0)],
    };
    let m = medium(1.0, Convention::Cycles);
    let ray = Ray { origin: DVec3::new(-0.5, 0.5, 0.5), direction: DVec3::X };
    let (reference, _) = exact(&field, &m, &ray);
    assert!((reference - 3.0).abs() < 1e-12);
    for est in [Estimator::Line, Estimator::RayMarch, Estimator::Blend { kappa: 4.0 }] {
        let (mean, se, _) = mc_emission(&field, &m, &ray, est, 5_000, 5);
        assert!((mean - reference).abs() <= 4.0 * se + 1e-9, "{est:?}: {mean}");
    }
}

#[test]
fn extreme_densities_and_temperatures_stay_finite() {
    let ray = box_ray();
    for density_scale in [1e-6, 1.0, 1e6] {
        for temperature in [0.0f32, 1.0, 499.0, 500.0, 3000.0, 1e5, 1e7] {
            for conv in [Convention::Physical, Convention::Cycles] {
                let emission = Emission {
                    kind: EmissionKind::Blackbody,
                    convention: conv,
                    scale: 1.0,
                    color: Rgb::ONE,
                    temperature_map: TemperatureMap::Kelvin,
                    cutoff_kelvin: 500.0,
                };
                let source = emission.map_source(temperature);
                let field = Constant {
                    lo: DVec3::ZERO,
                    hi: DVec3::new(2.0, 1.0, 1.0),
                    density: 1.0,
                    source,
                };
                let m = Medium {
                    sigma_t: density_scale,
                    albedo: plume_core::color::Rgb::splat(0.0),
                    g: 0.0,
                    emission,
                    extinction: Default::default(),
                };
                for est in ALL {
                    for i in 0..50 {
                        let mut s = Sampler::new(9, 1, i);
                        let u = s.next_f64();
                        let r =
                            track(&field, &m, &ray, f64::INFINITY, est, Collision::Skip, u, &mut s);
                        // Cycles' blackbody colour is not gamut-clamped: below ~1900 K its blue
                        // channel is negative, as in Cycles. Physical emission never is.
                        let nonneg =
                            conv == Convention::Cycles || r.emission.iter().all(|v| *v >= 0.0);
                        assert!(
                            r.emission.iter().all(|v| v.is_finite()) && nonneg,
                            "{est:?} σ={density_scale} T={temperature}: {:?}",
                            r.emission
                        );
                        assert!(r.transmittance.is_finite());
                    }
                }
            }
        }
    }
}

/// The point estimator scores only at collisions, so with Cycles' convention (emission
/// where density is 0) it misses light: a render warns, naming the flag that chose it,
/// whether every segment uses it or only the camera segment.
#[test]
fn the_point_estimator_warns_where_it_misses_emission_without_density() {
    let d = common::tmpdir("estimators", "point-warning");
    let ex = common::explosion(&d, 16, None);
    let out = d.join("x.exr");
    let cycles = [
        "--convention",
        "cycles",
        "--emission",
        "grid",
        "--emission-grid",
        "temperature",
        "--width",
        "8",
        "--height",
        "6",
        "--spp",
        "1",
    ];
    for (flags, named) in [
        (&["--estimator", "point"][..], "--estimator point"),
        (&["--camera-estimator", "point"][..], "--camera-estimator point"),
        (&[][..], ""),
    ] {
        let mut args = vec!["render", common::s(&ex), "-o", common::s(&out), "--overwrite"];
        args.extend(cycles);
        args.extend(flags);
        let o = common::plume(&args);
        let err = common::stderr(&o);
        assert!(o.status.success(), "{err}");
        if named.is_empty() {
            assert!(!err.contains("scores only at collisions"), "{flags:?}: {err}");
        } else {
            assert!(
                err.contains(&format!("{named} scores only at collisions")),
                "{flags:?}: {err}"
            );
        }
    }
}
