//! Dispatch: each command's flags become library types, then the library runs them.

use clap::ArgMatches;
use plume_core::error::Result;

use super::environment::working_dir;
use super::logger::{set_key_names, KeyNames};
use super::observer::Terminal;
use super::request::RenderRequest;
use super::{files, Cli, Command};

/// Run one parsed command line. `matches` says which flags were typed (scene files:
/// only those override the file's keys); `command_line` is recorded in outputs.
///
/// # Errors
/// Any input, argument or output error, with a message naming the file, grid, flag or
/// scene-file key.
pub fn run(cli: Cli, matches: &ArgMatches, command_line: &str) -> Result<()> {
    let sub = matches.subcommand().map(|(_, m)| m);
    match cli.command {
        Command::Render(args) => {
            let sub = sub.expect("invariant: a subcommand was parsed");
            let request = RenderRequest::try_from((&*args, sub))?;
            let working_dir = working_dir();
            if let Some(path) = &args.write_scene {
                plume_scene::file::write(path, &request.shot, &working_dir)?;
                eprintln!("plume: wrote {}", path.display());
                return Ok(());
            }
            set_key_names(KeyNames::of(&request.origin));
            if let Err(e) = plume::farm::signals::install() {
                log::warn!("cannot handle SIGTERM/SIGINT ({e}); a signal will end plume without writing the image so far");
            }
            let terminal = Terminal::new(&request.shot.settings);
            let context = plume::farm::observer::RunContext {
                command_line,
                working_dir: &working_dir,
                observer: &terminal,
            };
            let result = plume::farm::job::render_command(&request.shot, &context)
                .map_err(|e| request.origin.explain(e));
            terminal.finish(&result);
            result
        }
        Command::Merge(args) => {
            set_key_names(KeyNames::All);
            plume::farm::merge::merge_command(&(&args).into(), command_line)
        }
        Command::Info(args) => {
            set_key_names(KeyNames::All);
            files::info_command(&args)
        }
        Command::Prepare(args) => {
            set_key_names(KeyNames::All);
            files::prepare_command(&args)
        }
        Command::Bench(command) => {
            let sub = sub.and_then(|m| m.subcommand()).map(|(_, m)| m);
            super::bench::run(command, sub)
        }
        Command::Synth(files::SynthCommand::Explosion(args)) => {
            files::synth_explosion_command(&args)
        }
        Command::Synth(files::SynthCommand::Flare(args)) => files::synth_flare_command(&args),
        Command::Synth(files::SynthCommand::Sky(args)) => files::synth_sky_command(&args),
    }
}
