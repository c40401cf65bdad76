//! Instances (`instances = [{ translate = … }, …]` on a volume): a volume with instances
//! renders as the same file listed once per instance at the instance's whole placement
//! (`instance · entry`), also in object space and with FNEE; the same bits at any thread
//! count; bad instances refused in one line naming the key (exit 2, nothing written);
//! instances making a scene of one volume several; the scene file's round trip; and a
//! thousand instances sharing one volume's data.

use crate::common;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use common::{exr_pixels, plume, refused_in_one_line, s, stderr, tmpdir};
use plume::farm::fingerprint::settings_hash;
use plume_engine::integrator::AnyScene;
use plume_engine::overlap::member::Member;
use plume_scene::file::{to_toml_as_is, SceneFile};
use plume_scene::placement::{instance_placement, Placement};
use plume_scene::{Scale, Shot};
use plume_volume::trilinear::Trilinear;

/// A scene file rendering `volumes` (the volume tables) with `top` before them, 48×36 at
/// 8 spp, seed 7, to `dir/name.exr`; returns the file.
fn scene(dir: &Path, name: &str, top: &str, volumes: &str) -> PathBuf {
    let out = dir.join(format!("{name}.exr"));
    let text = format!(
        "{top}\n{volumes}\n[camera]\nwidth = 48\nheight = 36\n\n[render]\nspp = 8\nseed = 7\n\n[output]\nimage = {:?}\n",
        s(&out)
    );
    common::write_file(dir, &format!("{name}.toml"), &text)
}

/// Renders the scene file `file` with `extra` flags; its RGBA pixels.
fn render(file: &Path, extra: &[&str]) -> Vec<[f32; 4]> {
    let mut args = vec!["render", s(file), "-q", "--overwrite"];
    args.extend_from_slice(extra);
    let o = plume(&args);
    assert!(o.status.success(), "{}: {}", file.display(), stderr(&o));
    let text = std::fs::read_to_string(file).unwrap();
    let shot = SceneFile::parse(file, text, &plume_core::fs::parent_dir(file)).unwrap().0;
    exr_pixels(&shot.settings.output.image)
}

/// The instances of the tests: moved right; moved left, turned and halved.
const INSTANCES: [&str; 2] =
    ["{ translate = [12, 0, 0] }", "{ translate = [-12, 0, 0], rotate = [0, 0, 90], scale = 0.5 }"];

/// `INSTANCES` as placements.
fn instance_placements() -> [Placement; 2] {
    [
        Placement { translate: Some([12.0, 0.0, 0.0]), ..Placement::default() },
        Placement {
            translate: Some([-12.0, 0.0, 0.0]),
            rotate: Some([0.0, 0.0, 90.0]),
            scale: Some(Scale::Uniform(0.5)),
            matrix: None,
        },
    ]
}

/// The entry's own placement under the instances.
const ENTRY: &str = "rotate = [30, 0, 0]\ntranslate = [0, 3, 0]";

/// `ENTRY` as a placement.
fn entry_placement() -> Placement {
    Placement {
        translate: Some([0.0, 3.0, 0.0]),
        rotate: Some([30.0, 0.0, 0.0]),
        ..Placement::default()
    }
}

/// An affine map as a scene file's `matrix` value, rows as written.
fn matrix_rows(m: glam::DAffine3) -> String {
    let (a, t) = (m.matrix3, m.translation);
    let row = |r: usize| {
        let c = [a.x_axis[r], a.y_axis[r], a.z_axis[r], t[r]];
        format!("[{:?}, {:?}, {:?}, {:?}]", c[0], c[1], c[2], c[3])
    };
    format!("[{}, {}, {}, [0.0, 0.0, 0.0, 1.0]]", row(0), row(1), row(2))
}

/// The volume tables of one entry of the fire with `entry` keys and `INSTANCES`, and of
/// the same fire listed once per instance at the whole placement `instance · entry`.
fn instanced_and_listed(entry: &str) -> (String, String) {
    let fire = s(&common::fire()).to_string();
    let instanced =
        format!("[[volumes]]\nfile = {fire:?}\n{entry}\ninstances = [{}]\n", INSTANCES.join(", "));
    let own = entry_placement().transform("volume").unwrap();
    let listed: String = instance_placements()
        .iter()
        .map(|p| {
            let whole = instance_placement(own, p.transform("volume").unwrap()).unwrap();
            format!("[[volumes]]\nfile = {fire:?}\nmatrix = {}\n{}\n", matrix_rows(whole), {
                // The entry's other keys than its placement
                entry
                    .lines()
                    .filter(|l| !["rotate", "translate"].iter().any(|k| l.starts_with(k)))
                    .collect::<Vec<_>>()
                    .join("\n")
            })
        })
        .collect();
    (instanced, listed)
}

/// `a` and `b` have the same bits, and enough pixels lit to mean something.
///
/// The two scenes compute differently in `f64`: an instance carries each ray into the
/// entry's frame (`Instance::ray`: the origin through `base_from_world`, the direction
/// normalised again) and its FNEE proxy is the entry's, carried out (its density through
/// the map's Jacobian), while a listed volume's placement is folded into its own index
/// transform and its proxy built from its placed voxels. They agree to the last bits of
/// `f64`, far below a pixel's `f32` rounding, and no sampling decision (a collision, a
/// proxy cell) turns on such a difference in these scenes, so the pixels are the same
/// bits. Should a change make one decision turn, the images would agree to about 1e-5
/// per pixel and this comparison would have to become one.
#[track_caller]
fn assert_same_pixels(label: &str, a: &[[f32; 4]], b: &[[f32; 4]]) {
    assert!(common::pixel_bits(a) == common::pixel_bits(b), "{label}: the pixels differ");
    let lit = a.iter().filter(|p| p[0] > 0.0).count();
    assert!(lit > a.len() / 20, "{label}: only {lit} pixels lit");
}

#[test]
fn instances_render_as_the_volume_listed_at_each_placement() {
    let dir = tmpdir("instances", "listed");
    let emitting = "[medium]\ndensity_scale = 2";
    let (instanced, listed) = instanced_and_listed(ENTRY);
    let a = render(&scene(&dir, "instanced", emitting, &instanced), &[]);
    let b = render(&scene(&dir, "listed", emitting, &listed), &[]);
    assert_same_pixels("world space", &a, &b);
    // Object space: each instance's coefficients follow its whole placement's scale
    let (object, object_listed) = instanced_and_listed(&format!("{ENTRY}\nspace = \"object\""));
    let c = render(&scene(&dir, "object", emitting, &object), &[]);
    let d = render(&scene(&dir, "object_listed", emitting, &object_listed), &[]);
    assert_same_pixels("object space", &c, &d);
    // The halved instance is twice as dense per unit length there
    assert!(common::pixel_bits(&a) != common::pixel_bits(&c));
    // The entry's own placement counts under the instances
    let (unplaced, _) = instanced_and_listed("");
    let e = render(&scene(&dir, "unplaced", emitting, &unplaced), &[]);
    assert!(common::pixel_bits(&a) != common::pixel_bits(&e));
}

#[test]
fn instances_scatter_with_fnee_and_nee_as_the_volume_listed_at_each_placement() {
    let dir = tmpdir("instances", "fnee");
    let lit = "[medium]\ndensity_scale = 2\nalbedo = 0.8\ng = 0.3";
    for (name, entry) in
        [("world", ENTRY.to_string()), ("object", format!("{ENTRY}\nspace = \"object\""))]
    {
        let (instanced, listed) = instanced_and_listed(&entry);
        let (instanced, listed) = (
            scene(&dir, name, lit, &instanced),
            scene(&dir, &format!("{name}_listed"), lit, &listed),
        );
        for method in ["line-fnee", "point-nee"] {
            let a = render(&instanced, &["--method", method]);
            let b = render(&listed, &["--method", method]);
            assert_same_pixels(&format!("{name} {method}"), &a, &b);
        }
    }
}

#[test]
fn an_instanced_scene_renders_the_same_bits_at_any_thread_count() {
    let dir = tmpdir("instances", "threads");
    let (instanced, _) = instanced_and_listed(ENTRY);
    let lit = "[medium]\ndensity_scale = 2\nalbedo = 0.8\ng = 0.3";
    let file = scene(&dir, "instanced", lit, &instanced);
    let one = common::pixel_bits(&render(&file, &["--threads", "1"]));
    let three = common::pixel_bits(&render(&file, &["--threads", "3"]));
    assert_eq!(one, three);
}

#[test]
fn bad_instances_are_refused_in_one_line_naming_the_key() {
    let dir = tmpdir("instances", "refused");
    let out = dir.join("o.exr");
    let fire = s(&common::fire()).to_string();
    let singular = "{ matrix = [[1, 0, 0, 0], [2, 0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]] }";
    let one = |instances: &str| format!("[volume]\nfile = {fire:?}\ninstances = {instances}\n");
    let two = |instances: &str| {
        format!(
            "[[volumes]]\nfile = {fire:?}\n[[volumes]]\nfile = {fire:?}\ninstances = {instances}\n"
        )
    };
    let cases = [
        (one("[]"), "volume.instances", "empty"),
        (two("[]"), "volumes[1].instances", "empty"),
        (two(&format!("[{}, {singular}]", INSTANCES[0])), "volumes[1].instances[1].matrix", "singular"),
        (one("[{ scale = [1, 0, 1] }]"), "volume.instances[0].scale", "flattens"),
        (one("[{ matrix = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [1, 0, 0, 1]] }]"), "volume.instances[0].matrix", "[0, 0, 0, 1]"),
        (one("[{ translate = [1, 0, 0], matrix = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]] }]"), "volume.instances[0].matrix", "not both"),
        (one("[{ translat = [1, 0, 0] }]"), "volume.instances[0].translat", "unknown field"),
        (one("[{ scale = \"big\" }]"), "volume.instances[0].scale", "a number or [x, y, z]"),
    ];
    for (i, (volumes, key, needle)) in cases.iter().enumerate() {
        let file = common::write_file(
            &dir,
            &format!("case{i}.toml"),
            &format!("{volumes}\n[output]\nimage = {:?}\n", s(&out)),
        );
        let key = format!("key `{key}`");
        refused_in_one_line(&["render", s(&file)], 2, &[&key, needle], &out);
    }
    // Through --add-volume: the flag and the key inside it
    let add = format!("file = {fire:?}, instances = [{{ scale = 0 }}]");
    let args = ["render", &fire, "-o", s(&out), "--add-volume", &add];
    refused_in_one_line(&args, 2, &["--add-volume instances[0].scale"], &out);
}

#[test]
fn instances_make_a_scene_of_one_volume_several() {
    let dir = tmpdir("instances", "several");
    let out = dir.join("o.exr");
    let fire = s(&common::fire()).to_string();
    let volume = format!("[volume]\nfile = {fire:?}\ninstances = [{}]\n", INSTANCES[0]);
    for (top, entry, key, needle) in [
        ("[integrator]\ntracking = \"null\"", "", "integrator.tracking", "regularly"),
        ("", "velocity_grid = \"vel\"", "volume.velocity_grid", "motion blur"),
        ("", "albedo_grid = \"density\"", "volume.albedo_grid", "albedo grid"),
        ("[medium]\nabsorption_color = 0.5", "", "medium.absorption_color", "one volume"),
    ] {
        let text = format!("{top}\n{volume}{entry}\n[output]\nimage = {:?}\n", s(&out));
        let file = common::write_file(&dir, "case.toml", &text);
        let key = format!("key `{key}`");
        refused_in_one_line(&["render", s(&file)], 2, &[&key, needle], &out);
    }
    // The same scene without instances may
    let text = format!(
        "[integrator]\ntracking = \"null\"\n[volume]\nfile = {fire:?}\n[output]\nimage = {:?}\n",
        s(&out)
    );
    let shot = SceneFile::parse(Path::new("x.toml"), text, Path::new("")).unwrap().0;
    assert!(!shot.scene.is_several());
    assert!(shot.validate().is_ok());
}

#[test]
fn instances_round_trip_and_are_in_the_settings_hash() {
    let dir = tmpdir("instances", "roundtrip");
    let (instanced, _) = instanced_and_listed(ENTRY);
    let file = scene(&dir, "instanced", "", &instanced);
    let written = dir.join("written.toml");
    let o = plume(&["render", s(&file), "--write-scene", s(&written)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let read = |p: &Path| SceneFile::read(p).unwrap().0;
    assert_eq!(read(&written), read(&file));
    let shot = read(&file);
    assert_eq!(shot.scene.placed_volume_count(), 2);
    assert!(shot.scene.is_several());
    let again = SceneFile::parse(&file, to_toml_as_is(&shot).unwrap(), Path::new("")).unwrap().0;
    assert_eq!(again, shot);
    // A single volume given as [volume] with instances, and through --add-volume
    let fire = s(&common::fire()).to_string();
    let one = scene(
        &dir,
        "one",
        "",
        &format!("[volume]\nfile = {fire:?}\ninstances = [{}]\n", INSTANCES.join(", ")),
    );
    let o = plume(&["render", s(&one), "--write-scene", s(&written)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(read(&written), read(&one));
    let add = format!("file = {fire:?}, instances = [{}]", INSTANCES.join(", "));
    let o = plume(&["render", s(&one), "--add-volume", &add, "--write-scene", s(&written)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let added = read(&written);
    assert_eq!(added.scene.more_volumes[0].volume.instances, Some(instance_placements().to_vec()));
    // Instances change pixels: in the hash, and each one's placement with it
    let mut plain: Shot = read(&one);
    let hash = settings_hash(&plain, 0);
    plain.scene.volume.instances = None;
    assert_ne!(settings_hash(&plain, 0), hash);
    let mut moved = read(&one);
    moved.scene.volume.instances.as_mut().unwrap()[1].translate = Some([-13.0, 0.0, 0.0]);
    assert_ne!(settings_hash(&moved, 0), hash);
}

/// What a thousand instances of one volume cost, measured on the loaded scene: every
/// member shares one field (`Arc::ptr_eq`: the volume's bricks are in memory once) and
/// every placed proxy one proxy grid; what each instance adds is its member
/// (`size_of::<Member<Trilinear>>`, 320 bytes, and its scattering class) and its placed
/// proxy as the mixture counts it (`ProxyMixture::memory_bytes` less the shared grid, 288
/// bytes), plus a leaf in each of two R*-trees (members' boxes, proxies' emitting boxes;
/// bounded here by 128 bytes each: a box of six `f64`, an index, the tree's share of
/// nodes): under 1 KB, against 177 KB for the volume's bricks. Not the process's resident
/// memory, which the other tests running in this process would blur.
#[test]
fn a_thousand_instances_share_one_volume() {
    let dir = tmpdir("instances", "thousand");
    let mut shot = Shot::new(common::fire(), dir.join("o.exr"));
    shot.scene.medium.albedo = Some(plume_scene::Albedo::Grey(0.8));
    let n = 1000;
    let grid: Vec<Placement> = (0..n)
        .map(|i| {
            let (x, y, z) = (i % 10, (i / 10) % 10, i / 100);
            Placement {
                translate: Some([f64::from(x) * 20.0, f64::from(y) * 20.0, f64::from(z) * 40.0]),
                ..Placement::default()
            }
        })
        .collect();
    shot.scene.volume.instances = Some(grid);
    let shot = shot.validate().unwrap();
    let loaded =
        plume::load::load_scene(&shot.scene, &common::fire(), &shot.settings, None).unwrap();
    let AnyScene::LinearVolumes(scene) = &loaded.scene else {
        panic!("an instanced volume loads as several volumes")
    };
    let members = scene.field.members();
    assert_eq!(members.len(), n as usize);
    assert!(members.iter().all(|m| Arc::ptr_eq(&m.field, &members[0].field)));
    assert_eq!(Arc::strong_count(&members[0].field), n as usize);
    assert!(members.iter().all(|m| m.instance.is_some()));
    let one_volume = plume_volume::Field::data_bytes(&*members[0].field);
    let mixture = scene.lights.proxies.as_ref().expect("the fire emits and scatters");
    let proxies: Vec<_> = mixture.proxies().map(|(p, _)| Arc::clone(&p.proxy)).collect();
    assert_eq!(proxies.len(), n as usize);
    assert!(proxies.iter().all(|p| Arc::ptr_eq(p, &proxies[0])));
    // Equal weights: translations keep each instance's power
    let pmf: Vec<f64> = mixture.proxies().map(|(_, p)| p).collect();
    assert!(pmf.iter().all(|p| (p - 1.0 / f64::from(n)).abs() < 1e-12));
    let per_placed_proxy = (mixture.memory_bytes() - proxies[0].memory_bytes()) / n as usize;
    let member = std::mem::size_of::<Member<Trilinear>>() + std::mem::size_of::<Option<usize>>();
    let per_instance = member + per_placed_proxy + 2 * 128;
    assert!(per_instance < 1024, "{per_instance} bytes per instance");
    assert!(one_volume > 100 * per_instance, "the volume itself: {one_volume} bytes");
}
