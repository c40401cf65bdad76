//! Dispatch: each command's flags become library types, then the library runs them.

use clap::ArgMatches;
use plume_core::error::Result;

use super::render::RenderRequest;
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
            if let Some(path) = &args.write_scene {
                plume_scene::file::write(path, &request.shot)?;
                eprintln!("plume: wrote {}", path.display());
                return Ok(());
            }
            plume::farm::job::render_command(&request.shot, command_line).map_err(|e| request.origin.explain(e))
        }
        Command::Merge(args) => plume::farm::merge::merge_command(&(&args).into(), command_line),
        Command::Info(args) => files::info_command(&args),
        Command::Prepare(args) => files::prepare_command(&args),
        Command::Bench(command) => {
            let sub = sub.and_then(|m| m.subcommand()).map(|(_, m)| m);
            super::bench::run(command, sub)
        }
        Command::Synth(files::SynthCommand::Explosion(args)) => files::synth_explosion_command(&args),
        Command::Synth(files::SynthCommand::Flare(args)) => files::synth_flare_command(&args),
        Command::Synth(files::SynthCommand::Sky(args)) => files::synth_sky_command(&args),
    }
}
