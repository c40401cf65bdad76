//! The `plume` binary's command line (clap derive; doc comments are the `--help` text).
//! Nothing here is part of the library: flags become library types
//! ([`plume_scene::Shot`], `bench` and `merge` options) in one conversion per command,
//! and the library never sees a clap type.
//!
//! | file | command |
//! |---|---|
//! | `render.rs` | `plume render` flags (each sets a scene key; `--write-scene`) |
//! | `request.rs` | flags and scene file → a validated [`plume_scene::Shot`], and errors back to flags |
//! | `keys.rs` | the table of render flag → scene key, and back (for error messages) |
//! | `flags.rs` | value parsers shared by the commands (vectors, sizes, named choices) |
//! | `bench.rs` | `plume bench …` |
//! | `files.rs` | `plume info`, `plume prepare`, `plume merge`, `plume synth …` |
//! | `commands.rs` | dispatch |
//! | `logger.rs` | the library's log records on stderr, keys named as the flags that set them |
//! | `observer.rs` | what `plume render` shows while it runs: progress bar and lines, replays |
//! | `environment.rs` | what the library is given from the environment (directories) |
//!
//! The library never prints, exits or reads the environment (`scripts/check-quiet.sh`):
//! everything on stdout and stderr is written here or by the logger installed here.

pub mod bench;
pub mod commands;
pub mod environment;
pub mod files;
pub mod flags;
pub mod keys;
pub mod logger;
pub mod observer;
pub mod render;
pub mod request;

use clap::{Parser, Subcommand};

/// plume: a renderer for emissive heterogeneous volumes (OpenVDB), with line
/// integration and forward next-event estimation.
///
/// Exit codes: 0 success (also when every output was already complete and skipped);
/// 2 bad arguments or scene file; 3 input missing, unreadable or invalid (VDB file,
/// grid, merge part); 4 render or output failure, including an input that failed while
/// in use (truncated, rewritten or replaced by another process, an I/O error of its
/// storage; one line, never a death by SIGBUS; it ends a run of several frames at once)
/// or a cache lock held past --cache-lock-timeout; 5 interrupted by SIGTERM/SIGINT (the
/// image so far was written with its real spp; a rerun continues it); 6 --time-limit
/// reached (likewise); 7 a run of several frames in which some frames failed or stopped
/// early (each is reported; the others were rendered). A run of one frame exits with
/// that frame's code. 101 is a bug (a panic): please report it.
#[derive(Debug, Parser)]
#[command(name = "plume", version, about, long_about)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Render a VDB file, a sequence of them, or a scene file (.toml), to float EXRs (and
    /// optionally PNG previews).
    Render(Box<render::RenderArgs>),
    /// Assemble parts of a frame rendered as tiles (--crop, --tile) and sample ranges
    /// (--sample-range) into one EXR, bit-identical to rendering it in one process.
    Merge(files::MergeArgs),
    /// Print every grid of a VDB file: name, type, class, voxels, bounds, transform,
    /// value range, memory.
    Info(files::InfoArgs),
    /// Convert a .vdb into a brick cache file (.plume) that renders out of core: bricks,
    /// pyramid and FNEE proxy, memory-mapped by `plume render OUT.plume`.
    Prepare(files::PrepareArgs),
    /// Generate procedural volumes.
    #[command(subcommand)]
    Synth(files::SynthCommand),
    /// Benchmarks: speed and memory figures.
    #[command(subcommand)]
    Bench(bench::BenchCommand),
}
