//! The one conversion of `plume render` flags (and a scene file) into a validated
//! [`Shot`] ([`RenderRequest`]), and the way back for errors ([`Origin::explain`]).
//!
//! Without a scene file every flag, defaults included, gives its key. With one
//! (`plume render shot.toml`), the file gives the keys and only the flags typed on the
//! command line override them. [`render_flags`] (`keys.rs`) is the one table of flag →
//! key; it also turns the keys that library errors name back into the flags a user
//! typed, or into the scene file's line.

use std::ops::Range;

use clap::ArgMatches;
use plume_core::error::{Error, Result};
use plume_scene::file::{is_scene_file, SceneFile};
use plume_scene::{Shot, ValidShot};

use super::keys::{apply, flag_for_key, flag_name, render_flags};
use super::render::RenderArgs;

/// A render command line as library types.
pub struct RenderRequest {
    /// The validated shot.
    pub shot: ValidShot,
    /// Where its values came from, to name them in errors.
    pub origin: Origin,
}

/// Where a shot's values came from: flags, or a scene file and the flags typed beside it.
pub struct Origin {
    /// The scene file, if any.
    pub scene_file: Option<SceneFile>,
    /// Flag ids typed on the command line.
    pub given: Vec<String>,
    /// The indices of the volumes that `--add-volume` added (`volumes[INDEX]`).
    pub added_volumes: Range<usize>,
}

impl TryFrom<(&RenderArgs, &ArgMatches)> for RenderRequest {
    type Error = Error;

    /// The one conversion: flags, or a scene file with flags overriding its keys, into a
    /// validated shot. `matches` says which flags were typed.
    ///
    /// # Errors
    /// A bad scene file, a missing output, or a value [`Shot::validate`] refuses; errors
    /// name the flag or the file, line and key.
    fn try_from((args, matches): (&RenderArgs, &ArgMatches)) -> Result<RenderRequest> {
        let typed =
            |id: &str| matches.value_source(id) == Some(clap::parser::ValueSource::CommandLine);
        let given: Vec<String> =
            render_flags().map(|(id, _)| *id).filter(|id| typed(id)).map(String::from).collect();
        let (mut shot, scene_file, before) = if is_scene_file(&args.file) {
            let (mut shot, file) = SceneFile::read(&args.file)?;
            // A flag overrides the keys it conflicts with, too
            if typed("time") || typed("sample_range") {
                shot.settings.render.spp = None;
            }
            if typed("spp") || typed("sample_range") {
                shot.settings.render.time = None;
            }
            if typed("spp") || typed("time") {
                shot.settings.farm.sample_range = None;
            }
            if typed("crop") {
                shot.settings.farm.tile = None;
            }
            if typed("tile") {
                shot.settings.farm.crop = None;
            }
            let before = shot.scene.volume_count();
            apply(&mut shot, args, &typed);
            (shot, Some(file), before)
        } else {
            let output = args.output.clone().ok_or_else(|| {
                Error::invalid(
                    "--output",
                    "required (-o OUT.exr), unless FILE is a scene file that gives [output] image",
                )
            })?;
            let mut shot = Shot::new(&args.file, output);
            apply(&mut shot, args, &|_| true);
            (shot, None, 1)
        };
        // Not a flag nor a key: where this machine keeps caches
        shot.settings.render.user_cache_dir = Some(super::environment::user_cache_dir());
        let added_volumes = before..shot.scene.volume_count();
        let origin = Origin { scene_file, given, added_volumes };
        match shot.validate() {
            Ok(shot) => Ok(RenderRequest { shot, origin }),
            Err(e) => Err(origin.explain(e)),
        }
    }
}

impl Origin {
    /// `e` as the user should read it: keys named by the flag that set them, or by the
    /// scene file's line when the file did.
    #[must_use]
    pub fn explain(&self, e: Error) -> Error {
        let Error::InvalidArgument { flag: field, message } = e else { return e };
        let keys: Vec<&str> = field.split('/').collect();
        let flags: Vec<_> = keys.iter().map(|k| flag_for_key(k, &self.added_volumes)).collect();
        let typed = flags.iter().flatten().any(|(id, _)| self.given.iter().any(|g| g == id));
        if let Some(file) = &self.scene_file {
            if !typed {
                return file.error_at_key(keys[0], &message);
            }
        }
        let named: Vec<String> = keys
            .iter()
            .zip(flags)
            .map(|(k, flag)| flag.map_or_else(|| (*k).to_string(), |(_, name)| name))
            .collect();
        // Keys named inside the message too, longest first (`volumes`, a list, is not
        // named inside messages: its name is part of the keys of its entries)
        let mut message = message;
        let mut all: Vec<(&str, &str)> =
            render_flags().copied().filter(|(_, key)| key.contains('.')).collect();
        all.sort_by_key(|(_, k)| std::cmp::Reverse(k.len()));
        for (id, key) in all {
            message = message.replace(key, &flag_name(id));
        }
        Error::InvalidArgument { flag: named.join("/"), message }
    }
}

#[cfg(test)]
mod tests {
    use clap::{CommandFactory, FromArgMatches};

    use super::*;
    use crate::cli::{Cli, Command};

    fn request(argv: &[&str]) -> Result<RenderRequest> {
        let mut v = vec!["plume", "render"];
        v.extend_from_slice(argv);
        let matches = Cli::command().try_get_matches_from(v).unwrap();
        let cli = Cli::from_arg_matches(&matches).unwrap();
        let Command::Render(args) = cli.command else { unreachable!() };
        let (_, sub) = matches.subcommand().unwrap();
        RenderRequest::try_from((&*args, sub))
    }

    #[test]
    fn flag_defaults_are_the_library_defaults() {
        let mut shot = request(&["in.vdb", "-o", "out.exr"]).unwrap().shot.into_inner();
        // The one value from the environment, not from a flag
        assert!(shot.settings.render.user_cache_dir.take().is_some_and(|d| d.ends_with("plume")));
        assert_eq!(shot, Shot::new("in.vdb", "out.exr"));
    }

    #[test]
    fn every_render_flag_has_a_key() {
        let cmd = Cli::command();
        let render = cmd.find_subcommand("render").unwrap();
        for arg in render.get_arguments() {
            let id = arg.get_id().as_str();
            if ["file", "write_scene", "help"].contains(&id) {
                continue;
            }
            assert!(render_flags().any(|(f, _)| *f == id), "flag {id} sets no scene key");
        }
    }

    #[test]
    fn errors_name_the_flag() {
        let e = request(&["in.vdb", "-o", "out.exr", "--albedo", "2"]).err().unwrap().to_string();
        assert!(e.contains("--albedo"), "{e}");
        let e = request(&["in.vdb", "-o", "out.exr", "--width", "0"]).err().unwrap().to_string();
        assert!(e.contains("--width/--height"), "{e}");
        let e = request(&["in.vdb"]).err().unwrap().to_string();
        assert!(e.contains("--output"), "{e}");
    }

    #[test]
    fn added_volumes_take_the_first_volumes_values_and_errors_name_the_flag() {
        let add = |keys: &'static str| ["--add-volume", keys];
        let shot = request(
            &[
                &["in.vdb", "-o", "out.exr", "--albedo", "0.5", "--emission-scale", "3"][..],
                &add("file = \"b.vdb\", medium = { g = 0.3 }"),
            ]
            .concat(),
        )
        .unwrap()
        .shot;
        let b = &shot.scene.more_volumes[0];
        assert_eq!((b.medium.albedo, b.medium.g, b.emission.scale), (Some(0.5.into()), 0.3, 3.0));
        assert!(!shot.scene.listed);
        let base = ["in.vdb", "-o", "out.exr"];
        let e = request(&[&base[..], &add("file = \"b.vdb\", medium = { g = 2 }")].concat());
        let e = e.err().unwrap().to_string();
        assert!(e.contains("--add-volume medium.g"), "{e}");
        let second = add("file = \"c.vdb\", interpolation = \"nearest\"");
        let e = request(&[&base[..], &add("file = \"b.vdb\""), &second].concat());
        let e = e.err().unwrap().to_string();
        assert!(e.contains("--add-volume #2 interpolation"), "{e}");
    }
}
