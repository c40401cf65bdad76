//! Tests of [`super`]: Planck's law against known values and limits, the CIE integration,
//! the log-T table against the exact path, and the Cycles convention.

use super::*;

fn assert_rel(actual: f64, expected: f64, tolerance: f64, what: &str) {
    let rel = (actual / expected - 1.0).abs();
    assert!(rel <= tolerance, "{what}: {actual:e} vs {expected:e} (rel {rel:e} > {tolerance:e})");
}

/// Temperatures that must never produce NaN or ∞ (NaN is treated as 0 K).
const EDGE_TEMPERATURES: [f32; 12] =
    [0.0, 1e-3, 1.0, 100.0, 499.0, 500.0, 1e4, 1e7, 1e8, f32::MAX, f32::INFINITY, f32::NAN];

#[test]
fn planck_matches_method_range() {
    // METHOD §10.6: B(550 nm) at 500 K, 2000 K, 1e7 K.
    assert_rel(planck(550.0, 500.0), 4.5e-17, 0.02, "B(550, 500 K)");
    assert_rel(planck(550.0, 2000.0), 4.9, 0.02, "B(550, 2000 K)");
    assert_rel(planck(550.0, 1e7), 9.0e8, 0.02, "B(550, 1e7 K)");
}

#[test]
fn planck_edge_cases() {
    assert_eq!(planck(550.0, 0.0), 0.0);
    assert_eq!(planck(550.0, -300.0), 0.0);
    assert_eq!(planck(550.0, f64::NAN), 0.0);
    assert_eq!(planck(f64::NAN, 1000.0), 0.0);
    assert_eq!(planck(0.0, 1000.0), 0.0);
    // exp overflows: exactly 0, not NaN.
    assert_eq!(planck(550.0, 1e-3), 0.0);
    assert_eq!(planck(360.0, 1.0), 0.0);
    for t in [1e8, f64::from(f32::MAX)] {
        for lambda in [360.0, 550.0, 830.0] {
            let b = planck(lambda, t);
            assert!(b.is_finite() && b > 0.0, "B({lambda}, {t}) = {b}");
        }
    }
    // Rayleigh–Jeans regime, x = c₂/λT = 2.6e-11: 1/expm1(x) = 1/x − 1/2 + O(x). A naive
    // exp(x) − 1 would be off by ≈ 4e-6 relative here; expm1 is exact to rounding.
    let (lambda_m, t) = (550e-9f64, 1e15);
    let x = C2 / (lambda_m * t);
    let series = TWO_HC2 * 1e-9 / lambda_m.powi(5) * (1.0 / x - 0.5);
    assert_rel(planck(550.0, t), series, 1e-12, "Rayleigh–Jeans");
}

#[test]
fn planck_integrates_to_stefan_boltzmann() {
    // ∫₀^∞ B dλ = σT⁴/π; with METHOD's rounded constants σ comes out within 1.1e-5 of
    // Cycles' 5.670373e-8. Simpson in s = ln λ over [λ_peak/50, 2000·λ_peak]: the
    // tails beyond hold < 1e-7 of the total.
    for t in [500.0f64, 2000.0, 6500.0, 1e5, 1e7] {
        let lambda_peak_nm = 2.897771955e6 / t;
        let (s0, s1) = ((lambda_peak_nm / 50.0).ln(), (lambda_peak_nm * 2000.0).ln());
        let n = 20_000;
        let h = (s1 - s0) / n as f64;
        let integral: f64 = (0..=n)
            .map(|k| {
                let lambda = (s0 + k as f64 * h).exp();
                let weight = if k == 0 || k == n {
                    1.0
                } else if k % 2 == 1 {
                    4.0
                } else {
                    2.0
                };
                weight * planck(lambda, t) * lambda
            })
            .sum::<f64>()
            * h
            / 3.0;
        assert_rel(integral, STEFAN_BOLTZMANN * t.powi(4) / PI, 1e-4, "∫B dλ vs σT⁴/π");
    }
}

#[test]
fn cmf_table_integrals() {
    assert_eq!(CIE1931_2DEG.len() as u32, CIE1931_LAMBDA_MAX_NM - CIE1931_LAMBDA_MIN_NM + 1);
    let sums = CIE1931_2DEG
        .iter()
        .fold([0.0f64; 3], |acc, row| [acc[0] + row[0], acc[1] + row[1], acc[2] + row[2]]);
    assert!((sums[1] - 106.86).abs() < 0.05, "∫ȳ dλ = {} nm", sums[1]);
    // Equal-energy white: the three integrals agree to 0.04 %.
    assert!((sums[0] - sums[1]).abs() < 0.05 && (sums[2] - sums[1]).abs() < 0.05);
    // ȳ peaks at 1 at 555 nm.
    assert_eq!(CIE1931_2DEG[555 - 360][1], 1.0);
}

#[test]
fn fast_xyz_matches_blackbody_xyz() {
    let spectrum = PlanckCmf::new();
    for t in [100.0, 500.0, 1234.5, 2000.0, 6500.0, 3e4, 1e6, 1e8] {
        let (fast, reference) = (spectrum.xyz(t), blackbody_xyz(t));
        for k in 0..3 {
            assert_rel(fast[k], reference[k], 1e-13, "PlanckCmf vs blackbody_xyz");
        }
    }
}

#[test]
fn chromaticity_of_6504_k_on_planckian_locus() {
    let [x, y, z] = blackbody_xyz(6504.0);
    let (cx, cy) = (x / (x + y + z), y / (x + y + z));
    assert!((cx - 0.3135).abs() < 0.002 && (cy - 0.3237).abs() < 0.002, "(x, y) = ({cx}, {cy})");
}

#[test]
fn xyz_to_rec709_luminance_row() {
    // The Rec.709 luminance of M·XYZ is Y, up to the 4-digit rounding of M.
    let rgb = xyz_to_rec709([0.3, 0.7, 0.2]);
    assert!((rec709_luminance(rgb) - 0.7).abs() < 1e-4);
    assert_eq!(xyz_to_rec709([0.0, 1.0, 0.0]), [-1.5374, 1.8760, -0.2040]);
}

#[test]
fn rgb_exact_out_of_gamut_at_1000_k() {
    let c = blackbody_rgb_exact(1000.0);
    assert!(c.iter().all(|v| v.is_finite()), "{c:?}");
    assert_eq!(c[2], 0.0, "blue is out of gamut at 1000 K: {c:?}");
    assert!(c[0] > 0.0 && c[1] > 0.0, "{c:?}");
    // Unclamped blue is negative there.
    assert!(xyz_to_rec709(blackbody_xyz(1000.0))[2] < 0.0);
    // In gamut at 2000 K.
    assert!(blackbody_rgb_exact(2000.0).iter().all(|&v| v > 0.0));
}

#[test]
fn luminance_grows_steeply_and_monotonically() {
    let y = |t: f64| blackbody_xyz(t)[1];
    let ratio = y(2000.0) / y(1000.0);
    assert!(ratio > 1e5, "Y(2000 K)/Y(1000 K) = {ratio:e}");
    let mut previous = 0.0;
    for k in 0..=400 {
        let t = 500.0 * (2e4f64).powf(f64::from(k) / 400.0);
        let yt = y(t);
        assert!(yt > previous, "Y not increasing at {t} K");
        previous = yt;
    }
    // The table too, on a finer grid.
    let table = blackbody_table();
    let mut previous = 0.0;
    for k in 0..=20_000 {
        let t = 500.0 * 2e4f32.powf(k as f32 / 20_000.0);
        let yt = table.luminance(t);
        assert!(yt >= previous, "table Y not increasing at {t} K");
        previous = yt;
    }
}

/// Table vs [`blackbody_rgb_exact`] over 500 K … 1e7 K at the quarter, half and
/// three-quarter points of every table interval (linear interpolation is worst at
/// the midpoints). Measured (2048 nodes): luminance 2.0e-4, colour 2.0e-4 of the
/// largest channel, both at the cold end.
#[test]
fn table_matches_exact() {
    let table = blackbody_table();
    let (mut max_luminance_error, mut max_rgb_error) = (0.0f64, 0.0f64);
    let (mut worst_luminance_t, mut worst_rgb_t) = (0.0, 0.0);
    for k in 0..TABLE_NODES - 1 {
        for f in [0.25, 0.5, 0.75] {
            let t = (table.ln_t_min + (k as f64 + f) / table.nodes_per_ln_t).exp() as f32;
            if !(500.0..=1e7).contains(&t) {
                continue;
            }
            // Compare at the f32 temperature the table actually sees.
            let xyz = blackbody_xyz(f64::from(t));
            let exact = xyz_to_rec709(xyz).map(|c| c.max(0.0));
            let luminance_error = (table.luminance(t) / xyz[1] - 1.0).abs();
            let approx = table.rgb(t).to_f64();
            let largest = exact.iter().fold(0.0f64, |m, &c| m.max(c));
            let rgb_error =
                (0..3).map(|c| (approx[c] - exact[c]).abs()).fold(0.0, f64::max) / largest;
            if luminance_error > max_luminance_error {
                (max_luminance_error, worst_luminance_t) = (luminance_error, t);
            }
            if rgb_error > max_rgb_error {
                (max_rgb_error, worst_rgb_t) = (rgb_error, t);
            }
        }
    }
    eprintln!(
        "table max relative error over 500 K..1e7 K: luminance {max_luminance_error:.2e} \
         (at {worst_luminance_t} K), rgb {max_rgb_error:.2e} of largest channel \
         (at {worst_rgb_t} K)"
    );
    assert!(max_luminance_error < 1e-3, "luminance error {max_luminance_error:e}");
    assert!(max_rgb_error < 1e-3, "rgb error {max_rgb_error:e}");
}

#[test]
fn table_exact_at_nodes_and_zero_below() {
    let table = blackbody_table();
    assert!(table.rgb(99.0).is_black());
    assert_eq!(table.luminance(99.0), 0.0);
    // At 2000 K (no clamping) the table agrees with the exact colour.
    let exact = blackbody_rgb_exact(2000.0);
    let approx = table.rgb(2000.0).to_f64();
    for c in 0..3 {
        assert_rel(approx[c], exact[c], 1e-3, "C(2000 K)");
    }
    // Above the table, T is clamped.
    assert_eq!(table.rgb(1e9), table.rgb(TABLE_MAX_KELVIN));
    assert_eq!(table.luminance(f32::INFINITY), table.luminance(TABLE_MAX_KELVIN));
}

#[test]
fn chromaticity_has_unit_luminance_and_floor() {
    let table = blackbody_table();
    for t in [800.0, 3000.0, 1e6] {
        let luminance = table.chromaticity(t).luminance();
        assert!((luminance - 1.0).abs() < 1e-5, "Ĉ({t} K) luminance {luminance}");
    }
    let floor = table.chromaticity(800.0);
    for t in [0.0, 1.0, 300.0, 799.9, f32::NAN, -5.0] {
        assert_eq!(table.chromaticity(t), floor, "Ĉ({t} K) should be Ĉ(800 K)");
    }
    // At 800 K green and blue are out of gamut: pure red of luminance 1.
    assert_eq!(floor.0[1], 0.0);
    assert_eq!(floor.0[2], 0.0);
    assert!((floor.0[0] - 1.0 / 0.2126).abs() < 1e-5);
    // Above ≈ 1900 K nothing is clamped and Ĉ = C/Y (to the rounding of M₇₀₉).
    let c = blackbody_rgb_exact(3000.0);
    let y = blackbody_xyz(3000.0)[1];
    let chromaticity = table.chromaticity(3000.0).to_f64();
    for k in 0..3 {
        assert!((chromaticity[k] - c[k] / y).abs() < 1e-3, "Ĉ(3000 K) {chromaticity:?}");
    }
}

#[test]
fn cycles_blackbody_convention() {
    let expected_scale = STEFAN_BOLTZMANN / PI * 1e-6 * 1e12;
    let chromaticity = blackbody_table().cycles_chromaticity(1000.0);
    let actual = cycles_blackbody(1000.0);
    // (To 1e-6 of the largest channel: the uniform-T table interpolates the ln-T one)
    let largest = chromaticity.0.iter().map(|v| v.abs()).fold(0.0, f32::max);
    for c in 0..3 {
        let expected = expected_scale * f64::from(chromaticity.0[c]);
        assert!(
            (f64::from(actual.0[c]) - expected).abs() <= 1e-6 * expected_scale * f64::from(largest),
            "{actual:?}"
        );
    }
    // Unclamped, like Cycles' own fit (values from Cycles' svm_math_blackbody_color_rec709),
    // and constant outside 800 K … 12000 K.
    let table = blackbody_table();
    for (t, cycles) in
        [(800.0f32, [5.413f64, -0.203, -0.082]), (12000.0, [0.82659, 0.99452, 1.56659])]
    {
        let c = table.cycles_chromaticity(t);
        for k in 0..3 {
            assert!(
                (f64::from(c.0[k]) - cycles[k]).abs() < 0.01 * cycles[k].abs().max(0.5),
                "{t} K: {c:?} vs {cycles:?}"
            );
        }
    }
    assert_eq!(table.cycles_chromaticity(500.0), table.cycles_chromaticity(800.0));
    assert_eq!(table.cycles_chromaticity(5e4), table.cycles_chromaticity(12000.0));
    // No cutoff: 300 K still emits ≈ 1.5e-4 (METHOD §2).
    assert!((cycles_blackbody(300.0).luminance() - 1.46e-4).abs() < 0.01e-4);
    assert!(cycles_blackbody(0.0).is_black());
    assert!(cycles_blackbody(-10.0).is_black());
    assert!(cycles_blackbody(f32::NAN).is_black());
}

#[test]
fn cycles_uniform_table_agrees_with_the_ln_t_table() {
    // cycles_blackbody's uniform-in-T table against the ln-T table it is built from, over
    // 1 K steps and between nodes, and held constant outside 800 … 12000 K
    let table = blackbody_table();
    let mut worst = 0.0f64;
    for k in 0..=120_000 {
        let t = 500.0 + f64::from(k) * 0.1013;
        let t32 = t as f32;
        let exact = table.cycles_chromaticity(t32).to_f64();
        let scale = STEFAN_BOLTZMANN / PI * 1e-6 * f64::from(t32).powi(4);
        let got = cycles_blackbody(t32).to_f64();
        for c in 0..3 {
            let e = exact[c] * scale;
            worst = worst.max(
                (got[c] - e).abs() / (exact.iter().map(|v| v.abs()).fold(0.0, f64::max) * scale),
            );
        }
    }
    assert!(
        worst < 2e-6,
        "uniform-T table deviates by {worst:e} (relative to the largest channel)"
    );
}

#[test]
fn uniform_rgb_table_agrees_with_the_ln_t_table() {
    // rgb's T-uniform segments against the ln-T table they are built from, 500 K to
    // 20 000 K in 0.1 K steps (between nodes); above, rgb is the ln-T table itself
    let table = blackbody_table();
    let mut worst = 0.0f64;
    for k in 0..=195_000 {
        let t = (500.0 + f64::from(k) * 0.1) as f32;
        let got = table.rgb(t).to_f64();
        let want = table.rgb_ln_t(t).to_f64();
        let scale = want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for c in 0..3 {
            worst = worst.max((got[c] - want[c]).abs() / scale);
        }
    }
    println!("uniform-T rgb: largest deviation {worst:e} of the largest channel");
    assert!(worst < 1e-5, "uniform-T rgb deviates by {worst:e} of the largest channel");
    assert!(table.rgb(99.9).is_black());
    assert_eq!(table.rgb(25_000.0), table.rgb_ln_t(25_000.0));
}

#[test]
fn no_nan_or_inf_anywhere() {
    let table = blackbody_table();
    for t in EDGE_TEMPERATURES {
        // The exact functions are specified for finite T.
        if t.is_finite() || t.is_nan() {
            let t64 = f64::from(t);
            assert!(planck(550.0, t64).is_finite(), "planck at {t}");
            assert!(blackbody_xyz(t64).iter().all(|v| v.is_finite()), "xyz at {t}");
            assert!(blackbody_rgb_exact(t64).iter().all(|v| v.is_finite()), "rgb at {t}");
        }
        assert!(table.rgb(t).is_finite(), "table rgb at {t}");
        assert!(table.luminance(t).is_finite(), "table luminance at {t}");
        assert!(table.chromaticity(t).is_finite(), "chromaticity at {t}");
        assert!(cycles_blackbody(t).is_finite(), "cycles at {t}");
    }
    // NaN is treated as 0 K.
    assert!(planck(550.0, f64::NAN) == 0.0 && blackbody_xyz(f64::NAN) == [0.0; 3]);
    assert!(table.rgb(f32::NAN).is_black() && table.luminance(f32::NAN) == 0.0);
}

/// Prints the cross-check values quoted in reports; run with `--nocapture`.
#[test]
fn print_reference_colours() {
    let table = blackbody_table();
    for t in [800.0f32, 1000.0, 1500.0, 2000.0, 3000.0, 6500.0, 12000.0] {
        let exact = blackbody_rgb_exact(f64::from(t));
        eprintln!(
            "T = {t} K: C exact = [{:.6e}, {:.6e}, {:.6e}], table = {:?}, Y = {:.6e}, Ĉ = {:?}",
            exact[0],
            exact[1],
            exact[2],
            table.rgb(t).0,
            blackbody_xyz(f64::from(t))[1],
            table.chromaticity(t).0
        );
    }
}

#[test]
fn table_build_is_independent_of_thread_count() {
    let (one, three) =
        (BlackbodyTable::build_with_threads(1), BlackbodyTable::build_with_threads(3));
    let bits = |table: &BlackbodyTable| {
        let ln_y: Vec<u32> = table.ln_y.iter().map(|v| v.to_bits()).collect();
        let rgb: Vec<[u32; 3]> = table.rgb_over_y.iter().map(|c| c.map(f32::to_bits)).collect();
        (ln_y, rgb)
    };
    assert!(bits(&one) == bits(&three), "table differs between 1 and 3 build threads");
}

/// Table build time. Not a timed assertion (STYLE §8); run with
/// `cargo test --release --lib table_build_time -- --ignored --nocapture`.
#[test]
#[ignore = "benchmark; prints timing only"]
fn table_build_time() {
    /// CPU time of this thread, s (wall time is inflated on a shared machine).
    fn thread_cpu_seconds() -> f64 {
        let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
        // SAFETY: `ts` is a valid, writable timespec.
        let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
        assert_eq!(rc, 0);
        ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
    }
    let runs = 50;
    let (wall, cpu) = (std::time::Instant::now(), thread_cpu_seconds());
    let mut checksum = 0.0f32;
    for _ in 0..runs {
        let table = BlackbodyTable::build();
        checksum += table.ln_y[TABLE_NODES / 2];
    }
    let cpu_ms = (thread_cpu_seconds() - cpu) * 1e3 / f64::from(runs);
    let wall_ms = wall.elapsed().as_secs_f64() * 1e3 / f64::from(runs);
    eprintln!(
        "BlackbodyTable::build ({TABLE_NODES} nodes): {wall_ms:.2} ms wall, {cpu_ms:.2} ms \
         thread CPU per build (checksum {checksum})"
    );
}
