//! Placing the volume in the world (`volume.translate`, `rotate`, `scale`, `matrix`,
//! applied after the file's own transform, as Blender's object matrix `T · R · S`): the
//! image of a placed volume seen by the camera placed alike is the image of the volume
//! where the file puts it, bit for bit — moved, rotated, scaled with its coefficients,
//! with motion blur (its velocities rotate with it), and from a brick cache; its settings
//! hash differs; bad placements are refused naming the key.

use crate::common;

use common::{exr_pixels, pixel_bits, plume, s, stderr, tmpdir};
use std::path::Path;

/// Renders `volume` to `dir/name.exr`, 40×30, 4 spp, with `extra` flags; the pixels' bits.
fn render(dir: &Path, name: &str, volume: &Path, extra: &[&str]) -> Vec<u32> {
    let out = dir.join(format!("{name}.exr"));
    let mut args = vec!["render", s(volume), "-o", s(&out), "--width", "40", "--height", "30"];
    args.extend_from_slice(&["--spp", "4", "-q"]);
    args.extend_from_slice(extra);
    let o = plume(&args);
    assert!(o.status.success(), "{name}: {}", stderr(&o));
    pixel_bits(&exr_pixels(&out))
}

/// The camera 5 units in front of the volume along −z, looking at its centre.
const FRONT: [&str; 4] = ["--camera-from", "0,0.2,-5", "--camera-at", "0,0.2,0"];

#[test]
fn a_placed_volume_seen_by_a_camera_placed_alike_renders_the_same_bits() {
    let dir = tmpdir("placement", "same");
    let ex = common::explosion(&dir, 24, Some(2));
    let emission_only = ["--method", "ray-march"];
    let base = render(&dir, "base", &ex, &[&FRONT[..], &emission_only[..]].concat());
    // Moved, the camera moved with it; scattering too
    let moved = ["--camera-from", "10,20.2,25", "--camera-at", "10,20.2,30"];
    let shift = ["--volume-translate", "10,20,30"];
    assert_eq!(base, render(&dir, "moved", &ex, &[&moved[..], &shift, &emission_only].concat()));
    let lit = ["--albedo", "0.8"];
    assert_eq!(
        render(&dir, "lit", &ex, &[&FRONT[..], &lit[..]].concat()),
        render(&dir, "lit_moved", &ex, &[&moved[..], &shift, &lit].concat())
    );
    // A quarter turn about y: the camera's −z becomes −x
    let turned =
        ["--camera-from", "-5,0.2,0", "--camera-at", "0,0.2,0", "--volume-rotate", "0,90,0"];
    assert_eq!(base, render(&dir, "turned", &ex, &[&turned[..], &emission_only].concat()));
    // Twice the size with half the extinction and emission per unit length
    let scaled = ["--camera-from", "0,0.4,-10", "--camera-at", "0,0.4,0", "--volume-scale", "2"];
    let halved = ["--density-scale", "0.5", "--emission-scale", "0.5"];
    assert_eq!(base, render(&dir, "scaled", &ex, &[&scaled[..], &halved, &emission_only].concat()));
    // Cycles' Object space halves them itself
    let object = ["--volume-space", "object"];
    assert_eq!(base, render(&dir, "object", &ex, &[&scaled[..], &object, &emission_only].concat()));
    // The same turn as a matrix, rows as written
    let matrix = ["--volume-matrix", "0,0,1,0, 0,1,0,0, -1,0,0,0, 0,0,0,1"];
    let by_matrix = render(
        &dir,
        "matrix",
        &ex,
        &[&["--camera-from", "-5,0.2,0", "--camera-at", "0,0.2,0"][..], &matrix, &emission_only]
            .concat(),
    );
    assert_eq!(base, by_matrix);
    assert_ne!(
        base,
        render(&dir, "unplaced", &ex, &[&turned[..2], &turned[2..4], &emission_only].concat())
    );
}

#[test]
fn velocities_turn_with_the_volume_under_motion_blur() {
    let dir = tmpdir("placement", "motion");
    let ex = common::explosion(&dir, 24, Some(2));
    let blur = ["--velocity-grid", "velocity", "--shutter", "-0.5,0.5", "--velocity-scale", "20"];
    let base = render(&dir, "base", &ex, &[&FRONT[..], &blur[..]].concat());
    let turned =
        ["--camera-from", "-5,0.2,0", "--camera-at", "0,0.2,0", "--volume-rotate", "0,90,0"];
    assert_eq!(base, render(&dir, "turned", &ex, &[&turned[..], &blur].concat()));
    // The blur shows: a still render differs
    assert_ne!(base, render(&dir, "still", &ex, &FRONT));
}

#[test]
fn a_brick_cache_is_placed_as_its_vdb_and_the_placement_is_in_the_settings_hash() {
    let dir = tmpdir("placement", "cache");
    let ex = common::explosion(&dir, 24, Some(2));
    let cache = dir.join("ex.plume");
    let o = plume(&["prepare", s(&ex), "-o", s(&cache)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let placed =
        ["--volume-rotate", "10,20,30", "--volume-translate", "0.5,0,0", "--albedo", "0.8"];
    assert_eq!(
        render(&dir, "vdb", &ex, &[&FRONT[..], &placed[..]].concat()),
        render(&dir, "cache", &cache, &[&FRONT[..], &placed[..]].concat())
    );
    let base = ["render", s(&ex), "--width", "16", "--height", "12", "--spp", "2", "-q", "--stats"];
    let hashes = common::settings_hashes(
        &dir,
        &base,
        "--volume-translate",
        &[("none", None), ("zero", Some("0,0,0")), ("moved", Some("1,0,0"))],
    );
    assert_ne!(hashes[0], hashes[2], "the placement is not in the settings hash");
    assert_ne!(hashes[1], hashes[2]);
}

#[test]
fn bad_placements_are_refused_naming_the_key() {
    let dir = tmpdir("placement", "bad");
    let ex = common::explosion(&dir, 16, Some(2));
    let out = dir.join("x.exr");
    let render = ["render", s(&ex), "-o", s(&out)];
    for (extra, flag, needle) in [
        (
            &["--volume-matrix", "1,0,0,0, 2,0,0,0, 0,0,1,0, 0,0,0,1"][..],
            "--volume-matrix",
            "singular",
        ),
        (
            &["--volume-matrix", "1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,1,1"][..],
            "--volume-matrix",
            "not [0, 0, 0, 1]",
        ),
        (
            &[
                "--volume-matrix",
                "1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1",
                "--volume-translate",
                "1,0,0",
            ][..],
            "--volume-matrix",
            "not both",
        ),
        (&["--volume-scale", "1,0,2"][..], "--volume-scale", "flattens"),
    ] {
        let o = plume(&[&render[..], extra].concat());
        assert_eq!(o.status.code(), Some(2), "{extra:?}: {}", stderr(&o));
        let err = stderr(&o);
        assert!(err.contains(flag) && err.contains(needle), "{extra:?}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(!out.exists());
    }
    // In a scene file: the line and the key
    let file = dir.join("singular.toml");
    let text = format!(
        "[volume]\nfile = {:?}\nmatrix = [[0, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]\n[output]\nimage = {:?}\n",
        s(&ex),
        s(&out)
    );
    std::fs::write(&file, text).unwrap();
    let o = plume(&["render", s(&file)]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("key `volume.matrix`") && stderr(&o).contains("singular"),
        "{}",
        stderr(&o)
    );
    assert!(!out.exists());
}
