//! Lights on the command line and in scene files: every light type renders
//! through the binary, scene files round-trip them bit-identically, and bad light input
//! gets one line naming the flag or file, exit 2 or 3, and no output.

use crate::common;

use common::{explosion, exr_pixels, pixel_bits, plume, refused_in_one_line, s, tmpdir};

/// A small lat-long map: a bright warm band above the horizon, dim below.
fn write_map(path: &std::path::Path, width: u32, height: u32) {
    let pixels: Vec<[f32; 4]> = (0..width * height)
        .map(
            |i| if i / width < height / 2 { [2.0, 1.5, 1.0, 1.0] } else { [0.05, 0.05, 0.05, 1.0] },
        )
        .collect();
    plume::output::write_exr(path, width, height, &pixels, &[]).unwrap();
}

const SMALL: [&str; 8] = ["--width", "24", "--height", "16", "--spp", "4", "-q", "--albedo=0.7"];

/// The smoke alone, without its fire: what it shows is the lights'.
const UNLIT: [&str; 2] = ["--emission", "none"];

#[test]
fn every_light_type_renders_and_brightens_the_smoke() {
    let d = tmpdir("lights", "types");
    let ex = explosion(&d, 32, None);
    let map = d.join("map.exr");
    write_map(&map, 32, 16);
    let base_out = d.join("none.exr");
    let mut args = vec!["render", s(&ex), "-o", s(&base_out)];
    args.extend(SMALL);
    args.extend(UNLIT);
    assert!(plume(&args).status.success());
    let mean = |p: &std::path::Path| {
        let px = exr_pixels(p);
        px.iter().map(|p| f64::from(p[0] + p[1] + p[2])).sum::<f64>() / px.len() as f64
    };
    let without = mean(&base_out);
    assert_eq!(without, 0.0, "unlit smoke is black");
    let env_arg = format!("file = {:?}, intensity = 0.5, visible = false", s(&map));
    for (i, (flag, value)) in [
        ("--distant-light", "direction = [0.3, -0.2, -1], irradiance = 5, kelvin = 5500"),
        ("--distant-light", "direction = [0, -1, 0], illuminance = 3000, angle = 0"),
        (
            "--sphere-light",
            "position = [0, 3, 0], radius = 0.3, power = 2000, color = [1, 0.8, 0.6]",
        ),
        ("--sphere-light", "position = [2, 2, 2], intensity = 40"),
        ("--environment-map", env_arg.as_str()),
        ("--environment", "0.2,0.2,0.3"),
    ]
    .into_iter()
    .enumerate()
    {
        let out = d.join(format!("lit{i}.exr"));
        let mut args = vec!["render", s(&ex), "-o", s(&out), flag, value];
        args.extend(SMALL);
        args.extend(UNLIT);
        let o = plume(&args);
        assert!(o.status.success(), "{flag} {value}: {}", String::from_utf8_lossy(&o.stderr));
        let with = mean(&out);
        assert!(with.is_finite() && with > 1e-4, "{flag} {value}: mean {with} of the lit smoke");
    }
}

#[test]
fn lights_round_trip_through_scene_files_bit_identically() {
    let d = tmpdir("lights", "scene");
    let ex = explosion(&d, 32, None);
    let map = d.join("map.exr");
    write_map(&map, 32, 16);
    let env_arg = format!("file = {:?}, rotation = 30", s(&map));
    let lights = [
        "--distant-light",
        "direction = [0.3, -0.2, -1], irradiance = 5, kelvin = 5500",
        "--sphere-light",
        "position = [0, 3, 0], radius = 0.3, power = 2000",
        "--environment-map",
        env_arg.as_str(),
    ];
    let (direct, toml, from_file) = (d.join("direct.exr"), d.join("shot.toml"), d.join("file.exr"));
    let mut args = vec!["render", s(&ex), "-o", s(&direct)];
    args.extend(SMALL);
    args.extend(lights);
    assert!(plume(&args).status.success());
    let mut write = args.clone();
    write.extend(["--write-scene", s(&toml)]);
    assert!(plume(&write).status.success());
    let text = std::fs::read_to_string(&toml).unwrap();
    for key in
        ["[[lights.distant]]", "[[lights.sphere]]", "[lights.environment_map]", "kelvin = 5500"]
    {
        assert!(text.contains(key), "scene file lacks {key}:\n{text}");
    }
    assert!(plume(&["render", s(&toml), "-o", s(&from_file), "-q"]).status.success());
    assert_eq!(
        pixel_bits(&exr_pixels(&direct)),
        pixel_bits(&exr_pixels(&from_file)),
        "scene file and flags render the same bits"
    );
}

#[test]
fn bad_light_input_is_one_line_and_no_output() {
    let d = tmpdir("lights", "bad");
    let ex = explosion(&d, 32, None);
    let out = d.join("o.exr");
    let square = d.join("square.exr");
    write_map(&square, 8, 8);
    let nan = d.join("nan.exr");
    let mut px = vec![[1.0f32, 1.0, 1.0, 1.0]; 32 * 16];
    px[37] = [f32::NAN, 0.0, 0.0, 1.0];
    plume::output::write_exr(&nan, 32, 16, &px, &[]).unwrap();
    let missing = d.join("missing.exr");
    let cases: [(&str, String, i32, Vec<&str>); 9] = [
        (
            "--sphere-light",
            "position = [0, 0, 3], power = -5".into(),
            2,
            vec!["--sphere-light", "power"],
        ),
        (
            "--sphere-light",
            "position = [0, 0, 3], radius = -1".into(),
            2,
            vec!["--sphere-light", "radius"],
        ),
        (
            "--distant-light",
            "direction = [0, 0, 0]".into(),
            2,
            vec!["--distant-light", "direction"],
        ),
        (
            "--distant-light",
            "direction = [0, 0, -1], irradiance = 1, illuminance = 2".into(),
            2,
            vec!["--distant-light", "not both"],
        ),
        (
            "--distant-light",
            "direction = [0, 0, -1], brightness = 2".into(),
            2,
            vec!["--distant-light", "brightness"],
        ),
        ("--sky", "turbidity = 0".into(), 2, vec!["--sky", "turbidity"]),
        ("--environment-map", s(&missing).into(), 3, vec!["missing.exr"]),
        ("--environment-map", s(&square).into(), 3, vec!["square.exr", "lat-long"]),
        ("--environment-map", s(&nan).into(), 3, vec!["nan.exr"]),
    ];
    for (flag, value, code, needles) in cases {
        let mut args = vec!["render", s(&ex), "-o", s(&out), flag, value.as_str()];
        args.extend(SMALL);
        refused_in_one_line(&args, code, &needles, &out);
    }
}

#[test]
fn the_sky_lights_like_its_own_environment_map() {
    // `--sky` samples the tabulated sky and a 0.53° sun; `plume synth sky` writes the same
    // sky with the sun's energy in one pixel. The same light reaches the smoke, so every
    // pixel has the same expectation: the mean difference is 0 within 4σ (pixels are
    // independent: each has its own Sobol scramble).
    let d = tmpdir("lights", "sky");
    let ex = explosion(&d, 32, None);
    let map = d.join("sky.exr");
    let o = plume(&[
        "synth",
        "sky",
        "-o",
        s(&map),
        "--elevation",
        "40",
        "--azimuth",
        "30",
        "--turbidity",
        "3",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (a, b) = (d.join("sky_light.exr"), d.join("sky_map.exr"));
    let common = [
        "--width",
        "32",
        "--height",
        "24",
        "--spp",
        "64",
        "-q",
        "--albedo",
        "0.8",
        "--emission",
        "none",
    ];
    let mut args =
        vec!["render", s(&ex), "-o", s(&a), "--sky", "elevation = 40, azimuth = 30, turbidity = 3"];
    args.extend(common);
    assert!(plume(&args).status.success());
    let mut args = vec!["render", s(&ex), "-o", s(&b), "--environment-map", s(&map), "--seed", "1"];
    args.extend(common);
    assert!(plume(&args).status.success());
    let (pa, pb) = (exr_pixels(&a), exr_pixels(&b));
    let diff: Vec<f64> = pa
        .iter()
        .zip(&pb)
        .map(|(x, y)| f64::from(x[0] + x[1] + x[2]) - f64::from(y[0] + y[1] + y[2]))
        .collect();
    let (m, se) = common::mean_stderr(&diff);
    let level = pa.iter().map(|x| f64::from(x[0] + x[1] + x[2])).sum::<f64>() / pa.len() as f64;
    assert!(
        level > 0.0 && m.abs() < 4.0 * se + 1e-6 * level,
        "sky light vs its map: mean difference {m} ± {se} at level {level}"
    );
    assert!(se < 0.05 * level, "too noisy to tell: {se} at level {level}");
}

#[test]
fn debug_pixel_replays_a_lit_sample_exactly() {
    // One spp: the pixel is its one sample, which --debug-pixel replays, printing the
    // light samples and the lights its segments reach
    let d = tmpdir("lights", "debug");
    let ex = explosion(&d, 32, None);
    let out = d.join("o.exr");
    let common = [
        "--width",
        "20",
        "--height",
        "14",
        "--spp",
        "1",
        "--albedo",
        "0.8",
        "--seed",
        "5",
        "-q",
        "--distant-light",
        "direction = [0.3, -1, -0.2], irradiance = 4, angle = 10",
        "--environment",
        "0.1,0.1,0.1",
    ];
    let mut args = vec!["render", s(&ex), "-o", s(&out)];
    args.extend(common);
    assert!(plume(&args).status.success());
    let pixels = exr_pixels(&out);
    // The camera segment is ray-marched (alpha is 1 − τ) and its collision forced: where
    // 1 − τ ≥ 1/4 every sample collides (`medium::forced`)
    let i = (0..pixels.len())
        .filter(|&i| pixels[i][3] >= 0.25)
        .min_by_key(|&i| (i % 20).abs_diff(10) + (i / 20).abs_diff(7))
        .expect("a collided path");
    let (px, at) = (pixels[i], format!("{},{},0", i % 20, i / 20));
    let mut args = vec!["render", s(&ex), "-o", s(&out), "--debug-pixel", &at];
    args.extend(common);
    let o = plume(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("  light 0:") || err.contains("  light 1:"), "no light sample in {err}");
    let values = common::replayed_values(&o);
    for c in 0..4 {
        assert_eq!(values[c] as f32, px[c], "channel {c}: replay {values:?} vs pixel {px:?}");
    }
}
