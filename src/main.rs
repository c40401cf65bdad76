//! The `plume` command-line tool: parses arguments, runs the library, and turns an error
//! into a one-line message on stderr and a non-zero exit code.

use clap::Parser;

fn main() {
    let command_line = std::env::args().collect::<Vec<_>>().join(" ");
    let cli = plume::cli::Cli::parse();
    if let Err(e) = plume::app::run(cli, &command_line) {
        // Messages already carry their cause; one line, naming the file/grid/flag.
        eprintln!("plume: error: {e}");
        std::process::exit(e.exit_code());
    }
}
