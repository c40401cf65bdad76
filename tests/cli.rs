//! The `plume` binary as users and farms run it: real child processes, real files.

use crate::common;

use std::path::PathBuf;

use common::{explosion, exr_pixels, names_in, plume, plume_exits, s, tmpdir, SMOKE};

#[test]
fn render_is_bit_identical_for_1_and_2_threads_and_writes_all_outputs() {
    let d = tmpdir("cli", "det");
    // A 64³ explosion, generated per test that needs it (fast)
    let ex = explosion(&d, 64, Some(3));
    let mut images = Vec::new();
    for threads in ["1", "2"] {
        let out = d.join(format!("t{threads}.exr"));
        let png = d.join(format!("t{threads}.png"));
        let stats = d.join(format!("t{threads}.json"));
        let o = plume(&[
            "render",
            s(&ex),
            "-o",
            s(&out),
            "--preview",
            s(&png),
            "--stats",
            s(&stats),
            "--spp",
            "4",
            "--width",
            "48",
            "--height",
            "32",
            "--threads",
            threads,
            "--seed",
            "9",
            "--density-scale",
            "3",
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert!(std::fs::metadata(&png).unwrap().len() > 100);
        let st: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&stats).unwrap()).unwrap();
        for key in [
            "spp",
            "wall_seconds",
            "cpu_seconds",
            "core_hours",
            "samples_per_second",
            "peak_rss_bytes",
        ] {
            assert!(st.get(key).is_some(), "stats lacks {key}");
        }
        assert_eq!(st["spp"], 4);
        images.push(exr_pixels(&out));
    }
    assert!(images[0].iter().any(|p| p[0] > 0.0), "the explosion emits");
    assert_eq!(images[0], images[1]);
    let leftovers = names_in(&d, |n| n.contains(".tmp"));
    assert!(leftovers.is_empty());
}

#[test]
fn info_json_has_the_documented_keys() {
    let o = plume(&["info", SMOKE, "--json"]);
    assert!(o.status.success());
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let g = &v[0];
    for key in ["name", "type", "active_voxels", "voxel_size", "index_bbox", "min", "max"] {
        assert!(g.get(key).is_some(), "missing {key}");
    }
    assert_eq!(g["name"], "density");
    assert_eq!(g["active_voxels"], 1_049_275);
    assert_eq!(g["index_bbox"], serde_json::json!([[1, 2, 1], [111, 223, 112]]));
    let text = plume(&["info", SMOKE]);
    assert!(String::from_utf8_lossy(&text.stdout).contains("1,049,275"));
}

/// Every failure: non-zero exit with the documented code, one line naming the thing, no output.
#[test]
fn bad_input_gives_one_line_errors_and_exit_codes() {
    let d = tmpdir("cli", "err");
    let out = d.join("o.exr");
    let o_s = s(&out).to_string();
    let png_s = s(&d.join("o.png")).to_string();
    let cases: Vec<(Vec<&str>, i32, &str)> = vec![
        (vec!["render", "../shared/data/missing.vdb", "-o", &o_s], 3, "missing.vdb"),
        (vec!["render", SMOKE, "-o", &o_s, "--density-grid", "smoke"], 3, "available: density"),
        (
            vec![
                "render",
                "../shared/data/edge_cases/oiio_sphereCd.vdb",
                "--density-grid",
                "Cd",
                "-o",
                &o_s,
            ],
            3,
            "vec3s",
        ),
        (
            vec!["render", "../shared/data/edge_cases/malformed/oiio_truncated.vdb", "-o", &o_s],
            3,
            "oiio_truncated.vdb",
        ),
        (
            vec!["render", "../shared/data/nanovdb/openvdb_fvdb_smoke-blosc.nvdb", "-o", &o_s],
            3,
            "NanoVDB",
        ),
        (vec!["render", SMOKE, "-o", &o_s, "--emission", "blackbody"], 3, "temperature"),
        (
            vec!["render", SMOKE, "-o", "/nonexistent-dir/o.exr", "--spp", "1"],
            4,
            "/nonexistent-dir/o.exr",
        ),
        (vec!["render", SMOKE, "-o", &o_s, "--spp", "0"], 2, "--spp"),
        (vec!["render", SMOKE, "-o", &o_s, "--density-scale", "-1"], 2, "--density-scale"),
        (vec!["render", SMOKE, "-o", &o_s, "--temperature-map", "celsius"], 2, "--temperature-map"),
        (
            vec!["render", SMOKE, "-o", &o_s, "--camera-from", "0,0,0", "--camera-at", "0,0,0"],
            2,
            "--camera-at",
        ),
        (vec!["render", SMOKE, "-o", &o_s, "--camera-from", "1,2"], 2, "--camera-from"),
        (vec!["render", SMOKE, "-o", &o_s, "--estimator", "magic"], 2, "--estimator"),
        (vec!["render", SMOKE, "-o", &png_s], 2, "--output"),
        (vec!["render", SMOKE, "-o", &o_s, "--max-input-memory", "1KiB"], 3, "--max-input-memory"),
    ];
    for (args, code, needle) in cases {
        let err = plume_exits(&args, code, &[needle]);
        let error_lines: Vec<_> = err.lines().filter(|l| l.contains("error")).collect();
        assert_eq!(error_lines.len(), 1, "{args:?}: one error line: {err}");
        assert!(!out.exists(), "{args:?}: no output written");
    }
}

#[test]
fn every_real_and_malformed_file_renders_or_is_refused_cleanly() {
    let d = tmpdir("cli", "all");
    let mut files = Vec::new();
    let mut stack = vec![PathBuf::from("../shared/data")];
    while let Some(p) = stack.pop() {
        for e in std::fs::read_dir(&p).unwrap() {
            let path = e.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "vdb" || e == "nvdb") {
                files.push(path);
            }
        }
    }
    assert!(files.len() >= 18, "{files:?}");
    for f in files {
        let out = d.join("o.exr");
        let _ = std::fs::remove_file(&out);
        let o = plume(&[
            "render",
            s(&f),
            "-o",
            s(&out),
            "--spp",
            "1",
            "--width",
            "16",
            "--height",
            "12",
            "-q",
        ]);
        let code = o.status.code();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(code == Some(0) || code == Some(3), "{}: exit {code:?} {err}", f.display());
        if code == Some(0) {
            assert!(exr_pixels(&out).iter().flatten().all(|v| v.is_finite()), "{}", f.display());
        } else {
            assert!(
                err.contains(f.file_name().unwrap().to_str().unwrap()),
                "{}: {err}",
                f.display()
            );
            assert!(!out.exists());
        }
    }
}

#[test]
fn numerical_extremes_give_finite_pixels() {
    let d = tmpdir("cli", "ext");
    let ex = explosion(&d, 64, Some(3));
    // Density ×1e-6 … ×1e6; temperatures mapped up to 1e7 K (and down to 0 K).
    let cases: [&[&str]; 6] = [
        &["--density-scale", "1e-6"],
        &["--density-scale", "1e6"],
        &["--temperature-map", "linear:0,3300", "--density-scale", "2"],
        &["--temperature-map", "linear:0,0"],
        &["--temperature-map", "linear:0,1e-4", "--convention", "cycles"],
        &["--convention", "cycles", "--density-scale", "1e6"],
    ];
    for extra in cases {
        for est in ["point", "line", "ray-march"] {
            let out = d.join("o.exr");
            let mut args = vec![
                "render",
                s(&ex),
                "-o",
                s(&out),
                "--spp",
                "2",
                "--width",
                "24",
                "--height",
                "16",
                "-q",
                "--estimator",
                est,
            ];
            args.extend_from_slice(extra);
            let o = plume(&args);
            assert!(o.status.success(), "{args:?}: {}", String::from_utf8_lossy(&o.stderr));
            let px = exr_pixels(&out);
            assert!(px.iter().flatten().all(|v| v.is_finite()), "{args:?}");
        }
    }
}

/// `plume render --help` groups every flag under a heading; `-h` shows the flags most
/// renders use and leaves the tuning flags to `--help`.
#[test]
fn render_help_is_grouped_and_short_help_leaves_out_tuning_flags() {
    let text = |flag: &str| {
        let o = common::plume(&["render", flag]);
        assert!(o.status.success(), "render {flag}");
        String::from_utf8(o.stdout).unwrap()
    };
    let long = text("--help");
    for heading in [
        "Output:",
        "Sampling:",
        "Camera:",
        "Volume and grids:",
        "Medium:",
        "Lights:",
        "Motion:",
        "Method:",
        "Farm:",
        "Out of core:",
        "Advanced:",
    ] {
        assert!(long.lines().any(|l| l == heading), "--help lacks the heading {heading:?}");
    }
    let short = text("-h");
    for common in ["--spp", "--albedo", "--method", "--denoise", "--frames", "--memory-budget"] {
        assert!(short.contains(common), "-h lacks {common}");
    }
    for tuning in ["--point-lookup", "--nee-table", "--kappa", "--defer-paths", "--tracking"] {
        assert!(!short.contains(tuning), "-h shows the tuning flag {tuning}");
        assert!(long.contains(tuning), "--help lacks {tuning}");
    }
    assert!(!long.contains("--sampler"), "--sampler is a scene key only");
}
