//! Sampling primitives of `plume_core::sampling`: every sample/pdf pair the phase function and
//! the discrete distributions behind NEE and FNEE rely on.
//!
//! - Henyey–Greenstein: chi² against the analytic cosine CDF, normalisation, extremes.
//! - Alias table: chi² against the weights, zero weights, pmf sum.
//! - The Sobol sampler (`--sampler sobol`): values in [0, 1), stratification of the first
//!   2^k samples (one per elementary interval), decorrelation of segments, sets and
//!   pixels, and the `random` kind as the hashed stream (`Sampler::new`) bit for bit. The
//!   chi² tests draw from the i.i.d. hashed stream (`common::rng`): their counts assume
//!   independent draws.
//!
//! Fixed seeds; these chi² tests and those of `light_sampling.rs` are one family of
//! [`TESTS`] tests at family-wise false-failure rate [`ALPHA`] (Šidák).
//! `cargo test --test sampling -- --nocapture` prints p-values.

use crate::common;

use std::f64::consts::PI;

use common::{
    chi2_test, direction_bin, frame, hash, rng, SAMPLING_ALPHA as ALPHA, SAMPLING_TESTS as TESTS,
};
use glam::{DVec3, IVec3};
use plume_core::sampling::alias::AliasTable;
use plume_core::sampling::phase::{hg_pdf, sample_hg};
use plume_core::sampling::{Dim, Sampler, SamplerKind};

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
            assert!(
                (s.pdf - hg_pdf(g, c)).abs() <= 1e-9 * s.pdf,
                "g={g}: pdf {} vs {}",
                s.pdf,
                hg_pdf(g, c)
            );
            observed
                [direction_bin(s.direction, direction, basis, -1.0, nc, nphi).expect("c ≥ -1")] +=
                1.0;
        }
        let expected: Vec<f64> = (0..nc * nphi)
            .map(|b| {
                let ic = b / nphi;
                let (c0, c1) =
                    (-1.0 + 2.0 * ic as f64 / nc as f64, -1.0 + 2.0 * (ic + 1) as f64 / nc as f64);
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
            assert!(
                (part - cdf).abs() < 1e-6 * cdf.max(1e-3),
                "g={g} [{c0},{c1}]: {part} vs {cdf}"
            );
        }
    }
}

#[test]
fn hg_extremes_are_finite_and_unit() {
    let one_minus_eps = 1.0 - f64::EPSILON / 2.0;
    for direction in [DVec3::Z, -DVec3::Z, DVec3::new(1.0, 0.0, -0.0), DVec3::new(0.6, -0.8, 0.0)] {
        for g in [-1.0, -0.999, 0.999, 1.0] {
            for u in [
                [0.0, 0.0],
                [0.0, one_minus_eps],
                [one_minus_eps, 0.0],
                [one_minus_eps, one_minus_eps],
            ] {
                let s = sample_hg(g, direction, u);
                assert!(
                    s.direction.is_finite() && (s.direction.length() - 1.0).abs() < 1e-12,
                    "g={g} u={u:?}: {s:?}"
                );
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

// ---------------------------------------------------------------------------------------
// The Sobol sampler

/// Every named draw of one segment block, in a fixed order.
fn block_values(s: &mut Sampler) -> Vec<f64> {
    let mut v = s.get_2d(Dim::Direction).to_vec();
    v.push(s.get_1d(Dim::FreePath));
    v.push(s.get_1d(Dim::OnePoint));
    v.push(s.get_1d(Dim::LightChoice));
    v.extend(s.get_3d(Dim::LightPosition));
    v.push(s.get_1d(Dim::Roulette));
    v
}

/// The sampler of sample `sample` of pixel `pixel`, at the forward block of `depth`.
fn sobol_at(seed: u64, pixel: u64, sample: u64, depth: u32) -> Sampler {
    let mut s = Sampler::with_kind(SamplerKind::Sobol, seed, pixel, sample);
    s.start_vertex(depth);
    s
}

#[test]
fn sobol_values_lie_in_the_unit_interval_and_are_pure_functions_of_their_key() {
    for sample in (0..300).chain([65_535, 65_536, 1 << 20]) {
        for pixel in [0, 1, 12_345] {
            for depth in [0, 1, 7, 1000] {
                let mut s = sobol_at(3, pixel, sample, depth);
                let v = block_values(&mut s);
                assert!(v.iter().all(|u| (0.0..1.0).contains(u)), "{v:?}");
                // Asking again, or in another order, gives the same numbers
                let mut again = sobol_at(3, pixel, sample, depth);
                assert_eq!(again.get_1d(Dim::Roulette), v[8]);
                assert_eq!(block_values(&mut again), v);
                let mut light = Sampler::with_kind(SamplerKind::Sobol, 3, pixel, sample);
                light.start_light_segment(depth);
                assert_ne!(block_values(&mut light), v, "the light segment has its own block");
            }
        }
    }
}

/// Points `(x, y)` of `n = 2^m` samples form a (0, m, 2)-net: every elementary interval
/// `[a 2^-i, (a+1) 2^-i) × [b 2^-(m-i), (b+1) 2^-(m-i))` holds exactly one point.
fn assert_net(points: &[[f64; 2]], what: &str) {
    let m = points.len().trailing_zeros();
    assert_eq!(points.len(), 1 << m);
    for i in 0..=m {
        let mut seen = vec![false; points.len()];
        for p in points {
            let cell = ((p[0] * f64::from(1u32 << i)) as usize) << (m - i)
                | (p[1] * f64::from(1u32 << (m - i))) as usize;
            assert!(
                !seen[cell],
                "{what}: two of {} points in one {}×{} interval",
                points.len(),
                1u32 << i,
                1u32 << (m - i)
            );
            seen[cell] = true;
        }
    }
}

#[test]
fn sobol_direction_of_any_segment_is_a_net_over_the_first_power_of_two_samples() {
    // Owen scrambling keeps the (0, m, 2)-net property of Sobol dimensions 0 and 1, and
    // the index shuffle maps an aligned run of 2^m indices to another such run
    for (pixel, depth) in [(0u64, 0u32), (77, 0), (77, 3), (5000, 64)] {
        for m in [1, 4, 8, 12] {
            for start in [0, 1u64 << m] {
                let points: Vec<[f64; 2]> = (start..start + (1 << m))
                    .map(|i| sobol_at(9, pixel, i, depth).get_2d(Dim::Direction))
                    .collect();
                assert_net(&points, &format!("pixel {pixel} depth {depth} samples {start}+2^{m}"));
            }
        }
    }
    // Each 1-D draw alone is stratified: one of the first 2^m samples per 2^-m interval
    for (k, dim) in
        [Dim::FreePath, Dim::OnePoint, Dim::LightChoice, Dim::Roulette].into_iter().enumerate()
    {
        let m = 10;
        let mut seen = vec![false; 1 << m];
        for i in 0..1u64 << m {
            let mut s = Sampler::with_kind(SamplerKind::Sobol, 1, 42, i);
            s.start_light_segment(k as u32);
            let cell = (s.get_1d(dim) * f64::from(1u32 << m)) as usize;
            assert!(!seen[cell], "{dim:?}: two samples in one interval");
            seen[cell] = true;
        }
    }
}

fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let cov: f64 = a.iter().zip(b).map(|(x, y)| (x - ma) * (y - mb)).sum();
    let va: f64 = a.iter().map(|x| (x - ma) * (x - ma)).sum();
    let vb: f64 = b.iter().map(|y| (y - mb) * (y - mb)).sum();
    cov / (va * vb).sqrt()
}

#[test]
fn sobol_segments_sets_and_pixels_are_decorrelated() {
    // Pearson correlation over n samples: |r| < 4/√n for independent draws (a false
    // failure about once in 15 000 per pair)
    let n = 4096u64;
    let bound = 4.0 / (n as f64).sqrt();
    let draws = |pixel: u64, light: bool, depth: u32, dim: Dim, lane: usize| -> Vec<f64> {
        (0..n)
            .map(|i| {
                let mut s = Sampler::with_kind(SamplerKind::Sobol, 11, pixel, i);
                if light {
                    s.start_light_segment(depth);
                } else {
                    s.start_vertex(depth);
                }
                match dim {
                    Dim::Direction => s.get_2d(dim)[lane],
                    Dim::LightPosition => s.get_3d(dim)[lane],
                    _ => s.get_1d(dim),
                }
            })
            .collect()
    };
    let free_path = draws(3, false, 0, Dim::FreePath, 0);
    let pairs = [
        ("free path, vertex 0 / vertex 1", draws(3, false, 1, Dim::FreePath, 0)),
        ("free path, forward / light segment", draws(3, true, 0, Dim::FreePath, 0)),
        ("free path / roulette (another set)", draws(3, false, 0, Dim::Roulette, 0)),
        ("free path / light choice (another set)", draws(3, false, 0, Dim::LightChoice, 0)),
        ("free path, pixel 3 / pixel 4", draws(4, false, 0, Dim::FreePath, 0)),
        ("free path / direction x", draws(3, false, 0, Dim::Direction, 0)),
        ("free path / direction y", draws(3, false, 0, Dim::Direction, 1)),
    ];
    for (what, other) in &pairs {
        let r = correlation(&free_path, other);
        assert!(r.abs() < bound, "{what}: correlation {r:.4} (bound {bound:.4})");
    }
    let (x, y) = (draws(3, false, 2, Dim::Direction, 0), draws(3, false, 2, Dim::Direction, 1));
    assert!(correlation(&x, &y).abs() < bound, "direction x / y");
    let (p0, p2) =
        (draws(8, true, 1, Dim::LightPosition, 0), draws(8, true, 1, Dim::LightPosition, 2));
    assert!(correlation(&p0, &p2).abs() < bound, "light position lanes");
}

#[test]
fn random_kind_is_the_old_stream_in_the_order_drawn() {
    for (seed, pixel, sample) in [(0u64, 0u64, 0u64), (7, 12_345, 99)] {
        let mut old = Sampler::new(seed, pixel, sample);
        let expected: Vec<f64> = (0..9).map(|_| old.next_f64()).collect();
        let mut s = Sampler::with_kind(SamplerKind::Random, seed, pixel, sample);
        s.start_light_segment(4); // blocks mean nothing to the random stream
        assert_eq!(block_values(&mut s), expected);
        assert_eq!(s.kind(), SamplerKind::Random);
    }
    // The hashed stream of a Sobol sampler is the same stream (for variable-count draws)
    let (mut a, mut b) = (Sampler::with_kind(SamplerKind::Sobol, 2, 3, 4), Sampler::new(2, 3, 4));
    let _ = a.get_1d(Dim::FreePath);
    assert_eq!(a.next_f64(), b.next_f64());
}

#[test]
fn split_paths_of_a_pixel_form_one_sobol_sequence() {
    // n paths per collision over N samples: the n·N split paths' directions at a vertex
    // form a (0, m, 2)-net, as N·n samples of one sequence would; a split that reused the
    // sample's own index would put n points in each cell
    for (n, samples) in [(2u32, 64u64), (4, 16), (8, 128), (8, 8192)] {
        for (pixel, depth) in [(0u64, 1u32), (77, 3)] {
            let points: Vec<[f64; 2]> = (0..samples)
                .flat_map(|i| (0..n).map(move |k| (i, k)))
                .map(|(i, k)| {
                    let mut s = Sampler::with_kind(SamplerKind::Sobol, 9, pixel, i).split(k, n);
                    s.start_vertex(depth);
                    s.get_2d(Dim::Direction)
                })
                .collect();
            assert_net(
                &points,
                &format!("split {n} × {samples} samples, pixel {pixel} depth {depth}"),
            );
        }
    }
    // Past 2^16 split indices the next run of the sequence takes over with its own scramble
    let a = Sampler::with_kind(SamplerKind::Sobol, 9, 5, 8191).split(7, 8);
    let b = Sampler::with_kind(SamplerKind::Sobol, 9, 5, 8192).split(0, 8);
    let c = Sampler::with_kind(SamplerKind::Sobol, 9, 5, 0).split(0, 8);
    let first = |s: &Sampler| {
        let mut s = s.clone();
        s.start_vertex(1);
        block_values(&mut s)
    };
    assert!(first(&a).iter().chain(&first(&b)).all(|u| (0.0..1.0).contains(u)));
    assert_ne!(first(&b), first(&c), "index 65 536 is not index 0 again");
}

#[test]
fn one_split_is_the_sampler_itself_and_splits_have_their_own_streams() {
    for kind in [SamplerKind::Sobol, SamplerKind::Random] {
        let s = Sampler::with_kind(kind, 4, 10, 3);
        let (mut whole, mut one) = (s.clone(), s.split(0, 1));
        whole.start_vertex(2);
        one.start_vertex(2);
        assert_eq!(block_values(&mut one), block_values(&mut whole));
        assert_eq!(one.next_f64(), whole.next_f64());
        // Split paths draw other numbers than each other and than the unsplit path, in
        // their named draws and in their hashed streams
        let mut seen: Vec<(Vec<f64>, f64)> = Vec::new();
        for k in 0..4 {
            let mut p = s.split(k, 4);
            p.start_vertex(2);
            let v = (block_values(&mut p), p.next_f64());
            assert!(
                seen.iter().all(|o| o.0 != v.0 && o.1 != v.1),
                "{kind:?}: split {k} repeats another's numbers"
            );
            let mut unsplit = s.clone();
            unsplit.start_vertex(2);
            assert_ne!(v.0, block_values(&mut unsplit));
            seen.push(v);
        }
        // Pure: the same split again gives the same numbers
        let (mut p, mut q) = (s.split(2, 4), s.split(2, 4));
        assert_eq!(p.next_f64(), q.next_f64());
    }
}
