//! `plume bench`: the error metrics against hand-computed values, the numerical-extremes
//! sweep at small sizes, and the comparison pipeline end to end (library and binary); and
//! the equal-CPU rules of the peer comparison with Cycles (`scripts/budget.py`).
//! Timings are never asserted (STYLE.md §8); only structure, finiteness and means.

use crate::common;

use common::{data, exr_pixels, plume, s, tmpdir};
use glam::IVec3;
use plume::bench::compare::{compare, make_reference, read_reference, CompareConfig};
use plume::bench::extremes::{self, box_grid, ExtremesConfig};
use plume::bench::metrics::{bias, mean_rgb, relmse, rmse, Errors, RELMSE_TRIM};
use plume::bench::spec::{bench_shot, load, parse_methods};

fn px(v: &[[f32; 3]]) -> Vec<[f32; 4]> {
    v.iter().map(|p| [p[0], p[1], p[2], 1.0]).collect()
}

#[test]
fn metrics_match_hand_computed_values() {
    // Two pixels: differences (0, 1, 2) and (0, 0, −2)
    let x = px(&[[1.0, 2.0, 3.0], [0.0, 0.0, 0.0]]);
    let r = px(&[[1.0, 1.0, 1.0], [0.0, 0.0, 2.0]]);
    // Σ d² = 0 + 1 + 4 + 0 + 0 + 4 = 9 over 6 values
    assert!((rmse(&x, &r) - 1.5f64.sqrt()).abs() < 1e-15);
    // ε = 1: pixel 0: (0/2 + 1/2 + 4/2)/3 = 2.5/3; pixel 1: (0/1 + 0/1 + 4/5)/3 = 0.8/3
    assert!((relmse(&x, &r, 1.0, 0.0) - (2.5 / 3.0 + 0.8 / 3.0) / 2.0).abs() < 1e-15);
    // With half the pixels trimmed, the larger (pixel 0) goes
    assert!((relmse(&x, &r, 1.0, 0.5) - 0.8 / 3.0).abs() < 1e-15);
    // mean(x) = 6/6, mean(r) = 5/6
    assert!((bias(&x, &r) - 1.0 / 6.0).abs() < 1e-15);
    assert!((mean_rgb(&r) - 5.0 / 6.0).abs() < 1e-15);
    assert_eq!(rmse(&r, &r), 0.0);
    assert_eq!(relmse(&r, &r, 1e-2, RELMSE_TRIM), 0.0);
    // Alpha is ignored
    let mut y = x.clone();
    y[0][3] = 123.0;
    assert_eq!(Errors::of(&x, &r, 1e-2), Errors::of(&y, &r, 1e-2));
}

#[test]
fn relmse_trims_the_top_tenth_of_a_percent() {
    // 1000 pixels off by 10 % (relMSE 0.01 with ε = 0), one firefly of 1000
    let r = vec![[1.0f32, 1.0, 1.0, 1.0]; 1000];
    let mut x = vec![[1.1f32, 1.1, 1.1, 1.0]; 1000];
    x[17] = [1000.0; 4];
    let per_pixel = (1.1f32 as f64 - 1.0).powi(2);
    // ⌊0.001 · 1000⌋ = 1 pixel dropped: the firefly
    assert!((relmse(&x, &r, 0.0, RELMSE_TRIM) - per_pixel).abs() < 1e-12);
    // Untrimmed it dominates: (999 · 0.01 + 999²) / 1000
    let untrimmed = (999.0 * per_pixel + 999.0f64.powi(2)) / 1000.0;
    assert!((relmse(&x, &r, 0.0, 0.0) - untrimmed).abs() < 1e-9 * untrimmed);
    // 999 pixels: ⌊0.999⌋ = 0 dropped
    assert!(relmse(&x[..999], &r[..999], 0.0, RELMSE_TRIM) > 900.0);
    // ε keeps black reference pixels finite: (0.5² / (0 + 0.01)) = 25
    let black = px(&[[0.0, 0.0, 0.0]]);
    let grey = px(&[[0.5, 0.5, 0.5]]);
    assert!((relmse(&grey, &black, 1e-2, 0.0) - 25.0).abs() < 1e-12);
}

#[test]
fn extremes_sweep_passes_at_small_size() {
    let cfg = ExtremesConfig { box_voxels: 8, explosion_resolution: 16, size: 21, spp: 8 };
    let report = extremes::run(&cfg).unwrap();
    let failed: Vec<_> = report.rows.iter().filter(|r| !r.pass).collect();
    assert!(failed.is_empty(), "{}", report.table());
    assert!(report.rows.iter().all(|r| r.finite));
    let count = |sweep: &str| report.rows.iter().filter(|r| r.sweep == sweep).count();
    assert_eq!(count("density"), 13 * 5, "σ_t 1e-6 … 1e6, four estimators + scattering");
    assert_eq!(count("temperature"), 6 * 3);
    assert_eq!(count("voxel size"), 9 * 3);
    assert_eq!(count("invalid voxels"), 1 + 4);
    assert_eq!(count("cost"), 5, "four presets with their tracking, and null tracking");
    // The cost sweep: 13 density scales per series, its work counted; at the dense end
    // paths scatter (more walks per sample) while a walk costs no more than 2×
    assert_eq!(report.cost.len(), 13 * 5);
    for series in report.cost.chunks(13) {
        let (thin, dense) = (&series[0], &series[12]);
        assert!(thin.density_scale == 1e-6 && (dense.density_scale - 1e6).abs() < 1e-6);
        assert!(dense.walks_per_sample() > 4.0 * thin.walks_per_sample(), "{dense:?}");
        assert!(dense.collisions > 0 && thin.walks >= thin.samples);
        let work: Vec<f64> = series.iter().map(|p| p.work_per_walk()).collect();
        if series[0].tracking != "null" {
            assert!(extremes::growth(&work) <= extremes::MAX_GROWTH, "{work:?}");
        }
    }
    assert!(report.cost.iter().any(|p| p.tentative_points > 0), "null collisions counted");
    // The closed forms span the extremes: 1e-6 … 1 for density, up to 1e7 K
    let rm = |case: &str| {
        report
            .rows
            .iter()
            .find(|r| r.case == case && r.method == "ray-march")
            .unwrap()
            .expected
            .unwrap()
    };
    assert!((rm("σ_t = 1e6") - 1e-6).abs() < 1e-12);
    assert!((rm("σ_t = 1e-6") - 1.0).abs() < 1e-6);
    assert_eq!(rm("T = 300.0 K"), 0.0);
    assert!(rm("T = 1.000e7 K") > 1e10);
}

#[test]
fn invalid_voxel_counts_are_exact() {
    // 512 voxels, 4 of each kind in density
    let g = box_grid("density", 8, 0.5, |p| match (p.x, p.y) {
        (0, 0..=3) => f32::NAN,
        (1, 0..=3) => f32::INFINITY,
        (2, 0..=3) => f32::NEG_INFINITY,
        (3, 0..=3) => -1e-30,
        _ => 1.0,
    });
    let v = plume_volume::Volume::build(&g, None, |v| v).unwrap();
    assert_eq!(v.report.density_clamped, 4 * 4 * 8);
    assert_eq!(v.voxel(IVec3::new(0, 0, 0)).density, 0.0);
    assert_eq!(v.voxel(IVec3::new(5, 5, 5)).density, 1.0);
}

#[test]
fn compare_measures_every_method_and_writes_all_outputs() {
    let dir = tmpdir("bench-test", "lib");
    let keys = "[medium]\nalbedo = 0.5\n[camera]\nwidth = 24\nheight = 18\n[render]\nthreads = 2\n[integrator]\nproxy_resolution = 8";
    let shot = plume_scene::file::with_keys(&bench_shot("explosion:16"), keys).unwrap();
    let mut scene = load(shot, vec![keys.into()], &dir).unwrap();
    let reference = make_reference(&mut scene, 1.0, &|_| {}).unwrap();
    assert_eq!(reference.method, "line-fnee", "the scene scatters");
    assert!(reference.spp >= 2 && reference.noise_rmse.unwrap() > 0.0);
    let cfg = CompareConfig {
        methods: parse_methods("point-nee,line-fnee@8,line+none,blend+fnee", 4.0).unwrap(),
        cpu_seconds: 0.2,
        spp: None,
        runs: 2,
        epsilon: 1e-2,
        curve_points: 3,
        adaptive: true,
    };
    let report = compare(&mut scene, &reference, &cfg, &|_| {}).unwrap();
    assert_eq!(report.methods.len(), 4);
    // The cost of each target error, uniform and adaptive (a series of halving thresholds
    // ending with the first render that spends the budget)
    let table = report.target_table();
    for m in &report.methods {
        assert_eq!(m.to_target.len(), 3, "{}", m.method);
        assert_eq!(m.adaptive_to_target.len(), 3, "{}", m.method);
        assert!(m.to_target.iter().all(|t| t.cpu_seconds.is_some_and(|c| c > 0.0)));
        let a = &m.adaptive;
        assert!(!a.is_empty() && a.len() <= 8, "{}: {} adaptive renders", m.method, a.len());
        assert!(
            a[0].threshold == 0.1 && a.windows(2).all(|w| w[1].threshold == w[0].threshold / 2.0)
        );
        // Each render gives its own estimate over the measured pixels
        assert!(
            a.iter().all(|p| p.estimated_rel_rmse.is_some_and(|e| e > 0.0)),
            "{}: {a:?}",
            m.method
        );
        let adaptive = report.adaptive_table();
        assert!(adaptive.contains(&format!("| {} | 0.1 |", m.method)), "{adaptive}");
        assert!(
            a[..a.len() - 1].iter().all(|p| p.point.cpu_seconds < 0.2),
            "only the last spends it"
        );
        assert!(a.iter().all(|p| p.point.rel_rmse > 0.0 && p.mean_spp >= 16.0));
        assert!(table.contains(&format!("| {} | adaptive |", m.method)), "{table}");
    }
    assert!(report.equal_spp.is_power_of_two());
    for m in &report.methods {
        assert_eq!(m.curve.len(), 3);
        assert_eq!(m.equal_time.rmse.n, 2, "{}: two runs", m.method);
        assert!(m.equal_time.cpu_seconds.mean >= 0.2, "{}: the budget is spent", m.method);
        assert!(m.equal_time.spp.mean >= m.curve[0].spp.mean);
        assert!(m.equal_spp.spp.mean == report.equal_spp as f64);
        for v in [
            m.equal_time.rmse.mean,
            m.equal_time.relmse.mean,
            m.equal_time.bias.mean,
            m.equal_spp.rmse.mean,
        ] {
            assert!(v.is_finite(), "{}: {v}", m.method);
        }
        assert!(
            m.equal_time.rmse.mean > 0.0
                && m.peak_rss_bytes > 0
                && m.samples_per_cpu_second.mean > 0.0
        );
        assert_eq!(m.image.len(), 24 * 18);
        // Unbiased methods: the image mean is near the reference's (loose: few samples)
        assert!(
            m.equal_time.bias.mean.abs() < 0.5 * report.reference_mean,
            "{}: bias {}",
            m.method,
            m.equal_time.bias.mean
        );
    }
    assert_eq!(report.methods[1].proxy_resolution, Some(8));
    let files = report.write(&dir.join("out"), "t", true).unwrap();
    for f in &files {
        assert!(std::fs::metadata(f).unwrap().len() > 100, "{}", f.display());
    }
    let csv = std::fs::read_to_string(&files[0]).unwrap();
    assert_eq!(
        csv.lines().count(),
        1 + 4 * (2 + 3),
        "header + per method: equal-time, equal-spp, 3 curve points"
    );
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&files[1]).unwrap()).unwrap();
    assert_eq!(json["methods"].as_array().unwrap().len(), 4);
    for png in &files[2..] {
        let dec = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(png).unwrap()));
        let r = dec.read_info().unwrap();
        assert!(r.info().width > 100 && r.info().height > 50, "{}", png.display());
    }
    // A given reference reads back to the same pixels
    let exr = dir.join("ref.exr");
    plume::output::write_exr(&exr, 24, 18, &reference.pixels, &[]).unwrap();
    let back = read_reference(&exr, &scene).unwrap();
    assert_eq!(back.pixels, reference.pixels);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn compare_command_runs_end_to_end_and_refuses_bad_flags() {
    let dir = tmpdir("bench-test", "cli");
    let work = dir.join("work");
    let out = dir.join("out");
    let o = plume(&[
        "bench",
        "compare",
        "explosion:16",
        "--methods",
        "ray-march,line+none",
        "--time",
        "0.1",
        "--runs",
        "2",
        "--make-reference",
        "--reference-time",
        "0.4",
        "-o",
        s(&out),
        "--name",
        "e",
        "--work-dir",
        s(&work),
        "--",
        "--width",
        "16",
        "--height",
        "12",
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    assert!(
        stderr.contains("expected-value estimator"),
        "emission-only scenes get a ray-march reference: {stderr}"
    );
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("Equal CPU time")
            && stdout.contains("Equal spp")
            && stdout.contains("line+none"),
        "{stdout}"
    );
    for f in ["e.csv", "e.json", "e-error.png", "e-crops.png"] {
        assert!(out.join(f).exists(), "{f}");
    }
    // No reference
    let o = plume(&["bench", "compare", "explosion:16", "--work-dir", s(&work)]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--make-reference"));
    // Bad method, bad render flag
    let o = plume(&[
        "bench",
        "compare",
        "explosion:16",
        "--make-reference",
        "--methods",
        "line+sun",
        "--work-dir",
        s(&work),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("line+sun"));
    let o = plume(&[
        "bench",
        "compare",
        "explosion:16",
        "--make-reference",
        "--work-dir",
        s(&work),
        "--",
        "--albedo",
        "2",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn render_warns_with_the_exact_count_of_negative_voxels() {
    let dir = tmpdir("bench-test", "warn");
    // Density: 2 negative columns of 8×8 (−2 and −1e-30); temperature: 1 negative column
    let d = box_grid("density", 8, 0.25, |p| match p.x {
        0 => -2.0,
        1 => -1e-30,
        _ => 1.0,
    });
    let t = box_grid("temperature", 8, 0.25, |p| if p.x == 2 { -300.0 } else { 3000.0 });
    let file = dir.join("neg.vdb");
    plume::vdb::write_float_grids(&file, &[&d, &t]).unwrap();
    let exr = dir.join("o.exr");
    let o = plume(&[
        "render",
        s(&file),
        "-o",
        s(&exr),
        "--spp",
        "2",
        "--width",
        "16",
        "--height",
        "12",
        "-q",
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    assert!(
        stderr.contains("128 density voxels were NaN, infinite or negative and were set to 0"),
        "{stderr}"
    );
    assert!(
        stderr
            .contains("64 emission-source voxels were NaN, infinite or negative and were set to 0"),
        "{stderr}"
    );
    let px = exr_pixels(&exr);
    assert!(px.iter().flatten().all(|v| v.is_finite()));
    assert!(px.iter().any(|p| p[0] > 0.0));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn non_finite_voxels_in_a_file_are_clamped_and_counted_or_refused_by_name() {
    // The volume builder clamps NaN/±inf (tested above, in memory); the VDB reader
    // currently refuses such files as corrupt before the builder sees them. Either way the
    // user gets no NaN image: a warning with the exact count, or exit 3 naming the file.
    let dir = tmpdir("bench-test", "nonfinite");
    let d = box_grid("density", 8, 0.25, |p| match p.x {
        0 => f32::NAN,
        1 => f32::INFINITY,
        2 => f32::NEG_INFINITY,
        _ => 1.0,
    });
    let file = dir.join("nan.vdb");
    plume::vdb::write_float_grids(&file, &[&d]).unwrap();
    let exr = dir.join("o.exr");
    let o = plume(&[
        "render",
        s(&file),
        "-o",
        s(&exr),
        "--spp",
        "2",
        "--width",
        "16",
        "--height",
        "12",
        "-q",
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    match o.status.code() {
        Some(0) => {
            assert!(
                stderr.contains("192 density voxels were NaN, infinite or negative"),
                "{stderr}"
            );
            assert!(exr_pixels(&exr).iter().flatten().all(|v| v.is_finite()));
        }
        Some(3) => {
            assert!(stderr.contains("nan.vdb") && stderr.contains("192"), "{stderr}");
            assert!(!exr.exists());
        }
        other => panic!("exit {other:?}: {stderr}"),
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn interpolation_bench_runs_at_a_tiny_size_with_sane_figures() {
    let dir = tmpdir("bench-test", "interpolation");
    let (json, png) = (dir.join("i.json"), dir.join("closeup.png"));
    let data = data("");
    #[rustfmt::skip]
    let o = plume(&[
        "bench", "interpolation", "--data", s(&data), "--files", "smoke1", "--width", "16", "--height", "12", "--time", "0.01", "--repeats", "2",
        "--rule-files", "explosion/mantaflow_explosion_kelvin_0020.vdb", "--rule-width", "16", "--rule-height", "12", "--rule-step", "0.25",
        "--pictures", s(&png), "--closeup-width", "24", "--closeup-height", "16", "--closeup-spp", "1", "--json", s(&json),
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("linear cost ÷ nearest")
            && stdout.contains("dual pyramid")
            && stdout.contains("temperature first"),
        "{stdout}"
    );
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let cost = report["cost"].as_array().unwrap();
    assert_eq!(cost.len(), 4, "ray-march, line, line-fnee, point-nee");
    for row in cost {
        let ratio = row["cost_ratio"].as_f64().unwrap();
        assert!(ratio.is_finite() && ratio > 0.0, "{row}");
        assert_eq!(row["nearest"]["runs"].as_array().unwrap().len(), 2);
        assert!(row["linear"]["pieces_per_sample"].as_f64().unwrap() > 0.0, "{row}");
    }
    let memory = &report["memory"][0];
    let percent = memory["percent"].as_f64().unwrap();
    assert!(percent > 0.0 && percent <= 10.0, "the dual pyramid adds at most 10 %: {memory}");
    let rule = report["rule"]["rows"].as_array().unwrap();
    assert_eq!(rule.len(), 2, "cycles and physical conventions");
    for row in rule {
        for key in ["mean_difference_percent", "relrmse", "rmse_over_mean"] {
            assert!(row[key].as_f64().unwrap().is_finite(), "{key}: {row}");
        }
        assert!(row["cycles_mean"].as_f64().unwrap() > 0.0, "{row}");
    }
    let png = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&png).unwrap()));
    let info = png.read_info().unwrap();
    assert!(info.info().width >= 2 * 24 && info.info().height >= 16);
    // An unknown file name is refused, naming the flag
    let o = plume(&[
        "bench",
        "interpolation",
        "--data",
        s(&data),
        "--files",
        "nope",
        "--rule-files",
        "explosion/mantaflow_explosion_kelvin_0020.vdb",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--files"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// The peer comparison's equal-CPU rules (`scripts/budget.py`: the CPU model fitted over a
/// ladder, and the error at a budget read between the rungs that bracket it) pass their
/// self-test. Without `python3` the test skips loudly.
#[test]
fn the_peer_comparisons_budget_rules_pass_their_self_test() {
    let script = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/budget.py");
    let output = match std::process::Command::new("python3").arg(&script).output() {
        Ok(o) => o,
        Err(e) => {
            eprintln!(
                "\n!!!!!!!!!! SKIPPED budget.py self-test: cannot run python3: {e} !!!!!!!!!!\n"
            );
            return;
        }
    };
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success() && stdout.contains("self-test ok"),
        "{}: {stdout}{}",
        script.display(),
        String::from_utf8_lossy(&output.stderr)
    );
}

/// `plume bench demo` on a tiny scene file: it times each seed's render, judges it against
/// references it renders once and keeps (and again when one is damaged), and refuses
/// references that cannot measure noise.
#[test]
fn demo_bench_judges_each_seed_and_keeps_its_references() {
    let dir = tmpdir("bench-test", "demo");
    let vdb = common::explosion(&dir, 16, Some(3));
    let scene = dir.join("shot.toml");
    std::fs::write(
        &scene,
        "[volume]\nfile = \"ex.vdb\"\n[medium]\nalbedo = 0.8\n[camera]\nwidth = 24\nheight = 18\n[integrator]\ncamera_estimator = \"ray-march\"\nsplit = 2\n\
         [render]\nspp = 4\n[output]\nimage = \"shot.exr\"\ndenoise = true\n",
    )
    .unwrap();
    assert!(vdb.exists());
    let (work, json) = (dir.join("work"), dir.join("demo.json"));
    let args = [
        "bench",
        "demo",
        "--scene",
        s(&scene),
        "--seeds",
        "0,1",
        "--reference-spp",
        "16",
        "--work-dir",
        s(&work),
        "--json",
        s(&json),
        "--target-rel-rmse",
        "5",
    ];
    let o = plume(&args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert_eq!(err.matches("rendering reference").count(), 2, "{err}");
    let table = String::from_utf8_lossy(&o.stdout);
    assert!(
        table.contains("| seed | wall s |") && table.contains("relRMSE ≤ 5 on every seed: yes"),
        "{table}"
    );
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let runs = report["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 2);
    for run in runs {
        let e = &run["error"];
        let rel = e["rel_rmse"].as_f64().unwrap();
        // 4 spp of a scattering render against two 16-spp references: noisy, not wrong
        assert!(rel.is_finite() && rel > 0.0 && rel < 5.0, "{run}");
        assert!((e["mean_ratio"].as_f64().unwrap() - 1.0).abs() < 0.5, "{run}");
        assert!(
            run["wall_seconds"].as_f64().unwrap() > 0.0
                && run["cpu_seconds"].as_f64().unwrap() > 0.0,
            "{run}"
        );
        assert!(e["speck"]["ratio"].as_f64().unwrap() >= 1.0, "{run}");
    }
    // The user's image is untouched: every render went to the work directory
    assert!(!dir.join("shot.exr").exists());
    // A second run renders no reference
    let o = plume(&args);
    assert!(
        o.status.success() && !String::from_utf8_lossy(&o.stderr).contains("rendering reference"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    // A reference seed among the demo's would share its noise; one reference image has no spread
    common::plume_exits(
        &["bench", "demo", "--scene", s(&scene), "--seeds", "11", "--work-dir", s(&work)],
        2,
        &["--reference-seeds", "11"],
    );
    let one = work
        .read_dir()
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| {
            p.to_string_lossy().contains("reference-") && p.extension().is_some_and(|e| e == "exr")
        })
        .unwrap();
    common::plume_exits(
        &["bench", "demo", "--scene", s(&scene), "--references", s(&one), "--work-dir", s(&work)],
        2,
        &["--references"],
    );
    // A damaged reference (or an interrupted render's partial one) is rendered again
    std::fs::write(&one, b"not an image").unwrap();
    let o = plume(&args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success() && err.matches("rendering reference").count() == 1, "{err}");
    common::plume_exits(
        &["bench", "demo", "--scene", s(&scene), "--target-seconds", "0", "--work-dir", s(&work)],
        2,
        &["--target-seconds"],
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// `plume bench report` at the smallest budgets, with no data directory: every section
/// that needs a data file says so and the header lists it, the generated sections run, the
/// README demo runs on a tiny scene file in its place (its volume made as
/// `scripts/demo.sh` makes it), and the document has the report's form (no history, the
/// machine named once, a command under every table, the short ideas table).
#[test]
fn report_writes_a_document_of_its_form_at_tiny_budgets() {
    use plume::bench::report::{check_document, Budgets, ReportOptions};
    let dir = tmpdir("bench-test", "report");
    // The demo's scene file where the report looks for it, tiny, its volume missing
    std::fs::create_dir_all(dir.join("data")).unwrap();
    std::fs::write(
        dir.join("data/explosion.toml"),
        "[volume]\nfile = \"../out/explosion.vdb\"\n[medium]\ndensity_scale = 4.0\nalbedo = 0.8\n[camera]\nwidth = 12\nheight = 9\n\
         [render]\nspp = 2\n[output]\nimage = \"../out/explosion.exr\"\n",
    )
    .unwrap();
    let options = ReportOptions {
        out: dir.join("docs"),
        budgets: Budgets {
            quick: false,
            time_scale: 0.005,
            resolution: 16,
            core_resolution: 16,
            demo: true,
        },
        data: dir.join("no-data"),
        work_dir: dir.join("work"),
        working_dir: dir.clone(),
        exe: Some(common::PLUME.into()),
    };
    options.run().unwrap();
    let md = std::fs::read_to_string(dir.join("docs/BENCHMARKS.md")).unwrap();
    let problems = check_document(&md);
    assert!(problems.is_empty(), "{}\n\n{md}", problems.join("\n"));
    assert!(
        md.contains("This is the full form")
            && md.contains("(budgets set on the command line)")
            && md.contains("Not run: "),
        "{md}"
    );
    assert!(dir.join("out/explosion.vdb").exists(), "the demo's volume is made when missing");
    let demo = md.split("## README demo").nth(1).unwrap();
    assert!(demo.contains("| seed | wall s |") && demo.contains("\n| 3 | "), "{demo}");
    for generated in [
        "## Generated explosion 16³, thin",
        "## FNEE proxy resolution",
        "## Splitting by brightness",
        "## Motion blur",
        "## Numerical extremes",
    ] {
        let section = md.split(generated).nth(1).unwrap_or_else(|| panic!("no {generated:?}"));
        assert!(section.contains("```sh\nplume bench "), "{generated}: no command");
    }
    // The scene files the commands read are there, with the data's paths as seen from them
    let thin = std::fs::read_to_string(dir.join("docs/bench/scenes/thin.toml")).unwrap();
    assert!(thin.contains("explosion:16"), "{thin}");
    assert!(md.contains("Not measured: ") && md.contains("no-data"), "missing files are named");
    let _ = std::fs::remove_dir_all(&dir);
}

/// docs/BENCHMARKS.md is what `plume bench report` writes: today's figures only, the
/// machine named once, each table with the command that reproduces it, no commit hashes,
/// dates or issue numbers, and the sections other documents cite by name.
#[test]
fn benchmarks_md_has_the_reports_form() {
    use plume::bench::report::{check_document, history};
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/BENCHMARKS.md");
    let md = std::fs::read_to_string(&path).unwrap();
    let problems = check_document(&md);
    assert!(problems.is_empty(), "{}:\n{}", path.display(), problems.join("\n"));
    for section in [
        "Headline",
        "Core renderer",
        "FNEE proxy resolution",
        "Tracking",
        "Splitting at the camera collision",
        "Splitting by brightness",
        "Forced camera collisions",
        "Stochastic point lookups",
        "Adaptive sampling: CPU time to a target error",
        "Motion blur",
        "Interpolation",
        "Numerical extremes",
        "README demo",
        "Out of core with scattering",
        "Peer comparison: Cycles",
        "Ideas tried and not kept",
    ] {
        assert!(
            md.contains(&format!("\n## {section}")),
            "no section {section:?} in {}",
            path.display()
        );
    }
    // The check finds history where it is planted
    let planted = md.replacen(
        "## Numerical extremes\n",
        "## Numerical extremes\n\nMeasured at `25fc21c` on 2026-11-27 for issue #16.\n",
        1,
    );
    assert_eq!(history(&planted).len(), 3, "{:?}", history(&planted));
}
