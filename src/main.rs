//! The `plume` command-line tool: parses arguments, runs the library, and turns an error
//! into a one-line message on stderr and a non-zero exit code.

use clap::Parser;

use plume::vdb::isolate;

fn main() {
    // The isolated VDB reader is this same binary: `plume __read-grids …` (hidden, see
    // vdb::isolate). It is dispatched before clap so that it stays out of --help.
    let mut args = std::env::args_os().skip(1);
    if args.next().is_some_and(|a| a == isolate::READER_SUBCOMMAND) {
        isolate::reader_main(&args.collect::<Vec<_>>());
    }
    if let Ok(exe) = std::env::current_exe() {
        isolate::set_reader_exe(exe);
    }
    let command_line = std::env::args().collect::<Vec<_>>().join(" ");
    let cli = plume::cli::Cli::parse();
    if let Err(e) = plume::app::run(cli, &command_line) {
        // Messages already carry their cause; one line, naming the file/grid/flag.
        eprintln!("plume: error: {e}");
        std::process::exit(e.exit_code());
    }
}
