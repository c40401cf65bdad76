//! The `plume` command-line tool: parses arguments into the library's types, runs the
//! library, and turns an error into a one-line message on stderr and a non-zero exit
//! code. The command line (clap) lives here, in `cli/`, and nowhere in the library.

mod cli;

use clap::{CommandFactory, FromArgMatches};

use plume::vdb::isolate;

fn main() {
    // The isolated VDB reader is this same binary: `plume __read-grids …` (hidden, see
    // vdb::isolate). It is dispatched before clap so that it stays out of --help.
    let mut args = std::env::args_os().skip(1);
    if args.next().is_some_and(|a| a == isolate::READER_SUBCOMMAND) {
        isolate::reader_main(&args.collect::<Vec<_>>());
    }
    // A mapped file that fails under plume (truncated, I/O error) ends it with a line
    // and exit code 4 instead of SIGBUS. Not in the reader child above: its crash is
    // already the parent's error.
    if let Err(e) = plume::mapfault::install() {
        eprintln!("plume: warning: cannot install the SIGBUS handler for mapped files ({e})");
    }
    if let Ok(exe) = std::env::current_exe() {
        isolate::set_reader_exe(exe);
    }
    let command_line = std::env::args().collect::<Vec<_>>().join(" ");
    let matches = cli::Cli::command().get_matches();
    let parsed = cli::Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    if let Err(e) = cli::commands::run(parsed, &matches, &command_line) {
        // Messages already carry their cause; one line, naming the file/grid/flag.
        eprintln!("plume: error: {e}");
        std::process::exit(e.exit_code());
    }
}
