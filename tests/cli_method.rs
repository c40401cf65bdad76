//! The scattering / light-sampling surface of `plume render`: presets, diagnostics in
//! `--stats`, `--debug-pixel` replay, flag validation.

use crate::common;

use common::{explosion, exr_pixels, plume, s, synth_explosion, tmpdir};

#[test]
fn every_method_preset_renders_and_reports_its_counters() {
    let d = tmpdir("clim", "presets");
    let ex = explosion(&d, 48, None);
    for method in ["point-nee", "line-nee", "line-fnee", "ray-march"] {
        let out = d.join(format!("{method}.exr"));
        let stats = d.join(format!("{method}.json"));
        let o = plume(&[
            "render",
            s(&ex),
            "-o",
            s(&out),
            "--stats",
            s(&stats),
            "--method",
            method,
            "--albedo",
            "0.8",
            "--g",
            "0.4",
            "--spp",
            "2",
            "--width",
            "24",
            "--height",
            "16",
            "--density-scale",
            "5",
            "-q",
        ]);
        assert!(o.status.success(), "{method}: {}", String::from_utf8_lossy(&o.stderr));
        let st: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&stats).unwrap()).unwrap();
        let c = &st["counters"];
        for key in [
            "segments",
            "voxel_steps",
            "collisions",
            "fnee_samples",
            "nee_samples",
            "nonfinite_samples",
            "first_nonfinite",
        ] {
            assert!(c.get(key).is_some(), "{method}: counters lack {key}");
        }
        assert!(c["voxel_steps"].as_u64().unwrap() >= c["segments"].as_u64().unwrap() / 2);
        assert!(c["collisions"].as_u64().unwrap() > 0, "{method}: paths scatter");
        let uses_fnee = method == "line-fnee";
        let uses_nee = method.ends_with("-nee") && !uses_fnee;
        assert_eq!(c["fnee_samples"].as_u64().unwrap() > 0, uses_fnee, "{method}");
        assert_eq!(c["nee_samples"].as_u64().unwrap() > 0, uses_nee, "{method}");
        assert_eq!(c["nonfinite_samples"], 0);
    }
}

#[test]
fn debug_pixel_replays_the_rendered_sample() {
    // One sample per pixel: the replayed sample must equal the rendered pixel exactly, with
    // scattering, for line + FNEE and point + NEE, for both reconstructions (trilinear
    // draws NEE points from its own hat and evaluates pieces, not voxels).
    let d = tmpdir("clim", "debug");
    let ex = explosion(&d, 48, None);
    for interpolation in ["linear", "nearest"] {
        for method in ["line-fnee", "point-nee"] {
            let out = d.join(format!("{interpolation}-{method}.exr"));
            let common = [
                "--albedo",
                "0.8",
                "--spp",
                "1",
                "--width",
                "20",
                "--height",
                "14",
                "--density-scale",
                "4",
                "--seed",
                "5",
                "-q",
                "--interpolation",
                interpolation,
                "--method",
                method,
            ];
            let mut args = vec!["render", s(&ex), "-o", s(&out)];
            args.extend_from_slice(&common);
            assert!(plume(&args).status.success());
            // The pixel nearest the centre whose path collided (alpha 1) and carries light,
            // so that the replay goes through a scattering vertex and its light sample
            let pixels = exr_pixels(&out);
            let distance = |i: usize| (i % 20).abs_diff(10) + (i / 20).abs_diff(7);
            let i = (0..pixels.len())
                .filter(|&i| pixels[i][3] == 1.0 && pixels[i][0] > 0.0)
                .min_by_key(|&i| distance(i))
                .expect("a scattered path");
            let (px, at) = (pixels[i], format!("{},{},0", i % 20, i / 20));
            let mut args = vec!["render", s(&ex), "-o", s(&out), "--debug-pixel", &at];
            args.extend_from_slice(&common);
            let o = plume(&args);
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
            let err = String::from_utf8_lossy(&o.stderr);
            let light = if method == "line-fnee" { "fnee:" } else { "nee:" };
            for needle in [
                format!("plume: debug {at}: segment depth 0"),
                format!("plume: debug {at}: segment depth 1"),
                light.to_string(),
            ] {
                assert!(err.contains(&needle), "{interpolation} {method}: no {needle:?} in {err}");
            }
            let values = common::replayed_values(&o);
            for c in 0..4 {
                assert_eq!(
                    values[c] as f32, px[c],
                    "{interpolation} {method} channel {c}: replay {values:?} vs pixel {px:?}"
                );
            }
        }
    }
}

#[test]
fn scattering_flags_are_validated() {
    let d = tmpdir("clim", "flags");
    let ex = explosion(&d, 48, None);
    let out = d.join("o.exr");
    for (flag, value) in [
        ("--albedo", "1.5"),
        ("--g", "1"),
        ("--g", "-1.2"),
        ("--proxy-resolution", "12"),
        ("--debug-pixel", "99,0,0"),
        ("--environment", "1,-1,0"),
    ] {
        let albedo = if flag == "--albedo" { value } else { "0.5" };
        let mut args = vec![
            "render",
            s(&ex),
            "-o",
            s(&out),
            "--albedo",
            albedo,
            "--width",
            "16",
            "--height",
            "12",
            "--spp",
            "1",
        ];
        if flag != "--albedo" {
            args.extend_from_slice(&[flag, value]);
        }
        let o = plume(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{flag} {value}: {err}");
        assert!(err.contains(flag) && !err.contains("multiple times"), "{flag} {value}: {err}");
        assert!(!out.exists());
    }
}

#[test]
fn default_proxy_resolution_adapts_to_small_volumes() {
    // A 24³ volume cannot hold a 64³ proxy: the default shrinks to the data resolution,
    // while an explicit 64 is refused naming the flag.
    let d = tmpdir("clim", "proxy");
    let ex = d.join("small.vdb");
    synth_explosion(&ex, 24, None);
    let out = d.join("o.exr");
    let base = [
        "render",
        s(&ex),
        "-o",
        s(&out),
        "--albedo",
        "0.7",
        "--spp",
        "1",
        "--width",
        "12",
        "--height",
        "8",
        "-q",
    ];
    let o = plume(&base);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut explicit = base.to_vec();
    explicit.extend_from_slice(&["--proxy-resolution", "64", "--overwrite"]);
    let o = plume(&explicit);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--proxy-resolution"));
}
