//! Scenes of several volumes as data: `[[volumes]]` in scene files with what entries
//! inherit, the keys that name each volume, the round trip through `to_toml`, and the
//! validation of every volume and of what several volumes cannot do yet.

use std::path::Path;

use plume_core::error::{Error, Result};

use crate::file::{to_toml_as_is, SceneFile};
use crate::{Albedo, Interpolation, Shot, VolumeEntry};

fn parse(text: &str) -> Result<(Shot, SceneFile)> {
    SceneFile::parse(Path::new("shot.toml"), text.to_string(), Path::new(""))
}

fn shot(text: &str) -> Shot {
    parse(text).unwrap().0
}

/// The key and message of a validation error.
fn refusal(shot: Shot) -> (String, String) {
    match shot.validate() {
        Err(Error::InvalidArgument { flag, message }) => (flag, message),
        other => panic!("expected a refusal, got {other:?}"),
    }
}

const OUTPUT: &str = "[output]\nimage = \"o.exr\"\n";

/// Two volumes under shared top-level tables, the second with sub-tables of its own.
const TWO: &str = r#"
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
group = "smoke_light"
casts_shadows = false
emission = { source = "none" }
[volumes.medium]
g = 0.3

[output]
image = "o.exr"
"#;

#[test]
fn entries_inherit_the_top_level_emission_and_medium_keys_they_leave_out() {
    let s = shot(TWO).scene;
    assert!(s.listed);
    assert_eq!(s.volume_count(), 2);
    assert_eq!(s.volume.file, Path::new("fire.vdb"));
    assert_eq!((s.medium.density_scale, s.medium.albedo, s.medium.g), (4.0, Some(0.8.into()), 0.0));
    assert_eq!(s.emission.scale, 2.0);
    let smoke = &s.more_volumes[0];
    assert_eq!(smoke.volume.file, Path::new("smoke.vdb"));
    assert_eq!(smoke.volume.translate, Some([2.0, 0.0, 0.0]));
    assert_eq!(smoke.volume.name.as_deref(), Some("smoke"));
    assert_eq!(smoke.volume.group.as_deref(), Some("smoke_light"));
    assert_eq!(s.aov_groups(), ["smoke_light"]);
    assert!(smoke.volume.visible_to_camera && !smoke.volume.casts_shadows);
    assert_eq!(
        (smoke.medium.density_scale, smoke.medium.albedo, smoke.medium.g),
        (4.0, Some(0.8.into()), 0.3)
    );
    assert_eq!(smoke.emission.source, crate::EmissionSource::None);
    assert_eq!(smoke.emission.scale, 2.0);
    // Without top-level tables, the defaults
    let bare =
        shot(&format!("[[volumes]]\nfile = \"a.vdb\"\n[[volumes]]\nfile = \"b.vdb\"\n{OUTPUT}"));
    assert_eq!(bare.scene.more_volumes[0], VolumeEntry::new("b.vdb"));
    assert!(shot(TWO).validate().is_ok());
}

#[test]
fn keys_name_the_volume_as_the_scene_gave_it() {
    let listed = shot(TWO).scene;
    let entries = listed.entries();
    let keys = |i: usize| {
        ["density_grid", "emission.scale", "medium.g", "medium"].map(|f| entries[i].key(f))
    };
    assert_eq!(
        keys(0),
        [
            "volumes[0].density_grid",
            "volumes[0].emission.scale",
            "volumes[0].medium.g",
            "volumes[0].medium"
        ]
    );
    assert_eq!(
        keys(1),
        [
            "volumes[1].density_grid",
            "volumes[1].emission.scale",
            "volumes[1].medium.g",
            "volumes[1].medium"
        ]
    );
    assert_eq!(entries[1].albedo_rgb(), [0.8; 3]);
    let one = Shot::new("a.vdb", "o.exr").scene;
    let first = &one.entries()[0];
    assert_eq!(
        ["density_grid", "emission.scale", "medium.g"].map(|f| first.key(f)),
        ["volume.density_grid", "emission.scale", "medium.g"]
    );
    // A volume added to a scene given as [volume]: the first keeps its keys
    let mut added = one.clone();
    added.more_volumes.push(VolumeEntry::new("b.vdb"));
    let entries = added.entries();
    assert_eq!(
        (entries[0].key("matrix"), entries[1].key("matrix")),
        ("volume.matrix".into(), "volumes[1].matrix".into())
    );
}

#[test]
fn a_list_round_trips_through_to_toml() {
    let two = shot(TWO);
    let text = to_toml_as_is(&two).unwrap();
    assert!(text.contains("[[volumes]]") && !text.contains("[volume]"), "{text}");
    assert_eq!(shot(&text), two);
    // A list of one stays a list; a volume given as [volume] with one added becomes one
    let one = shot(&format!("[[volumes]]\nfile = \"a.vdb\"\n{OUTPUT}"));
    assert!(one.scene.listed && one.scene.more_volumes.is_empty());
    assert_eq!(shot(&to_toml_as_is(&one).unwrap()), one);
    let mut added = Shot::new("a.vdb", "o.exr");
    added.scene.medium.albedo = Some(Albedo::Color([0.5, 0.6, 0.7]));
    added.scene.more_volumes.push(VolumeEntry::new("b.vdb"));
    let back = shot(&to_toml_as_is(&added).unwrap());
    assert!(back.scene.listed);
    added.scene.listed = true;
    assert_eq!(back, added);
    // One volume given as [volume]: today's text
    let single = Shot::new("a.vdb", "o.exr");
    let text = to_toml_as_is(&single).unwrap();
    assert!(text.contains("[volume]\nfile = \"a.vdb\"\n") && !text.contains("volumes"), "{text}");
    assert_eq!(shot(&text), single);
}

#[test]
fn volume_tables_that_cannot_be_are_refused_at_their_line() {
    let both = format!("[volume]\nfile = \"a.vdb\"\n[[volumes]]\nfile = \"b.vdb\"\n{OUTPUT}");
    let e = parse(&both).err().unwrap().to_string();
    assert!(e.starts_with("shot.toml:3: key `volumes`:") && e.contains("not both"), "{e}");
    let e = parse(&format!("volumes = []\n{OUTPUT}")).err().unwrap().to_string();
    assert!(e.contains("key `volumes`") && e.contains("empty"), "{e}");
    // Unknown keys and wrong types inside an entry: the entry's key at its line
    for (text, needle) in [
        (
            "[[volumes]]\nfile = \"a\"\n[[volumes]]\nfile = \"b\"\ncolour = 1\n",
            "shot.toml:5: key `volumes[1].colour`",
        ),
        (
            "[[volumes]]\nfile = \"a\"\n[volumes.medium]\ngg = 1\n",
            "shot.toml:4: key `volumes[0].medium.gg`",
        ),
        (
            "[[volumes]]\nfile = \"a\"\n[[volumes]]\nfile = \"b\"\nmedium = { g = \"x\" }\n",
            "shot.toml:5: key `volumes[1].medium.g`",
        ),
        // A syntax error: the key read from the text
        (
            "[[volumes]]\nfile = \"a\"\n[[volumes]]\nfile = \"b\"\n[volumes.medium]\ng = \n",
            "shot.toml:6: key `volumes[1].medium.g`",
        ),
    ] {
        let e = parse(text).err().unwrap().to_string();
        assert!(e.contains(needle), "{e}");
    }
}

#[test]
fn every_volume_gets_the_checks_of_one_naming_its_keys() {
    let singular = "matrix = [[1, 0, 0, 0], [2, 0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]";
    for (entry, key, needle) in [
        (singular, "volumes[1].matrix", "singular"),
        ("medium = { albedo = [0.5, 1.5, 0.5] }", "volumes[1].medium.albedo", "[0, 1]"),
        ("medium = { g = 1 }", "volumes[1].medium.g", "(-1, 1)"),
        ("medium = { density_scale = -1 }", "volumes[1].medium.density_scale", "≥ 0"),
        (
            "emission = { temperature_map = \"celsius\" }",
            "volumes[1].emission.temperature_map",
            "linear",
        ),
        ("emission = { color = [1, -1, 1] }", "volumes[1].emission.color", "≥ 0"),
        ("density_grid = \"\"", "volumes[1].density_grid", "name[N]"),
        ("name = \"emission\"", "volumes[1].name", "fixed layer"),
        ("group = \"a.b\"", "volumes[1].group", "letters"),
    ] {
        let text =
            format!("[[volumes]]\nfile = \"a\"\n[[volumes]]\nfile = \"b\"\n{entry}\n{OUTPUT}");
        let (s, file) = parse(&text).unwrap();
        let (k, m) = refusal(s);
        assert_eq!(k, key, "{entry}: {m}");
        assert!(m.contains(needle), "{entry}: {m}");
        // The scene file names the line
        assert_eq!(file.line_of(&k), Some(5), "{k}");
    }
}

#[test]
fn one_volume_validates_as_before() {
    let mut s = Shot::new("a.vdb", "o.exr");
    s.scene.volume.matrix = Some([[0.0; 4], [0.0; 4], [0.0; 4], [0.0, 0.0, 0.0, 1.0]]);
    assert_eq!(refusal(s).0, "volume.matrix");
    let mut s = Shot::new("a.vdb", "o.exr");
    s.scene.medium.g = 1.0;
    assert_eq!(refusal(s).0, "medium.g");
    let mut s = Shot::new("a.vdb", "o.exr");
    s.scene.medium.absorption_color = Some(Albedo::Color([0.1, 0.2, 0.3]));
    s.scene.volume.albedo_grid = Some("albedo".into());
    let (k, m) = refusal(s);
    assert_eq!(k, "medium.absorption_color");
    assert!(m.contains("(volume.albedo_grid)"), "{m}");
    // What several volumes may not do, one may
    let mut s = Shot::new("a.vdb", "o.exr");
    s.scene.volume.velocity_grid = Some("v".into());
    s.scene.volume.interpolation = Interpolation::Nearest;
    s.scene.integrator.tracking = crate::TrackingChoice::Null;
    assert!(s.validate().is_ok());
    // A list of one: the same checks, its keys
    let (k, _) =
        refusal(shot(&format!("[[volumes]]\nfile = \"a\"\nmedium = {{ g = 2 }}\n{OUTPUT}")));
    assert_eq!(k, "volumes[0].medium.g");
}

#[test]
fn what_several_volumes_cannot_do_yet_is_refused_naming_the_key() {
    for (top, entry, key) in [
        ("", "interpolation = \"nearest\"", "volumes[1].interpolation"),
        ("", "velocity_grid = \"v\"", "volumes[1].velocity_grid"),
        ("", "albedo_grid = \"albedo\"", "volumes[1].albedo_grid"),
        ("", "medium = { absorption_color = 0.5 }", "volumes[1].medium.absorption_color"),
        ("[medium]\nabsorption_color = 0.5\n", "", "volumes[0].medium.absorption_color"),
        ("[integrator]\ntracking = \"null\"\n", "", "integrator.tracking"),
    ] {
        let text =
            format!("{top}[[volumes]]\nfile = \"a\"\n[[volumes]]\nfile = \"b\"\n{entry}\n{OUTPUT}");
        let (k, m) = refusal(shot(&text));
        assert_eq!(k, key, "{entry}{top}: {m}");
    }
    // Every light sampling works
    for ls in ["fnee", "nee", "none"] {
        let text = format!("[integrator]\nlight_sampling = \"{ls}\"\n[[volumes]]\nfile = \"a\"\n[[volumes]]\nfile = \"b\"\n{OUTPUT}");
        assert!(shot(&text).validate().is_ok(), "{ls}");
    }
}

#[test]
fn at_most_eight_scattering_media() {
    let mut text = String::from("[medium]\nalbedo = 0.5\n");
    // Nine volumes of eight media (two alike), then one more
    for g in [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.7] {
        text += &format!("[[volumes]]\nfile = \"a\"\nmedium = {{ g = {g} }}\n");
    }
    // Emission only: not a scattering medium
    text += "[[volumes]]\nfile = \"a\"\nmedium = { albedo = 0, g = 0.9 }\n";
    assert!(shot(&format!("{text}{OUTPUT}")).validate().is_ok());
    text += "[[volumes]]\nfile = \"a\"\nmedium = { albedo = [0.5, 0.5, 0.4] }\n";
    let (k, m) = refusal(shot(&format!("{text}{OUTPUT}")));
    assert_eq!(k, "volumes[10].medium", "{m}");
    // Named at the entry's line, also where the entry inherits the key
    let (_, file) = parse(&format!("{text}{OUTPUT}")).unwrap();
    assert_eq!(file.line_of(&k), Some(35));
    let inherited = "[[volumes]]\nfile = \"a\"\n\n[[volumes]]\nfile = \"b\"\n";
    let (_, file) = parse(&format!("{inherited}{OUTPUT}")).unwrap();
    assert_eq!(file.line_of("volumes[1].medium.g"), Some(4));
    assert_eq!(file.line_of("medium.g"), None);
    // Without bounces nothing scatters
    let (s, _) = parse(&format!("{text}[integrator]\nmax_depth = 0\n{OUTPUT}")).unwrap();
    assert!(s.validate().is_ok());
}

/// One volume with two instances, inline.
const INSTANCED: &str = r#"
[volume]
file = "fire.vdb"
rotate = [30, 0, 0]
instances = [
    { translate = [2, 0, 0] },
    { translate = [-2, 0, 0], rotate = [0, 0, 90], scale = 0.5 },
]

[output]
image = "o.exr"
"#;

#[test]
fn instances_are_placements_after_the_volumes_own() {
    let s = shot(INSTANCED);
    let instances = s.scene.volume.instances.clone().unwrap();
    assert_eq!(instances.len(), 2);
    assert_eq!(instances[1].scale, Some(crate::Scale::Uniform(0.5)));
    assert_eq!(instances[1].rotate, Some([0.0, 0.0, 90.0]));
    assert!(s.scene.is_several() && s.scene.volume_count() == 1);
    assert_eq!(s.scene.placed_volume_count(), 2);
    assert!(s.clone().validate().is_ok());
    // A scene without instances is not several; a list of one neither
    assert!(!Shot::new("a.vdb", "o.exr").scene.is_several());
    assert!(!shot(&format!("[[volumes]]\nfile = \"a\"\n{OUTPUT}")).scene.is_several());
    // In a list, and as an array of tables
    let text = format!(
        "[[volumes]]\nfile = \"a\"\n[[volumes]]\nfile = \"b\"\n[[volumes.instances]]\ntranslate = [1, 0, 0]\n[[volumes.instances]]\nscale = 2\n{OUTPUT}"
    );
    let listed = shot(&text).scene;
    assert_eq!(listed.placed_volume_count(), 3);
    assert_eq!(listed.more_volumes[0].volume.placed_count(), 2);
    assert!(listed.volume.instances.is_none());
}

#[test]
fn instances_round_trip_and_a_scene_without_them_is_written_as_before() {
    let one = shot(INSTANCED);
    let text = to_toml_as_is(&one).unwrap();
    assert!(text.contains("[volume]") && text.contains("instances"), "{text}");
    assert_eq!(shot(&text), one);
    let listed = shot(&INSTANCED.replace("[volume]", "[[volumes]]"));
    let text = to_toml_as_is(&listed).unwrap();
    assert!(text.contains("[[volumes]]") && text.contains("instances"), "{text}");
    assert_eq!(shot(&text), listed);
    let single = to_toml_as_is(&Shot::new("a.vdb", "o.exr")).unwrap();
    assert!(!single.contains("instances"), "{single}");
}

#[test]
fn bad_instances_are_refused_naming_their_key_and_line() {
    let singular = "{ matrix = [[1, 0, 0, 0], [2, 0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]] }";
    for (volume, instances, key, needle, line) in [
        ("[volume]", "[]", "volume.instances", "empty", 3),
        ("[volume]", "[{ scale = 0 }]", "volume.instances[0].scale", "flattens", 3),
        (
            "[[volumes]]",
            "[{}, { scale = [1, 0, 1] }]",
            "volumes[0].instances[1].scale",
            "flattens",
            3,
        ),
        (
            "[[volumes]]",
            &format!("[{{ translate = [1, 0, 0] }}, {singular}]"),
            "volumes[0].instances[1].matrix",
            "singular",
            3,
        ),
        ("[volume]", "[{ rotate = [nan, 0, 0] }]", "volume.instances[0].rotate", "not finite", 3),
    ] {
        let text = format!("{volume}\nfile = \"a\"\ninstances = {instances}\n{OUTPUT}");
        let (s, file) = parse(&text).unwrap();
        let (k, m) = refusal(s);
        assert_eq!(k, key, "{instances}: {m}");
        assert!(m.contains(needle), "{instances}: {m}");
        assert_eq!(file.line_of(&k), Some(line), "{k}");
    }
    // Of a further entry, written as tables: the line of the instance's key
    let text = "[[volumes]]\nfile = \"a\"\n[[volumes]]\nfile = \"b\"\n[[volumes.instances]]\ntranslate = [1, 0, 0]\n[[volumes.instances]]\nscale = 0\n";
    let (s, file) = parse(&format!("{text}{OUTPUT}")).unwrap();
    let (k, _) = refusal(s);
    assert_eq!(k, "volumes[1].instances[1].scale");
    assert_eq!(file.line_of(&k), Some(8));
    // Unknown keys and syntax errors inside an instance: named by the parser
    for (text, needle) in [
        ("[volume]\nfile = \"a\"\ninstances = [{ move = 1 }]\n", "shot.toml:3: key `volume.instances[0].move`"),
        (
            "[[volumes]]\nfile = \"a\"\n[[volumes.instances]]\nscale = 1\n[[volumes]]\nfile = \"b\"\n[[volumes.instances]]\nscale = 1\n[[volumes.instances]]\nscale = 0.5.5\n",
            "shot.toml:10: key `volumes[1].instances[1].scale`",
        ),
    ] {
        let e = parse(text).err().unwrap().to_string();
        assert!(e.contains(needle), "{e}");
    }
}

#[test]
fn instances_make_one_volume_several_for_validation() {
    for (top, key) in [
        ("[integrator]\ntracking = \"null\"\n", "integrator.tracking"),
        ("[medium]\nabsorption_color = 0.5\n", "medium.absorption_color"),
    ] {
        let (k, m) = refusal(shot(&format!("{top}{INSTANCED}")));
        assert_eq!(k, key, "{m}");
    }
    let with = |keys: &str| INSTANCED.replace("rotate = [30, 0, 0]", keys);
    for (keys, key) in [
        ("velocity_grid = \"v\"", "volume.velocity_grid"),
        ("albedo_grid = \"albedo\"", "volume.albedo_grid"),
    ] {
        let (k, m) = refusal(shot(&with(keys)));
        assert_eq!(k, key, "{m}");
        assert!(m.contains("instances"), "{m}");
    }
    // Without instances the same one volume may
    let plain =
        shot(&format!("[integrator]\ntracking = \"null\"\n[volume]\nfile = \"a\"\n{OUTPUT}"));
    assert!(plain.validate().is_ok());
}
