//! The stream in a child process: `plume __read-grids stream FILE MAX_BYTES SEL` runs
//! [`LocalStream`] and writes its batches to the pipe (`wire/stream/`); the parent
//! decodes one record at a time, checks it (`Delivery`) and visits it.
//!
//! - **Memory**: the child's `RLIMIT_DATA` is [`IsolationLimits::memory_bytes`], as for
//!   whole-grid reads (`2 × max_bytes + 256 MiB` by default), while `max_bytes` bounds the
//!   child's topology rather than the voxelized grid; the parent holds one batch. Neither
//!   grows with the grid's values. The mapped file is not counted by `RLIMIT_DATA` (its
//!   pages are the page cache's, read-only).
//! - **Time**: the wall-clock deadline ([`IsolationLimits::timeout`]) counts only the time
//!   spent waiting for the child: each visitor call moves it later by its own duration,
//!   so a slow consumer never fails the read (the child then sleeps on a full pipe).
//!   `RLIMIT_CPU` still bounds the child's own work.
//! - **Failure**: a crash, hang, limit or malformed reply is [`Error::ReaderFailed`]
//!   naming the file and grid; a visitor error kills the child and is returned as is.

use std::ffi::OsString;
use std::io::{self, BufReader, Write};
use std::path::Path;
use std::time::Instant;

use super::STREAM_BATCH;
use super::{Delivery, HeaderVisitor, LeafVisitor, LocalStream, Refusal, StreamedGrid};
use crate::vdb::isolate::{
    child_error, malformed_reply, unexpected, ChildPipes, IsolationLimits, Parsed, ReaderCommand,
    ReaderRun,
};
use crate::vdb::read::check_file;
use crate::vdb::wire::{ChildError, Decoder, Encoder, Record, WireError};
use crate::vdb::{GridSelector, ReadLimits};
use plume_core::error::{Error, Result};

/// [`super::stream_float_grid`] in a child process of `reader_exe` (the `plume` binary).
///
/// # Errors
/// As [`super::stream_float_grid`]; [`Error::ReaderFailed`] when the child crashes, hangs,
/// exceeds a limit or replies with garbage (leaves already visited stay visited);
/// [`Error::ReaderSpawn`] when it cannot start.
pub fn stream_float_grid_isolated(
    reader_exe: &ReaderCommand,
    path: &Path,
    selector: &GridSelector,
    read_limits: &ReadLimits,
    limits: &IsolationLimits,
    header: &mut HeaderVisitor<'_>,
    leaf: &mut LeafVisitor<'_>,
) -> Result<StreamedGrid> {
    check_file(path)?;
    let args: Vec<OsString> = vec![
        "stream".into(),
        path.into(),
        read_limits.max_bytes.to_string().into(),
        selector.to_string().into(),
    ];
    let mut run = ReaderRun::spawn(reader_exe, &args, limits)?;
    let mut grid: Option<String> = None;
    let mut visitor_error: Option<Error> = None;
    // No GRID record belongs in a stream reply: 0 bytes of whole-grid data allowed
    let outcome = run.parse(0, |decoder| {
        parse_stream_reply(decoder, selector, header, leaf, &mut grid, &mut visitor_error)
    });
    let finished = run.finish(path, outcome, grid.clone(), limits);
    if let Some(error) = visitor_error {
        return Err(error);
    }
    finished?.map_err(|e| child_error(path, e, grid, limits))
}

/// The error `parse_stream_reply` returns when a visitor failed: not the child's fault,
/// but it stops the child like a broken reply does.
fn aborted(visitor_error: &mut Option<Error>, error: Error) -> WireError {
    *visitor_error = Some(error);
    WireError::Io(io::Error::other("stream aborted by its visitor"))
}

/// FAILED must be followed by END.
fn failed_then_end(
    decoder: &mut Decoder<&mut BufReader<ChildPipes>>,
    error: ChildError,
) -> Parsed<StreamedGrid> {
    match decoder.next()? {
        Record::End => Ok(Err(error)),
        other => Err(unexpected(&other)),
    }
}

/// Decodes BEGIN, STREAM, LEAVES…, TILES…, END and visits as it goes.
fn parse_stream_reply(
    decoder: &mut Decoder<&mut BufReader<ChildPipes>>,
    selector: &GridSelector,
    header: &mut HeaderVisitor<'_>,
    leaf: &mut LeafVisitor<'_>,
    grid: &mut Option<String>,
    visitor_error: &mut Option<Error>,
) -> Parsed<StreamedGrid> {
    match decoder.next()? {
        Record::Begin { request: 0, alternative: 0 } => *grid = Some(selector.to_string()),
        Record::Failed(e) => return failed_then_end(decoder, e),
        other => return Err(unexpected(&other)),
    }
    let announced = match decoder.next()? {
        Record::Stream(g) if g.name == selector.name => g,
        Record::Stream(_) => return Err(malformed_reply("STREAM names another grid")),
        Record::Failed(e) => return failed_then_end(decoder, e),
        other => return Err(unexpected(&other)),
    };
    let start = Instant::now();
    let visited = header(&announced);
    decoder.input().get_mut().extend_deadline(start.elapsed());
    if let Err(e) = visited {
        return Err(aborted(visitor_error, e));
    }
    let mut delivery = Delivery::new(announced, leaf);
    loop {
        let record = decoder.next()?;
        let start = Instant::now();
        let delivered = match record {
            Record::Leaves => {
                let (origins, values) = decoder.leaf_batch();
                delivery.leaves(origins, values)
            }
            Record::Tiles => decoder.tile_batch().iter().try_for_each(|t| delivery.tile(t)),
            Record::Failed(e) => return failed_then_end(decoder, e),
            Record::End => {
                return match delivery.finish() {
                    Ok(g) => Ok(Ok(g)),
                    Err(Refusal::Corrupt(m)) => Err(WireError::Malformed(m)),
                    Err(Refusal::Visitor(e)) => Err(aborted(visitor_error, e)),
                };
            }
            other => return Err(unexpected(&other)),
        };
        decoder.input().get_mut().extend_deadline(start.elapsed());
        match delivered {
            Ok(()) => {}
            Err(Refusal::Corrupt(m)) => return Err(WireError::Malformed(m)),
            Err(Refusal::Visitor(e)) => return Err(aborted(visitor_error, e)),
        }
    }
}

/// The child's side: streams the grid, or reports why it cannot. BEGIN goes out (flushed)
/// before OpenVDB touches the file, so that a crash names the grid.
pub(crate) fn serve_stream<W: Write>(
    out: &mut Encoder<W>,
    path: &Path,
    limits: &ReadLimits,
    selector: &GridSelector,
) -> io::Result<()> {
    out.begin(0, 0)?;
    let mut stream = match LocalStream::open(path, selector, limits) {
        Ok(stream) => stream,
        Err(e) => return out.failed(&ChildError::from_error(&e)),
    };
    out.stream(stream.grid())?;
    loop {
        match stream.next_batch() {
            Ok(Some((origins, values))) => out.leaves(origins, values)?,
            Ok(None) => break,
            Err(e) => return out.failed(&ChildError::from_error(&e)),
        }
    }
    for tiles in stream.tiles().chunks(STREAM_BATCH) {
        out.tiles(tiles)?;
    }
    Ok(())
}
