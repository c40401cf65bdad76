//! Scene files: `plume render shot.toml` renders exactly what the same flags render,
//! `--write-scene` round-trips, flags override keys, the EXR header carries the resolved
//! scene, and a bad file gets one line naming the file, the line and the key (exit 2, no
//! output).

use crate::common;

use std::path::{Path, PathBuf};

use common::{pixel_bits as bits, plume, s, tmpdir};

/// The generated explosion every test renders (small and fast).
fn explosion(dir: &Path) -> PathBuf {
    common::explosion(dir, 32, None)
}

fn pixels(path: &Path) -> Vec<[f32; 4]> {
    common::exr_pixels(path)
}

fn ok(o: &std::process::Output) {
    assert!(o.status.success(), "plume failed: {}", String::from_utf8_lossy(&o.stderr));
}

/// Flags of a render that exercises most keys (scattering, camera, estimator, lights).
const FLAGS: &[&str] = &[
    "--spp",
    "3",
    "--width",
    "40",
    "--height",
    "30",
    "--density-scale",
    "4",
    "--albedo",
    "0.8",
    "--g",
    "0.3",
    "--camera-from",
    "3,2,6",
    "--fov",
    "35",
    "--estimator",
    "blend",
    "--camera-estimator",
    "ray-march",
    "--kappa",
    "2",
    "--environment",
    "0.1,0.2,0.3",
    "--mis",
    "balance",
    "--proxy-resolution",
    "8",
    "--emission-color",
    "1,0.5,0.25",
    "--emission-scale",
    "1.5",
    "--seed",
    "5",
    "-q",
];

#[test]
fn scene_file_renders_what_the_flags_render_bit_for_bit() {
    let dir = tmpdir("scene", "equal");
    let vdb = explosion(&dir);
    let by_flags = dir.join("flags.exr");
    let mut argv = vec!["render", s(&vdb), "-o", s(&by_flags)];
    argv.extend_from_slice(FLAGS);
    ok(&plume(&argv));
    let shot = dir.join("shot.toml");
    std::fs::write(
        &shot,
        r#"
[volume]
file = "ex.vdb"
[medium]
density_scale = 4
albedo = 0.8
g = 0.3
[camera]
from = [3, 2, 6]
fov = 35
width = 40
height = 30
[emission]
color = [1, 0.5, 0.25]
scale = 1.5
[lights]
environment = [0.1, 0.2, 0.3]
[integrator]
estimator = "blend"
camera_estimator = "ray-march"
kappa = 2
mis = "balance"
proxy_resolution = 8
[render]
spp = 3
seed = 5
quiet = true
[output]
image = "file.exr"
"#,
    )
    .unwrap();
    ok(&plume(&["render", s(&shot)]));
    let from_file = dir.join("file.exr");
    assert!(from_file.exists(), "relative paths are relative to the scene file");
    assert_eq!(bits(&pixels(&by_flags)), bits(&pixels(&from_file)));
    // The header says how the image was made: the resolved scene, itself a scene file
    let meta = plume::output::read_exr_contents(&from_file).unwrap().metadata;
    let scene = meta.get("plume:scene").expect("plume:scene attribute");
    assert!(
        scene.contains("estimator = \"blend\"")
            && scene.contains("camera_estimator = \"ray-march\"")
            && scene.contains("density_scale = 4.0"),
        "{scene}"
    );
    let again = dir.join("from-header.toml");
    std::fs::write(&again, scene).unwrap();
    let out = dir.join("from-header.exr");
    ok(&plume(&["render", s(&again), "-o", s(&out)]));
    assert_eq!(bits(&pixels(&by_flags)), bits(&pixels(&out)));
}

#[test]
fn write_scene_then_render_gives_the_same_image() {
    let dir = tmpdir("scene", "roundtrip");
    let vdb = explosion(&dir);
    let direct = dir.join("direct.exr");
    let written = dir.join("written.toml");
    let mut argv = vec!["render", s(&vdb), "-o", s(&direct)];
    argv.extend_from_slice(FLAGS);
    let mut write = argv.clone();
    write.extend_from_slice(&["--write-scene", s(&written)]);
    ok(&plume(&write));
    assert!(!direct.exists(), "--write-scene renders nothing");
    let text = std::fs::read_to_string(&written).unwrap();
    assert!(text.contains("[camera]") && text.contains("width = 40"), "{text}");
    ok(&plume(&argv));
    // Rendered from another directory: the written paths are absolute
    let elsewhere = tmpdir("scene", "roundtrip-cwd");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_plume"))
        .current_dir(&elsewhere)
        .args(["render", s(&written), "-o", "again.exr"])
        .output()
        .unwrap();
    ok(&o);
    assert_eq!(bits(&pixels(&direct)), bits(&pixels(&elsewhere.join("again.exr"))));
    // Writing the scene of the written scene gives the same file
    let twice = dir.join("twice.toml");
    ok(&plume(&["render", s(&written), "--write-scene", s(&twice)]));
    assert_eq!(std::fs::read_to_string(&twice).unwrap(), text);
}

#[test]
fn flags_beside_a_scene_file_override_its_keys() {
    let dir = tmpdir("scene", "override");
    let vdb = explosion(&dir);
    let shot = dir.join("shot.toml");
    std::fs::write(&shot, "[volume]\nfile = \"ex.vdb\"\n[camera]\nwidth = 40\nheight = 30\n[render]\nspp = 2\nquiet = true\n[output]\nimage = \"a.exr\"\n")
        .unwrap();
    let by_flags = dir.join("flags.exr");
    ok(&plume(&[
        "render",
        s(&vdb),
        "-o",
        s(&by_flags),
        "--width",
        "40",
        "--height",
        "30",
        "--spp",
        "4",
        "--density-scale",
        "3",
        "-q",
    ]));
    let over = dir.join("over.exr");
    ok(&plume(&["render", s(&shot), "-o", s(&over), "--spp", "4", "--density-scale", "3"]));
    assert!(!dir.join("a.exr").exists());
    assert_eq!(bits(&pixels(&by_flags)), bits(&pixels(&over)));
    // A file without [output] takes -o, and without it is refused naming the key
    let bare = dir.join("bare.toml");
    std::fs::write(&bare, "[volume]\nfile = \"ex.vdb\"\n[camera]\nwidth = 40\nheight = 30\n[render]\nspp = 4\nquiet = true\n[medium]\ndensity_scale = 3\n")
        .unwrap();
    let o = plume(&["render", s(&bare)]);
    let err = String::from_utf8_lossy(&o.stderr);
    // The file lies in another directory than the working one: still "required", not a
    // directory taken for the image
    assert!(
        o.status.code() == Some(2) && err.contains("output.image") && err.contains("required"),
        "{err}"
    );
    let from_bare = dir.join("bare.exr");
    ok(&plume(&["render", s(&bare), "-o", s(&from_bare)]));
    assert_eq!(bits(&pixels(&by_flags)), bits(&pixels(&from_bare)));
    // A flag also replaces the keys it conflicts with: --time drops the file's spp
    let written = dir.join("timed.toml");
    ok(&plume(&["render", s(&shot), "--time", "1", "--write-scene", s(&written)]));
    let text = std::fs::read_to_string(&written).unwrap();
    assert!(text.contains("time = 1.0") && !text.contains("spp ="), "{text}");
}

/// Run a bad scene file: exit 2, one line naming the file, the line and the key, no output.
fn refused(name: &str, body: &str, line: usize, key: &str) {
    let dir = tmpdir("scene", &format!("bad-{name}"));
    let shot = dir.join("bad.toml");
    std::fs::write(&shot, body).unwrap();
    let o = plume(&["render", s(&shot)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{name}: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{name}: one line: {err}");
    let at = format!("{}:{line}:", shot.display());
    assert!(err.contains(&at), "{name}: expected {at} in {err}");
    assert!(err.contains(key), "{name}: expected key {key} in {err}");
    assert!(!dir.join("out.exr").exists(), "{name}: no output");
}

#[test]
fn bad_scene_files_name_the_file_line_and_key() {
    let head = "[volume]\nfile = \"ex.vdb\"\n[output]\nimage = \"out.exr\"\n";
    refused("syntax", &format!("{head}[camera]\nwidth = = 3\n"), 6, "camera");
    refused("unknown-key", &format!("{head}[camera]\nwidht = 3\n"), 6, "widht");
    refused("unknown-table", &format!("{head}[camra]\nwidth = 3\n"), 5, "camra");
    refused("wrong-type", &format!("{head}[camera]\nwidth = \"wide\"\n"), 6, "camera.width");
    refused(
        "bad-choice",
        &format!("{head}[integrator]\nmethod = \"fast\"\n"),
        6,
        "integrator.method",
    );
    refused(
        "out-of-range",
        &format!("{head}[medium]\ng = 0.5\nalbedo = 1.5\n"),
        7,
        "medium.albedo",
    );
    refused("no-paths", &format!("{head}[integrator]\nsplit = 0\n"), 6, "integrator.split");
    refused("negative-size", &format!("{head}\n[camera]\nheight = -4\n"), 7, "camera.height");
    refused(
        "bad-output",
        "[volume]\nfile = \"ex.vdb\"\n[output]\nimage = \"out.png\"\n",
        4,
        "output.image",
    );
    refused(
        "no-volume-file",
        "[volume]\ndensity_grid = \"d\"\n[output]\nimage = \"out.exr\"\n",
        1,
        "volume",
    );
}

#[test]
fn a_flag_value_beside_a_scene_file_is_named_by_its_flag() {
    let dir = tmpdir("scene", "flag-error");
    let shot = dir.join("shot.toml");
    std::fs::write(&shot, "[volume]\nfile = \"ex.vdb\"\n[output]\nimage = \"out.exr\"\n").unwrap();
    let o = plume(&["render", s(&shot), "--albedo", "3"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("--albedo") && !err.contains("bad.toml"), "{err}");
}

#[test]
fn the_example_scene_file_is_complete_and_valid() {
    let dir = tmpdir("scene", "example");
    let example = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/explosion.toml");
    let written = dir.join("resolved.toml");
    ok(&plume(&["render", s(&example), "--write-scene", s(&written)]));
    let text = std::fs::read_to_string(&written).unwrap();
    for key in [
        "density_scale = 4.0",
        "albedo = 0.8",
        "g = 0.3",
        "spp = 32",
        "method = \"line-fnee\"",
        "split = 6",
        "split_by = \"brightness\"",
        "proxy_resolution = 32",
        "camera_estimator = \"ray-march\"",
        "width = 640",
        "denoise = true",
    ] {
        assert!(text.contains(key), "{key} in {text}");
    }
    // The demo script's main command renders this file (and `plume bench demo` times it),
    // so the two cannot drift apart
    let demo =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/demo.sh"))
            .unwrap();
    assert!(
        demo.lines().any(|l| l
            .trim_start()
            .starts_with("./target/release/plume render data/explosion.toml")),
        "{demo}"
    );
}

#[test]
fn a_merged_frame_records_the_scene_of_the_whole_frame() {
    let dir = tmpdir("scene", "merge");
    let vdb = explosion(&dir);
    let part = |i: &str| dir.join(format!("part{i}.exr"));
    for i in ["0", "1"] {
        let tile = format!("{i}/2");
        ok(&plume(&[
            "render",
            s(&vdb),
            "-o",
            s(&part(i)),
            "--tile",
            &tile,
            "--spp",
            "3",
            "--width",
            "40",
            "--height",
            "30",
            "--albedo",
            "0.5",
            "-q",
        ]));
    }
    let merged = dir.join("merged.exr");
    ok(&plume(&["merge", s(&part("0")), s(&part("1")), "-o", s(&merged), "-q"]));
    let scene = plume::output::read_exr_contents(&merged)
        .unwrap()
        .metadata
        .remove("plume:scene")
        .expect("plume:scene");
    assert!(!scene.contains("tile") && !scene.contains("crop"), "{scene}");
    let shot = dir.join("merged.toml");
    std::fs::write(&shot, &scene).unwrap();
    let again = dir.join("again.exr");
    ok(&plume(&["render", s(&shot), "-o", s(&again)]));
    assert_eq!(
        bits(&pixels(&merged)),
        bits(&pixels(&again)),
        "the merged frame's scene renders the merged frame"
    );
}

/// The sampler is a scene-file key only (`render.sampler`): the independent random
/// numbers are kept for reproducing the sampler comparison, and never beat Sobol points.
#[test]
fn sampler_is_chosen_by_key_is_written_and_changes_the_image() {
    let dir = tmpdir("scene", "sampler");
    explosion(&dir);
    let scene = |sampler: &str| {
        let line =
            if sampler.is_empty() { String::new() } else { format!("sampler = \"{sampler}\"\n") };
        format!("[volume]\nfile = \"ex.vdb\"\n[camera]\nwidth = 24\nheight = 16\n[medium]\nalbedo = 0.8\ndensity_scale = 4.0\n[render]\nspp = 2\n{line}quiet = true\n")
    };
    let render = |name: &str, sampler: &str| {
        let shot = dir.join(format!("{name}.toml"));
        std::fs::write(&shot, scene(sampler)).unwrap();
        let out = dir.join(format!("{name}.exr"));
        ok(&plume(&["render", s(&shot), "-o", s(&out)]));
        bits(&pixels(&out))
    };
    let default = render("default", "");
    assert_eq!(default, render("sobol", "sobol"), "sobol is the default");
    let random = render("random", "random");
    assert_ne!(default, random);
    // --write-scene records the choice
    let written = dir.join("written.toml");
    ok(&plume(&[
        "render",
        s(&dir.join("random.toml")),
        "-o",
        s(&dir.join("unused.exr")),
        "--write-scene",
        s(&written),
    ]));
    assert!(std::fs::read_to_string(&written).unwrap().contains("sampler = \"random\""));
    // No flag: the sampler is not a tuning knob of the command line
    common::plume_exits(
        &["render", s(&dir.join("ex.vdb")), "-o", s(&dir.join("x.exr")), "--sampler", "random"],
        2,
        &["--sampler"],
    );
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, scene("halton")).unwrap();
    common::plume_exits(&["render", s(&bad), "-o", s(&dir.join("x.exr"))], 2, &["sobol", "random"]);
}
