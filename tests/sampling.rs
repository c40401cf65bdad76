//! Sampling primitives of `plume::sampling`: every sample/pdf pair the phase function and
//! the discrete distributions behind NEE and FNEE rely on.
//!
//! - Henyey–Greenstein: chi² against the analytic cosine CDF, normalisation, extremes.
//! - Alias table: chi² against the weights, zero weights, pmf sum.
//!
//! Fixed seeds; these chi² tests and those of `light_sampling.rs` are one family of
//! [`TESTS`] tests at family-wise false-failure rate [`ALPHA`] (Šidák).
//! `cargo test --test sampling -- --nocapture` prints p-values.

mod common;

use std::f64::consts::PI;

use common::{chi2_test, direction_bin, frame, hash, rng, SAMPLING_ALPHA as ALPHA, SAMPLING_TESTS as TESTS};
use glam::{DVec3, IVec3};
use plume::sampling::alias::AliasTable;
use plume::sampling::phase::{hg_pdf, sample_hg};

// ---------------------------------------------------------------------------------------
// Henyey–Greenstein

/// Analytic CDF of HG in cos θ: `F(c) = (1−g²)/(2g) [(1+g²−2gc)^{-1/2} − 1/(1+g)]`.
fn hg_cdf(g: f64, c: f64) -> f64 {
    if g == 0.0 {
        0.5 * (1.0 + c)
    } else {
        (1.0 - g * g) / (2.0 * g) * ((1.0 + g * g - 2.0 * g * c).powf(-0.5) - 1.0 / (1.0 + g))
    }
}

#[test]
fn hg_sampling_matches_its_pdf_chi2() {
    let direction = DVec3::new(0.3, -0.5, 0.8).normalize();
    let basis = frame(direction);
    let (nc, nphi, n) = (40, 10, 200_000);
    for (k, g) in [-0.9, -0.5, 0.0, 0.5, 0.9].into_iter().enumerate() {
        let mut sampler = rng(100 + k as u64);
        let mut observed = vec![0.0; nc * nphi];
        for _ in 0..n {
            let s = sample_hg(g, direction, [sampler.next_f64(), sampler.next_f64()]);
            assert_eq!(s.weight, 1.0);
            let c = s.direction.dot(direction);
            assert!((s.pdf - hg_pdf(g, c)).abs() <= 1e-9 * s.pdf, "g={g}: pdf {} vs {}", s.pdf, hg_pdf(g, c));
            observed[direction_bin(s.direction, direction, basis, -1.0, nc, nphi).expect("c ≥ -1")] += 1.0;
        }
        let expected: Vec<f64> = (0..nc * nphi)
            .map(|b| {
                let ic = b / nphi;
                let (c0, c1) = (-1.0 + 2.0 * ic as f64 / nc as f64, -1.0 + 2.0 * (ic + 1) as f64 / nc as f64);
                n as f64 * (hg_cdf(g, c1) - hg_cdf(g, c0)) / nphi as f64
            })
            .collect();
        chi2_test(&format!("hg_g{g}"), &observed, &expected, ALPHA, TESTS);
    }
}

/// `2π ∫ p dc` on a mesh graded towards both ends of `[−1, 1]` (HG peaks at ±1).
fn integrate_hg(g: f64, a: f64, b: f64) -> f64 {
    // c = a + (b − a) v³ on each half, so the mesh is fine where the peak is
    let n = 200_000;
    let mut sum = 0.0;
    for (from, to) in [(a, 0.5 * (a + b)), (b, 0.5 * (a + b))] {
        for i in 0..n {
            let (v0, v1) = (i as f64 / n as f64, (i + 1) as f64 / n as f64);
            let (c0, c1) = (from + (to - from) * v0.powi(3), from + (to - from) * v1.powi(3));
            sum += 2.0 * PI * hg_pdf(g, 0.5 * (c0 + c1)) * (c1 - c0).abs();
        }
    }
    sum
}

#[test]
fn hg_pdf_integrates_to_one_and_matches_the_cdf() {
    for g in [-0.999, -0.9, -0.5, -1e-4, 0.0, 0.5, 0.9, 0.999] {
        let total = integrate_hg(g, -1.0, 1.0);
        assert!((total - 1.0).abs() < 1e-6, "g={g}: ∫p dω = {total}");
        // The analytic CDF used for the chi² expectations is the integral of hg_pdf
        for (c0, c1) in [(-1.0, -0.5), (-0.3, 0.2), (0.6, 0.95), (0.95, 1.0)] {
            let part = integrate_hg(g, c0, c1);
            let cdf = hg_cdf(g, c1) - hg_cdf(g, c0);
            assert!((part - cdf).abs() < 1e-6 * cdf.max(1e-3), "g={g} [{c0},{c1}]: {part} vs {cdf}");
        }
    }
}

#[test]
fn hg_extremes_are_finite_and_unit() {
    let one_minus_eps = 1.0 - f64::EPSILON / 2.0;
    for direction in [DVec3::Z, -DVec3::Z, DVec3::new(1.0, 0.0, -0.0), DVec3::new(0.6, -0.8, 0.0)] {
        for g in [-1.0, -0.999, 0.999, 1.0] {
            for u in [[0.0, 0.0], [0.0, one_minus_eps], [one_minus_eps, 0.0], [one_minus_eps, one_minus_eps]] {
                let s = sample_hg(g, direction, u);
                assert!(s.direction.is_finite() && (s.direction.length() - 1.0).abs() < 1e-12, "g={g} u={u:?}: {s:?}");
                assert!(s.pdf > 0.0 && !s.pdf.is_nan() && s.weight == 1.0, "g={g} u={u:?}: {s:?}");
            }
        }
    }
}

// ---------------------------------------------------------------------------------------
// Alias table

#[test]
fn alias_table_chi2_zero_weights_and_pmf_sum() {
    let weights: Vec<f64> = (0..64u32)
        .map(|i| match i % 5 {
            0 => 0.0,
            1 => 1e-3,
            _ => f64::from(hash(IVec3::new(i as i32, 0, 0), 9) % 1000) + 1.0,
        })
        .collect();
    let table = AliasTable::new(&weights).expect("positive sum");
    let total: f64 = weights.iter().sum();
    let pmf_sum: f64 = (0..table.len()).map(|i| table.pmf(i)).sum();
    assert!((pmf_sum - 1.0).abs() < 1e-14, "Σ pmf = {pmf_sum}");
    let n = 1_000_000;
    let mut observed = vec![0.0; weights.len()];
    let mut sampler = rng(7);
    for _ in 0..n {
        let s = table.sample(sampler.next_f64());
        assert_eq!(s.pmf.to_bits(), table.pmf(s.index).to_bits());
        observed[s.index] += 1.0;
    }
    for (i, &w) in weights.iter().enumerate() {
        if w == 0.0 {
            assert_eq!(observed[i], 0.0, "zero weight {i} sampled");
            assert_eq!(table.pmf(i), 0.0);
        }
    }
    let expected: Vec<f64> = weights.iter().map(|w| n as f64 * w / total).collect();
    chi2_test("alias", &observed, &expected, ALPHA, TESTS);
}
