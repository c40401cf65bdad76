//! Light groups of volumes (`group`, `--volume-group`; `plume_engine::integrator`'s groups
//! module): with `--aovs` a volume's light, seen directly and scattered, is the layer of its
//! group. The beauty does not change. Where grouped volumes overlap the layers sum to the
//! beauty, per pixel to rounding, with nothing left over when every emitter has a group
//! (so each group's walks give exactly the main walk's share), under line-fnee and
//! point-nee, and without scattering a group's layer is the bits of the render in which
//! only it emits; volumes without a group keep `emission` and `scattered`; one volume with
//! a group moves its light to that layer; a bad group is one line naming its key.

use crate::common;

use common::{plume, refused_in_one_line, s, stderr, tmpdir};

type Channels = std::collections::BTreeMap<String, Vec<f32>>;

/// The second volume, overlapping the first: moved, turned, denser, scattering
/// differently, with `keys` added.
fn second(file: &std::path::Path, keys: &str) -> String {
    format!(
        r#"file = "{}", translate = [0.2, 0.1, 0.0], rotate = [0, 0, 30], scale = 0.8, medium = {{ density_scale = 6, albedo = [0.5, 0.6, 0.7], g = -0.3 }}{keys}"#,
        s(file)
    )
}

/// Render `ex` and the second volume with `keys`, `extra` flags and AOVs; every channel.
fn render(
    dir: &std::path::Path,
    name: &str,
    ex: &std::path::Path,
    keys: &str,
    extra: &[&str],
) -> Channels {
    let out = dir.join(format!("{name}.exr"));
    let add = second(ex, keys);
    let mut args = vec!["render", s(ex), "-o", s(&out), "--width", "24", "--height", "16"];
    args.extend_from_slice(&["--spp", "8", "--albedo", "0.8", "--g", "0.3", "--aovs", "-q"]);
    args.extend_from_slice(&["--add-volume", &add]);
    args.extend_from_slice(extra);
    let o = plume(&args);
    assert!(o.status.success(), "{name}: {}", stderr(&o));
    common::channels(&out)
}

fn layer<'a>(c: &'a Channels, name: &str) -> &'a [f32] {
    c.get(name).unwrap_or_else(|| panic!("no channel {name} in {:?}", c.keys()))
}

/// Per pixel and colour channel, the sum of `layers` is the beauty to rounding; each of
/// them holds light.
#[track_caller]
fn assert_layers_sum_to_beauty(label: &str, c: &Channels, layers: &[&str]) {
    for ch in ["R", "G", "B"] {
        let beauty = layer(c, ch);
        for (p, &b) in beauty.iter().enumerate() {
            let sum: f64 =
                layers.iter().map(|l| f64::from(layer(c, &format!("{l}.{ch}"))[p])).sum();
            let want = f64::from(b);
            assert!(
                (sum - want).abs() <= 2e-6 * want.abs() + 1e-30,
                "{label} {ch} pixel {p}: {sum} vs {want}"
            );
        }
    }
    for l in layers {
        assert!(layer(c, &format!("{l}.R")).iter().sum::<f32>() > 0.0, "{label}: {l} is dark");
    }
}

/// The beauty's channels.
fn beauty(c: &Channels) -> Vec<Vec<u32>> {
    ["R", "G", "B", "A"]
        .iter()
        .map(|ch| layer(c, ch).iter().map(|v| v.to_bits()).collect())
        .collect()
}

#[test]
fn overlapping_groups_split_the_light_and_leave_the_beauty_alone() {
    let dir = tmpdir("volume_groups", "overlap");
    let ex = common::explosion(&dir, 24, Some(2));
    let shell = r#", group = "shell", emission = { scale = 0.5 }"#;
    for method in ["line-fnee", "point-nee"] {
        let m = ["--method", method, "--volume-group", "core"];
        let grouped = render(&dir, "grouped", &ex, shell, &m);
        assert_layers_sum_to_beauty(method, &grouped, &["core", "shell"]);
        for l in ["emission", "scattered"] {
            assert!(layer(&grouped, &format!("{l}.R")).iter().all(|&v| v == 0.0), "{method}: {l}");
        }
        let plain = render(&dir, "plain", &ex, ", emission = { scale = 0.5 }", &m[..2]);
        assert_eq!(beauty(&grouped), beauty(&plain), "{method}: groups changed the beauty");
        let three = render(&dir, "three", &ex, shell, &[&m[..], &["--threads", "3"]].concat());
        assert_eq!(common::bits(&grouped), common::bits(&three), "{method}: threads");
    }
    // A volume without a group keeps `emission` and `scattered`, beside the group's layer
    let mixed = render(&dir, "mixed", &ex, shell, &[]);
    assert_layers_sum_to_beauty("mixed", &mixed, &["emission", "scattered", "shell"]);
}

#[test]
fn without_scattering_a_group_is_the_render_in_which_only_it_emits() {
    let dir = tmpdir("volume_groups", "camera");
    let ex = common::explosion(&dir, 24, Some(2));
    let flags = ["--max-depth", "0", "--volume-group", "core"];
    let both = render(&dir, "both", &ex, r#", group = "shell""#, &flags);
    let alone =
        render(&dir, "alone", &ex, r#", group = "shell", emission = { scale = 0 }"#, &flags);
    for ch in ["R", "G", "B"] {
        let name = format!("core.{ch}");
        let bits = |c: &Channels| layer(c, &name).iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&both), bits(&alone), "{name}");
    }
}

#[test]
fn one_volume_with_a_group_moves_its_light_to_that_layer() {
    let dir = tmpdir("volume_groups", "one");
    let ex = common::explosion(&dir, 24, Some(2));
    let run = |name: &str, extra: &[&str]| {
        let out = dir.join(format!("{name}.exr"));
        let mut args = vec!["render", s(&ex), "-o", s(&out), "--width", "24", "--height", "16"];
        args.extend_from_slice(&["--spp", "8", "--albedo", "0.8", "--aovs", "-q"]);
        args.extend_from_slice(extra);
        let o = plume(&args);
        assert!(o.status.success(), "{name}: {}", stderr(&o));
        common::channels(&out)
    };
    let plain = run("plain", &[]);
    let grouped = run("grouped", &["--volume-group", "fire"]);
    assert_eq!(beauty(&grouped), beauty(&plain));
    for ch in ["R", "G", "B"] {
        let fire = layer(&grouped, &format!("fire.{ch}"));
        let (e, sc) =
            (layer(&plain, &format!("emission.{ch}")), layer(&plain, &format!("scattered.{ch}")));
        for p in 0..fire.len() {
            let want = f64::from(e[p]) + f64::from(sc[p]);
            assert!((f64::from(fire[p]) - want).abs() <= 1e-6 * want + 1e-30, "{ch} pixel {p}");
        }
        assert!(layer(&grouped, &format!("emission.{ch}")).iter().all(|&v| v == 0.0));
    }
}

#[test]
fn a_bad_group_is_refused_naming_its_key() {
    let dir = tmpdir("volume_groups", "refused");
    let out = dir.join("o.exr");
    let ex = common::explosion(&dir, 16, Some(2));
    let add = second(&ex, r#", group = "emission""#);
    let args = ["render", s(&ex), "-o", s(&out), "--add-volume", &add];
    refused_in_one_line(&args, 2, &["--add-volume group", "fixed layer"], &out);
    let text = format!(
        "[[volumes]]\nfile = {:?}\n[[volumes]]\nfile = {:?}\ngroup = \"sum\"\n[output]\nimage = {:?}\n",
        s(&ex),
        s(&ex),
        s(&out)
    );
    let file = dir.join("scene.toml");
    std::fs::write(&file, text).unwrap();
    refused_in_one_line(&["render", s(&file)], 2, &["volumes[1].group", "fixed layer"], &out);
    let args = ["render", s(&ex), "-o", s(&out), "--volume-group", "a b"];
    refused_in_one_line(&args, 2, &["--volume-group", "letters"], &out);
}
