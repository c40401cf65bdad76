//! The `plume` command-line tool: parses arguments into the library's types, runs the
//! library, and turns an error into a one-line message on stderr and a non-zero exit
//! code. The command line (clap) lives here, in `cli/`, and nowhere in the library; so
//! do the terminal (the logger, progress, printed reports), the process's exit and what
//! is read from the environment.

mod cli;

use clap::{CommandFactory, FromArgMatches};

use plume::vdb::isolate;

fn main() {
    cli::logger::install();
    // Before anything else: this build may use instructions the CPU lacks (src/cpu.rs)
    let missing = plume::cpu::missing_features();
    if !missing.is_empty() {
        eprintln!("plume: error: {}", plume::cpu::refusal(&missing));
        std::process::exit(plume_core::error::exit::RENDER_OR_OUTPUT);
    }
    // The isolated VDB reader is this same binary: `plume __read-grids …` (hidden, see
    // vdb::isolate). It is dispatched before clap so that it stays out of --help.
    let mut args = std::env::args_os().skip(1);
    if args.next().is_some_and(|a| a == isolate::READER_SUBCOMMAND) {
        reader_exit(isolate::reader_main(&args.collect::<Vec<_>>()));
    }
    // A mapped file that fails under plume (truncated, I/O error) ends it with a line
    // and exit code 4 instead of SIGBUS. Not in the reader child above: its crash is
    // already the parent's error.
    if let Err(e) = plume_volume::out_of_core::mapfault::install() {
        eprintln!("plume: warning: cannot install the SIGBUS handler for mapped files ({e})");
    }
    if let Ok(exe) = std::env::current_exe() {
        isolate::set_reader_exe(exe);
    }
    let command_line = std::env::args().collect::<Vec<_>>().join(" ");
    let matches = cli::Cli::command().try_get_matches().unwrap_or_else(|e| usage_error(&e));
    let parsed = cli::Cli::from_arg_matches(&matches).unwrap_or_else(|e| usage_error(&e));
    if let Err(e) = cli::commands::run(parsed, &matches, &command_line) {
        // Messages already carry their cause; one line, naming the file/grid/flag.
        eprintln!("plume: error: {}", cli::logger::name_keys(&e.to_string()));
        std::process::exit(e.exit_code());
    }
}

/// End the reader subcommand (`vdb::isolate`): exit status 0 after a complete reply,
/// else the failure's line and status.
///
/// With `_exit`, skipping C++ static destructors: after a read of a hostile file the heap
/// may be damaged, and a crash on the way out would turn a good reply into a failure.
fn reader_exit(result: Result<(), isolate::ReaderFailure>) -> ! {
    let code = match result {
        Ok(()) => 0,
        Err(failure) => {
            eprintln!("plume {}: {failure}", isolate::READER_SUBCOMMAND);
            failure.exit_code()
        }
    };
    let _ = std::io::Write::flush(&mut std::io::stderr());
    // SAFETY: _exit ends the process without running atexit handlers; every output
    // stream was flushed above (the reply by the reader, stderr here).
    unsafe { libc::_exit(code) }
}

/// A command line clap cannot parse: one line naming the flag, exit 2 (help and version
/// requests print as clap prints them).
fn usage_error(e: &clap::Error) -> ! {
    use clap::error::ErrorKind;
    if matches!(
        e.kind(),
        ErrorKind::DisplayHelp
            | ErrorKind::DisplayVersion
            | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
    ) {
        e.exit();
    }
    // clap's message, its possible values and tips, without the usage and help pointers
    let text = e.render().to_string();
    let parts: Vec<&str> = text
        .lines()
        .map(str::trim)
        .take_while(|l| !l.starts_with("Usage:") && !l.starts_with("For more information"))
        .filter(|l| !l.is_empty())
        .collect();
    let line =
        if parts.is_empty() { "error: invalid command line".to_string() } else { parts.join(" ") };
    eprintln!("plume: {line}");
    std::process::exit(2);
}
