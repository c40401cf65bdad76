//! The child side of an isolated read: [`reader_main`] runs inside
//! `plume __read-grids …` (see the command line in [`super`]), reads with the in-process
//! reader and writes the reply to its stdout in the format of `vdb/wire/`. A failure to
//! do so comes back as a [`ReaderFailure`], which the binary prints before it ends the
//! process.

use std::ffi::OsString;
use std::io::{self, BufWriter, Write};
use std::os::fd::AsFd;
use std::path::{Path, PathBuf};

use super::READER_SUBCOMMAND;
use crate::vdb::read::plan_requests;
use crate::vdb::stream::serve_stream;
use crate::vdb::wire::{ChildError, Encoder};
use crate::vdb::{
    list_grids, read_float_grid, read_vec3_grid, GridRequest, GridSelector, ReadLimits,
};
use plume_core::error::Error;

/// Why the reader subcommand failed; a reply that reports a clean failure (a missing
/// grid, a corrupt file) is not one.
#[derive(Debug)]
pub enum ReaderFailure {
    /// The reply could not be written (exit status 1).
    Reply(io::Error),
    /// A malformed command line (exit status 2); the message is the usage.
    Usage(String),
}

impl ReaderFailure {
    /// The exit status the reader process ends with: 1 for [`ReaderFailure::Reply`], 2
    /// for [`ReaderFailure::Usage`] (0 is a complete reply).
    #[must_use]
    pub fn exit_code(&self) -> i32 {
        match self {
            ReaderFailure::Reply(_) => 1,
            ReaderFailure::Usage(_) => 2,
        }
    }
}

impl std::fmt::Display for ReaderFailure {
    /// The message after `plume __read-grids: `.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ReaderFailure::Reply(e) => write!(f, "cannot write the reply: {e}"),
            ReaderFailure::Usage(message) => f.write_str(message),
        }
    }
}

/// Runs the reader subcommand (the arguments after [`READER_SUBCOMMAND`]): `Ok` after a
/// complete reply (which may report a clean failure).
///
/// The caller ends the process at once with `_exit` and [`ReaderFailure::exit_code`] (0
/// for `Ok`), skipping C++ static destructors: after a read of a hostile file the heap
/// may be damaged, and a crash on the way out would turn a good reply into a failure.
///
/// # Errors
/// [`ReaderFailure`]: the reply could not be written, or the command line is malformed.
pub fn reader_main(args: &[OsString]) -> Result<(), ReaderFailure> {
    // SAFETY: prctl(PR_SET_DUMPABLE, 0) only changes this process's dumpable flag (no core
    // dump of a crash on a hostile file). It is reset by exec, so it is set here.
    unsafe {
        libc::prctl(libc::PR_SET_DUMPABLE, 0, 0, 0, 0);
    }
    let command = ReaderCommand::parse(args).map_err(ReaderFailure::Usage)?;
    serve(&command).map_err(ReaderFailure::Reply)
}

/// A parsed reader command line.
enum ReaderCommand {
    List { path: PathBuf },
    Read { path: PathBuf, limits: ReadLimits, requests: Vec<GridRequest> },
    Stream { path: PathBuf, limits: ReadLimits, selector: GridSelector },
    Vec3 { path: PathBuf, limits: ReadLimits, selector: GridSelector },
}

impl ReaderCommand {
    fn parse(args: &[OsString]) -> std::result::Result<ReaderCommand, String> {
        let usage = || {
            format!(
                "usage: plume {READER_SUBCOMMAND} list FILE | read FILE MAX_BYTES (need|want) N SEL... ... \
                 | stream FILE MAX_BYTES SEL | vec3 FILE MAX_BYTES SEL"
            )
        };
        let mut it = args.iter();
        fn text(
            arg: Option<&OsString>,
            usage: impl Fn() -> String,
        ) -> std::result::Result<&str, String> {
            arg.and_then(|a| a.to_str()).ok_or_else(usage)
        }
        let mode = text(it.next(), usage)?;
        let path = PathBuf::from(it.next().ok_or_else(usage)?);
        match mode {
            "list" if it.len() == 0 => Ok(ReaderCommand::List { path }),
            "read" => {
                let max_bytes = text(it.next(), usage)?.parse().map_err(|_| usage())?;
                let mut requests = Vec::new();
                while let Some(kind) = it.next() {
                    let required = match kind.to_str() {
                        Some("need") => true,
                        Some("want") => false,
                        _ => return Err(usage()),
                    };
                    let count: usize = text(it.next(), usage)?.parse().map_err(|_| usage())?;
                    if count == 0 || count > it.len() {
                        return Err(usage());
                    }
                    let alternatives = (0..count)
                        .map(|_| {
                            text(it.next(), usage)?
                                .parse::<GridSelector>()
                                .map_err(|e| e.to_string())
                        })
                        .collect::<std::result::Result<Vec<_>, _>>()?;
                    requests.push(GridRequest { alternatives, required });
                }
                Ok(ReaderCommand::Read { path, limits: ReadLimits { max_bytes }, requests })
            }
            "stream" | "vec3" if it.len() == 2 => {
                let max_bytes = text(it.next(), usage)?.parse().map_err(|_| usage())?;
                let selector = text(it.next(), usage)?.parse().map_err(|e: Error| e.to_string())?;
                let limits = ReadLimits { max_bytes };
                Ok(if mode == "stream" {
                    ReaderCommand::Stream { path, limits, selector }
                } else {
                    ReaderCommand::Vec3 { path, limits, selector }
                })
            }
            _ => Err(usage()),
        }
    }
}

/// Writes the reply to a duplicate of stdout, and points stdout at stderr so that nothing
/// OpenVDB might print can corrupt the reply.
fn serve(command: &ReaderCommand) -> io::Result<()> {
    let reply = std::fs::File::from(io::stdout().as_fd().try_clone_to_owned()?);
    // SAFETY: dup2 on two open descriptors of this process; fd 1 now refers to stderr.
    if unsafe { libc::dup2(libc::STDERR_FILENO, libc::STDOUT_FILENO) } < 0 {
        return Err(io::Error::last_os_error());
    }
    let mut out = Encoder::new(BufWriter::with_capacity(256 * 1024, reply))?;
    match command {
        ReaderCommand::List { path } => match list_grids(path) {
            Ok(infos) => out.infos(&infos)?,
            Err(e) => out.failed(&ChildError::from_error(&e))?,
        },
        ReaderCommand::Read { path, limits, requests } => {
            serve_read(&mut out, path, limits, requests)?;
        }
        ReaderCommand::Stream { path, limits, selector } => {
            serve_stream(&mut out, path, limits, selector)?;
        }
        ReaderCommand::Vec3 { path, limits, selector } => {
            serve_vec3(&mut out, path, limits, selector)?;
        }
    }
    out.end()?;
    Ok(())
}

fn serve_read<W: Write>(
    out: &mut Encoder<W>,
    path: &Path,
    limits: &ReadLimits,
    requests: &[GridRequest],
) -> io::Result<()> {
    let plan = match plan_requests(path, requests) {
        Ok(plan) => plan,
        Err(e) => return out.failed(&ChildError::from_error(&e)),
    };
    for (index, (choice, request)) in plan.into_iter().zip(requests).enumerate() {
        let index = wire_index(index);
        let Some(alternative) = choice else {
            out.absent(index)?;
            continue;
        };
        out.begin(index, wire_index(alternative))?;
        // Each grid is sent and freed before the next is read
        match read_float_grid(path, &request.alternatives[alternative], limits) {
            Ok(grid) => out.grid(index, wire_index(alternative), &grid)?,
            Err(e) => return out.failed(&ChildError::from_error(&e)),
        }
    }
    Ok(())
}

/// One vector grid as three GRID records (x, y, z) for request 0, alternative 0.
fn serve_vec3<W: Write>(
    out: &mut Encoder<W>,
    path: &Path,
    limits: &ReadLimits,
    selector: &GridSelector,
) -> io::Result<()> {
    out.begin(0, 0)?;
    match read_vec3_grid(path, selector, limits) {
        Ok(components) => components.iter().try_for_each(|grid| out.grid(0, 0, grid)),
        Err(e) => out.failed(&ChildError::from_error(&e)),
    }
}

/// Request and alternative indices come from a command line, far below `u32::MAX`.
fn wire_index(i: usize) -> u32 {
    u32::try_from(i).expect("invariant: request indices come from a command line")
}
