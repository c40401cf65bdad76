//! Several volumes through the binary (`--add-volume`, `[[volumes]]`): the same bits on
//! any number of threads, from tiles and sample ranges merged, and from a resumed render,
//! light-group layers included;
//! a volume hidden from the camera leaves it seeing the other alone; what goes wrong in one
//! volume's file is one line naming that volume's key, with nothing written; a small
//! volume leaves the rest of the memory budget to a large one.

use std::path::Path;

use crate::common;

use common::{plume, s, stderr, tmpdir};

type Bits = std::collections::BTreeMap<String, Vec<u32>>;

/// The second volume: the explosion moved, turned and scaled, denser, scattering
/// differently and emitting half as much.
fn second(file: &std::path::Path) -> String {
    format!(
        r#"file = "{}", translate = [0.3, 0.1, 0.0], rotate = [0, 0, 30], scale = 0.8, medium = {{ density_scale = 6, albedo = [0.5, 0.6, 0.7], g = -0.3 }}, emission = {{ scale = 0.5 }}"#,
        s(file)
    )
}

/// Render the explosion `ex` with `extra` flags; every channel's bits.
fn render_bits(dir: &std::path::Path, name: &str, ex: &std::path::Path, extra: &[&str]) -> Bits {
    let out = dir.join(format!("{name}.exr"));
    let mut args = vec!["render", s(ex), "-o", s(&out), "--width", "24", "--height", "16"];
    args.extend_from_slice(&["--albedo", "0.8", "--g", "0.3", "--aovs", "-q"]);
    args.extend_from_slice(extra);
    let o = plume(&args);
    assert!(o.status.success(), "{name}: {}", stderr(&o));
    common::bits(&common::channels(&out))
}

#[test]
fn several_volumes_give_the_same_bits_across_threads_parts_and_resumes() {
    let dir = tmpdir("overlap", "binary");
    let ex = common::explosion(&dir, 24, Some(2));
    // In a light group of its own: its layer, the first volume's `emission` and
    // `scattered`, are walked apart and must merge and resume as the beauty does
    let add = format!("{}, group = \"second\"", second(&ex));
    let with = |extra: &[&'static str]| -> Vec<String> {
        let mut v: Vec<String> = vec!["--add-volume".into(), add.clone()];
        v.extend(extra.iter().map(|x| (*x).to_string()));
        v
    };
    let render = |name: &str, extra: &[&'static str]| {
        let args = with(extra);
        render_bits(&dir, name, &ex, &args.iter().map(String::as_str).collect::<Vec<_>>())
    };
    let one = render("one", &["--spp", "4", "--threads", "1"]);
    assert!(one.contains_key("second.R"), "{:?}", one.keys());
    assert_eq!(one, render("three", &["--spp", "4", "--threads", "3"]));
    assert_ne!(one, render_bits(&dir, "alone", &ex, &["--spp", "4", "--threads", "1"]));
    // Classic NEE over the volumes' tables, too
    let nee = render("nee1", &["--spp", "4", "--threads", "1", "--method", "point-nee"]);
    assert_eq!(nee, render("nee3", &["--spp", "4", "--threads", "3", "--method", "point-nee"]));
    assert_ne!(nee, one);
    // Two tiles × two sample ranges, merged
    let mut parts = Vec::new();
    for tile in ["0/2", "1/2"] {
        for range in ["0..1", "1..4"] {
            let name = format!("part_{}_{}", &tile[..1], &range[..1]);
            let (tile, range): (&'static str, &'static str) = (tile, range);
            render(&name, &["--tile", tile, "--sample-range", range]);
            parts.push(dir.join(format!("{name}.exr")));
        }
    }
    let merged = dir.join("merged.exr");
    let mut args = vec!["merge", "-o", s(&merged), "-q"];
    args.extend(parts.iter().map(|p| s(p)));
    let o = plume(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(one, common::bits(&common::channels(&merged)), "merged parts differ");
    // Two samples with sums, continued to four
    render("resumed", &["--spp", "2", "--sums"]);
    assert_eq!(one, render("resumed", &["--spp", "4"]), "resumed differs");
}

#[test]
fn a_volume_hidden_from_the_camera_leaves_the_other_alone_in_view() {
    // Without scattering, a hidden second volume changes nothing the camera sees
    let dir = tmpdir("overlap", "hidden");
    let ex = common::explosion(&dir, 16, Some(2));
    // A camera of its own: framing would follow the two volumes' box
    let spp = [
        "--spp",
        "2",
        "--albedo",
        "0",
        "--threads",
        "1",
        "--camera-from",
        "0.5,0.4,3",
        "--camera-at",
        "0,0,0",
    ];
    let out = |name: &str| dir.join(format!("{name}.exr"));
    let alone = {
        let o = plume(
            &[
                &[
                    "render",
                    s(&ex),
                    "-o",
                    s(&out("alone")),
                    "--width",
                    "16",
                    "--height",
                    "12",
                    "-q",
                ][..],
                &spp,
            ]
            .concat(),
        );
        assert!(o.status.success(), "{}", stderr(&o));
        common::exr_pixels(&out("alone"))
    };
    let hidden = format!(
        r#"file = "{}", translate = [0.3, 0.1, 0.0], medium = {{ density_scale = 6, albedo = 0 }}, visible_to_camera = false"#,
        s(&ex)
    );
    let o =
        plume(
            &[
                &[
                    "render",
                    s(&ex),
                    "-o",
                    s(&out("hidden")),
                    "--width",
                    "16",
                    "--height",
                    "12",
                    "-q",
                ][..],
                &spp,
                &["--add-volume", &hidden],
            ]
            .concat(),
        );
    assert!(o.status.success(), "{}", stderr(&o));
    let seen = common::exr_pixels(&out("hidden"));
    assert_eq!(alone.len(), seen.len());
    for (a, b) in alone.iter().zip(&seen) {
        for c in 0..4 {
            assert!((a[c] - b[c]).abs() <= 1e-5 * a[c].abs().max(1e-3), "{a:?} vs {b:?}");
        }
    }
}

#[test]
fn a_fault_in_one_volume_names_its_key_and_writes_nothing() {
    let dir = tmpdir("overlap", "faults");
    let ex = common::explosion(&dir, 16, Some(2));
    let out = dir.join("x.exr");
    let scene = |body: &str| {
        let path = dir.join("shot.toml");
        let text = format!(
            "[[volumes]]\nfile = \"{f}\"\n\n[[volumes]]\nfile = \"{f}\"\n{body}\n\n[camera]\nwidth = 16\nheight = 12\n\n[output]\nimage = \"{o}\"\n",
            f = s(&ex),
            o = s(&out)
        );
        std::fs::write(&path, text).unwrap();
        path
    };
    for (body, key, code) in [
        ("density_grid = \"smoke\"", "volumes[1].density_grid", 3),
        ("file = \"missing.vdb\"", "volumes[1].file", 3),
        (
            "matrix = [[1, 0, 0, 0], [0, 0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]",
            "volumes[1].matrix",
            2,
        ),
        ("medium = { albedo = [0.5, 1.5, 0.2] }", "volumes[1].medium.albedo", 2),
    ] {
        // `file` given twice in one entry is a TOML error: the missing file replaces it
        let body_scene = if body.starts_with("file") {
            let path = dir.join("shot.toml");
            std::fs::write(
                &path,
                format!(
                    "[[volumes]]\nfile = \"{f}\"\n\n[[volumes]]\n{body}\n\n[camera]\nwidth = 16\nheight = 12\n\n[output]\nimage = \"{o}\"\n",
                    f = s(&ex),
                    o = s(&out)
                ),
            )
            .unwrap();
            path
        } else {
            scene(body)
        };
        let o = plume(&["render", s(&body_scene), "--spp", "1", "-q"]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(code), "{body}: {err}");
        assert!(err.contains(key), "{body}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(!out.exists(), "{body}: an output was written");
    }
}

#[test]
fn a_small_volume_leaves_the_rest_of_the_budget_to_a_large_one() {
    // Each volume needs four times its file to be read whole; the small one takes its
    // need, the large one the rest: read whole at exactly both needs, paged one byte below
    // (an equal share, half, would page it at either)
    let dir = tmpdir("several", "shares");
    let (large, small) = (dir.join("large.vdb"), dir.join("small.vdb"));
    common::synth_explosion(&large, 48, Some(2));
    common::synth_explosion(&small, 16, Some(2));
    let need = |p: &Path| 4 * std::fs::metadata(p).unwrap().len();
    let both = need(&large) + need(&small);
    let add = format!("file = {:?}, translate = [0.5, 0, 0]", s(&small));
    for (budget, paged) in [(both, false), (both - 1, true)] {
        let cache = dir.join(format!("cache{budget}"));
        let out = dir.join(format!("o{budget}.exr"));
        let budget = budget.to_string();
        let o = plume(&[
            "render",
            s(&large),
            "--add-volume",
            &add,
            "--memory-budget",
            &budget,
            "--cache-dir",
            s(&cache),
            "--width",
            "16",
            "--height",
            "12",
            "--spp",
            "1",
            "-o",
            s(&out),
            "-q",
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        let made = match cache.exists() {
            true => common::names_in(&cache, |n| n.ends_with(".plume")),
            false => Vec::new(),
        };
        assert_eq!(!made.is_empty(), paged, "budget {budget}: {made:?}");
        assert!(made.iter().all(|n| n.starts_with("large")), "{made:?}");
    }
}
