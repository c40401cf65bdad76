//! Several volumes in one scene, as data: `[[volumes]]` scene files (what entries inherit
//! from the top-level tables, relative paths), `[volume]` beside `[[volumes]]` refused, the
//! round trip through `--write-scene`, a scene of one volume written and hashed exactly as
//! before, every refusal of validation through `plume render` (exit 2, one line naming the
//! key, nothing written), `--add-volume` giving the scene of the equivalent file, and each
//! further volume's file resolved per frame and checked before anything renders.
//!
//! Nothing here renders two volumes: each command stops in validation or at a missing
//! input, before loading.

use crate::common;

use std::path::{Path, PathBuf};

use common::{plume, refused_in_one_line, s, stderr, tmpdir};
use plume::farm::fingerprint::settings_hash;
use plume_scene::file::{to_toml_as_is, SceneFile};
use plume_scene::{Shot, ValidShot};

/// The real-data smoke file, absolute.
fn smoke() -> PathBuf {
    common::data("smoke/openvdb_org_smoke1.vdb")
}

/// The shot of the scene file `path`.
fn read(path: &Path) -> Shot {
    SceneFile::read(path).unwrap().0
}

/// A scene file of two volumes (smoke and fire) to `out`: `top` before the list, `entry`
/// in the second entry.
fn two_volumes(top: &str, entry: &str, out: &Path) -> String {
    format!(
        "{top}\n[[volumes]]\nfile = {:?}\n\n[[volumes]]\nfile = {:?}\n{entry}\n\n[output]\nimage = {:?}\n",
        s(&smoke()),
        s(&common::fire()),
        s(out)
    )
}

#[test]
fn entries_inherit_what_they_leave_out_and_resolve_paths_against_the_file() {
    let dir = tmpdir("several", "parse");
    let path = common::write_file(
        &dir,
        "shot.toml",
        r#"
[medium]
density_scale = 4.0
albedo = 0.8

[emission]
scale = 2.0

[[volumes]]
file = "fire.vdb"

[[volumes]]
file = "smoke.vdb"
translate = [2.0, 0.0, 0.0]
name = "smoke"
[volumes.medium]
g = 0.3

[[volumes]]
file = "/data/mist.vdb"
medium = { density_scale = 0.5, albedo = [0.9, 0.9, 1.0] }
emission = { source = "none" }

[output]
image = "shot.exr"
"#,
    );
    let shot = read(&path);
    let scene = &shot.scene;
    assert!(scene.listed);
    assert_eq!(scene.volume_count(), 3);
    let entries = scene.entries();
    let summary: Vec<_> = entries
        .iter()
        .map(|e| (e.volume.file.clone(), e.medium.density_scale, e.albedo_rgb(), e.medium.g))
        .collect();
    assert_eq!(
        summary,
        [
            (dir.join("fire.vdb"), 4.0, [0.8; 3], 0.0),
            (dir.join("smoke.vdb"), 4.0, [0.8; 3], 0.3),
            (PathBuf::from("/data/mist.vdb"), 0.5, [0.9, 0.9, 1.0], 0.0),
        ]
    );
    let scales: Vec<f32> = entries.iter().map(|e| e.emission.scale).collect();
    assert_eq!(scales, [2.0; 3]);
    assert_eq!(entries[2].emission.source, plume_scene::EmissionSource::None);
    assert_eq!(entries[1].volume.translate, Some([2.0, 0.0, 0.0]));
    assert_eq!(entries[1].volume.name.as_deref(), Some("smoke"));
    assert_eq!(entries[1].key("medium.g"), "volumes[1].medium.g");
    assert!(shot.clone().validate().is_ok());
}

#[test]
fn volume_beside_volumes_and_an_empty_list_are_refused() {
    let dir = tmpdir("several", "tables");
    let out = dir.join("o.exr");
    let both =
        format!("[volume]\nfile = {:?}\n{}", s(&smoke()), two_volumes("", "", &out).trim_start());
    let file = common::write_file(&dir, "both.toml", &both);
    refused_in_one_line(&["render", s(&file)], 2, &["both.toml:3", "key `volumes`"], &out);
    let file = common::write_file(
        &dir,
        "empty.toml",
        &format!("volumes = []\n[output]\nimage = {:?}\n", s(&out)),
    );
    refused_in_one_line(&["render", s(&file)], 2, &["key `volumes`", "empty"], &out);
    let bad = two_volumes("", "medium = { gg = 0.3 }", &out);
    let file = common::write_file(&dir, "unknown.toml", &bad);
    refused_in_one_line(
        &["render", s(&file)],
        2,
        &["unknown.toml:7", "volumes[1].medium.gg"],
        &out,
    );
}

#[test]
fn write_scene_round_trips_a_list() {
    let dir = tmpdir("several", "roundtrip");
    let out = dir.join("o.exr");
    let entry = "translate = [1.0, 0.0, 0.0]\nname = \"fire\"\nvisible_to_camera = false\n[volumes.medium]\ng = 0.3\nalbedo = [0.5, 0.6, 0.7]";
    let file = common::write_file(
        &dir,
        "two.toml",
        &two_volumes("[medium]\ndensity_scale = 3", entry, &out),
    );
    let written = dir.join("written.toml");
    let o = plume(&["render", s(&file), "--write-scene", s(&written)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!out.exists());
    let text = std::fs::read_to_string(&written).unwrap();
    assert_eq!(text.matches("[[volumes]]").count(), 2, "{text}");
    assert_eq!(read(&written), read(&file));
    // The library's own round trip
    let shot = read(&file);
    let again = SceneFile::parse(&file, to_toml_as_is(&shot).unwrap(), Path::new("")).unwrap().0;
    assert_eq!(again, shot);
}

/// `data/explosion.toml` as `to_toml_as_is` wrote it before scenes had several volumes,
/// without its first line (the header, which names plume's version).
const EXPLOSION_TOML: &str = r#"[volume]
file = "../out/explosion.vdb"
density_grid = "density"
temperature_grid = "temperature"
interpolation = "linear"

[emission]
source = "auto"
convention = "physical"
temperature_map = "kelvin"
temperature_cutoff = 500.0
scale = 1.0
color = [
    1.0,
    1.0,
    1.0,
]

[medium]
density_scale = 4.0
albedo = 0.800000011920929
g = 0.3

[camera]
fov = 40.0
width = 640
height = 480
up_axis = "y"
fps = 24.0

[lights]

[integrator]
method = "line-fnee"
camera_estimator = "ray-march"
camera_collision = "forced"
mis = "power"
proxy_resolution = 32
max_depth = 64
kappa = 4.0
tracking = "auto"
split = 6
split_by = "brightness"
point_lookup = "stochastic"

[render]
spp = 32
sampler = "sobol"
threads = 0
sample_order = "auto"
defer_paths = "auto"
quiet = false
progress = "none"

[farm]
overwrite = false

[output]
image = "../out/explosion.exr"
preview = "../out/explosion.png"
stats = "../out/explosion.json"
sums = false
aovs = false
denoise = true

[reading]
read_timeout = 120.0
no_isolation = false
"#;

/// The settings hash (seed 0) of `data/explosion.toml` before scenes had several volumes.
/// The hash includes plume's version, so a new version changes it: pin it again then, and
/// only then.
const EXPLOSION_HASH: (&str, &str) = ("0.1.0", "40e1b44fc21df30efa2d96577de18224");

#[test]
fn a_scene_of_one_volume_is_written_and_hashed_as_before() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/explosion.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let shot = SceneFile::parse(&path, text.clone(), Path::new("")).unwrap().0;
    let written = to_toml_as_is(&shot).unwrap();
    assert_eq!(written.split_once('\n').unwrap().1, EXPLOSION_TOML);
    if env!("CARGO_PKG_VERSION") == EXPLOSION_HASH.0 {
        assert_eq!(settings_hash(&shot, 0), EXPLOSION_HASH.1);
    }
    // The same volume as a list of one: the same pixels, so the same hash
    let listed = text.replace("[volume]", "[[volumes]]");
    let listed = SceneFile::parse(&path, listed, Path::new("")).unwrap().0;
    assert!(listed.scene.listed);
    assert_eq!(settings_hash(&listed, 0), settings_hash(&shot, 0));
    assert!(to_toml_as_is(&listed).unwrap().contains("[[volumes]]"));
}

#[test]
fn what_several_volumes_cannot_do_yet_is_refused_in_one_line_naming_the_key() {
    let dir = tmpdir("several", "refused");
    let out = dir.join("o.exr");
    let singular = "matrix = [[1, 0, 0, 0], [2, 0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]";
    let mut media = String::from("[medium]\nalbedo = 0.5\n");
    for g in 1..=8 {
        let file = s(&smoke()).to_string();
        media += &format!("[[volumes]]\nfile = {file:?}\nmedium = {{ g = 0.{g} }}\n");
    }
    let cases = [
        ("", "interpolation = \"nearest\"", "volumes[1].interpolation", "one reconstruction"),
        ("", "velocity_grid = \"vel\"", "volumes[1].velocity_grid", "motion blur"),
        ("", "albedo_grid = \"density\"", "volumes[1].albedo_grid", "albedo grid"),
        (
            "",
            "medium = { absorption_color = 0.5 }",
            "volumes[1].medium.absorption_color",
            "one volume",
        ),
        ("[integrator]\ntracking = \"null\"", "", "integrator.tracking", "regularly"),
        (&media, "", "volumes[8].medium", "at most 8"),
        ("", singular, "volumes[1].matrix", "singular"),
        ("", "medium = { albedo = [0.5, 1.5, 0.5] }", "volumes[1].medium.albedo", "[0, 1]"),
    ];
    for (i, (top, entry, key, needle)) in cases.iter().enumerate() {
        let file =
            common::write_file(&dir, &format!("case{i}.toml"), &two_volumes(top, entry, &out));
        let key = format!("key `{key}`");
        refused_in_one_line(&["render", s(&file)], 2, &[&key, needle], &out);
    }
    // The same through flags: the flag that gave the value
    let (smoke, add) = (smoke(), format!("file = {:?}", s(&common::fire())));
    for (flags, needle) in [
        (&["--tracking", "null"][..], "--tracking"),
        (&["--absorption-color", "0.5"], "--absorption-color"),
    ] {
        let mut args = vec!["render", s(&smoke), "-o", s(&out), "--add-volume", &add];
        args.extend_from_slice(flags);
        refused_in_one_line(&args, 2, &[needle], &out);
    }
    let interpolation = format!("{add}, interpolation = \"nearest\"");
    let args = ["render", s(&smoke), "-o", s(&out), "--add-volume", &interpolation];
    refused_in_one_line(&args, 2, &["--add-volume interpolation"], &out);
}

#[test]
fn add_volume_gives_the_scene_of_the_equivalent_file() {
    let dir = tmpdir("several", "add");
    let out = dir.join("o.exr");
    let keys = format!(
        "file = {:?}, translate = [1, 0, 0], name = \"fire\", medium = {{ density_scale = 2, g = 0.3 }}",
        s(&common::fire())
    );
    let by_flags = dir.join("flags.toml");
    let o = plume(&[
        "render",
        s(&smoke()),
        "-o",
        s(&out),
        "--albedo",
        "0.5",
        "--add-volume",
        &keys,
        "--write-scene",
        s(&by_flags),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let entry = "translate = [1, 0, 0]\nname = \"fire\"\nmedium = { density_scale = 2, g = 0.3 }";
    let file =
        common::write_file(&dir, "file.toml", &two_volumes("[medium]\nalbedo = 0.5", entry, &out));
    assert_eq!(read(&by_flags), read(&file));
    // Beside a scene file: appended to its list, inheriting its first volume's values
    let over = dir.join("over.toml");
    let third = format!("file = {:?}", s(&smoke()));
    let o = plume(&["render", s(&file), "--add-volume", &third, "--write-scene", s(&over)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let three = format!(
        "{}\n[[volumes]]\nfile = {:?}\n",
        two_volumes("[medium]\nalbedo = 0.5", entry, &out),
        s(&smoke())
    );
    assert_eq!(read(&over), read(&common::write_file(&dir, "three.toml", &three)));
    assert!(!out.exists());
}

#[test]
fn further_files_are_resolved_per_frame_and_a_missing_one_is_named_by_its_key() {
    let dir = tmpdir("several", "frames");
    let out = dir.join("o.####.exr");
    let sequence = common::data("sequence/openusd_smoke_######.vdb");
    let entry = format!("[[volumes]]\nfile = {:?}\n", s(&sequence));
    let text = format!("{}{entry}\n[farm]\nframes = \"2\"\n", two_volumes("", "", &out));
    let shot = read(&common::write_file(&dir, "frames.toml", &text));
    let valid: ValidShot = shot.validate().unwrap();
    let job = plume::farm::plan::Job::new(&valid).unwrap();
    let paths = plume::farm::outputs::FramePaths::resolve(&job, Some(2));
    let scene = paths.scene(job.scene());
    assert_eq!(scene.more_volumes[0].volume.file, common::fire());
    assert_eq!(
        scene.more_volumes[1].volume.file,
        common::data("sequence/openusd_smoke_000002.vdb")
    );
    assert_eq!(paths.input, smoke());
    // A further file missing for the frame: its key and path, exit 3, nothing written
    let missing = dir.join("missing.####.vdb");
    let entry = format!("[[volumes]]\nfile = {:?}\n", s(&missing));
    let text = format!("{}{entry}\n[farm]\nframes = \"7\"\n", two_volumes("", "", &out));
    let file = common::write_file(&dir, "missing.toml", &text);
    let written = dir.join("o.0007.exr");
    let needles = ["volumes[2].file", "missing.0007.vdb"];
    refused_in_one_line(&["render", s(&file), "-q"], 3, &needles, &written);
}
