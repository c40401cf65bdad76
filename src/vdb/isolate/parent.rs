//! The parent side of an isolated read: [`ReadIsolation`] chooses where to read, the
//! `read`, `vec3` and `list` requests are sent to a child (`process.rs`), and its replies
//! are decoded and checked against the requests, a clean failure becoming the error the
//! in-process reader would have returned.

use std::ffi::OsString;
use std::io::{self, Read};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::Duration;

use super::{IsolationLimits, ReaderRun};
use crate::vdb::read::check_file;
use crate::vdb::wire::{ChildError, Decoder, Record, WireError};
use crate::vdb::{
    list_grids, read_grids, read_vec3_grid, FloatGrid, FoundGrid, GridInfo, GridRequest,
};
use crate::vdb::{GridSelector, ReadLimits};
use plume_core::error::{Error, Result};

/// The command that serves [`READER_SUBCOMMAND`](super::READER_SUBCOMMAND): an executable
/// and the arguments that come before the subcommand (none for the `plume` binary;
/// `-m plume._reader` for the Python package's interpreter).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ReaderCommand {
    /// The executable.
    pub exe: PathBuf,
    /// Arguments before the subcommand.
    pub prefix: Vec<OsString>,
}

impl From<PathBuf> for ReaderCommand {
    fn from(exe: PathBuf) -> ReaderCommand {
        ReaderCommand { exe, prefix: Vec::new() }
    }
}

impl From<&str> for ReaderCommand {
    fn from(exe: &str) -> ReaderCommand {
        ReaderCommand::from(PathBuf::from(exe))
    }
}

/// The command registered by [`set_reader_exe`] or [`set_reader_command`].
static READER: OnceLock<ReaderCommand> = OnceLock::new();

/// Registers the executable that serves [`READER_SUBCOMMAND`](super::READER_SUBCOMMAND);
/// the `plume` binary registers itself at start-up. Only the first registration has an
/// effect.
pub fn set_reader_exe(exe: PathBuf) {
    set_reader_command(exe.into());
}

/// Registers a command that serves [`READER_SUBCOMMAND`](super::READER_SUBCOMMAND) after
/// its prefix arguments (an interpreter running a module that calls [`super::reader_main`]).
/// Only the first registration has an effect.
pub fn set_reader_command(command: ReaderCommand) {
    let _ = READER.set(command);
}

/// The command registered by [`set_reader_exe`] or [`set_reader_command`], if any.
#[must_use]
pub fn reader_exe() -> Option<&'static ReaderCommand> {
    READER.get()
}

/// Where VDB files are read.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ReadIsolation {
    /// In this process: fastest, but a malformed file can crash or hang plume.
    InProcess,
    /// In a child process of `reader_exe` (the `plume` binary) under `limits`.
    Child {
        /// The command that serves [`READER_SUBCOMMAND`](super::READER_SUBCOMMAND).
        reader_exe: ReaderCommand,
        /// Limits of the child.
        limits: IsolationLimits,
    },
}

impl ReadIsolation {
    /// The CLI's choice: a child of the registered executable unless `no_isolation`.
    /// Without a registered executable (a library caller that has not called
    /// [`set_reader_exe`]) reading stays in-process.
    #[must_use]
    pub fn from_flags(
        no_isolation: bool,
        read_limits: &ReadLimits,
        timeout: Duration,
    ) -> ReadIsolation {
        match reader_exe() {
            Some(exe) if !no_isolation => ReadIsolation::Child {
                reader_exe: exe.clone(),
                limits: IsolationLimits::new(read_limits, timeout),
            },
            _ => ReadIsolation::InProcess,
        }
    }

    /// [`crate::vdb::list_grids`], here or in the child.
    ///
    /// # Errors
    /// As [`crate::vdb::list_grids`], plus [`Error::ReaderFailed`] and [`Error::ReaderSpawn`].
    pub fn list_grids(&self, path: &Path) -> Result<Vec<GridInfo>> {
        match self {
            ReadIsolation::InProcess => list_grids(path),
            ReadIsolation::Child { reader_exe, limits } => {
                list_grids_isolated(reader_exe, path, limits)
            }
        }
    }

    /// [`crate::vdb::read_grids`], here or in the child.
    ///
    /// # Errors
    /// As [`crate::vdb::read_grids`], plus [`Error::ReaderFailed`] and [`Error::ReaderSpawn`].
    pub fn read_grids(
        &self,
        path: &Path,
        requests: &[GridRequest],
        read_limits: &ReadLimits,
    ) -> Result<Vec<Option<FoundGrid>>> {
        match self {
            ReadIsolation::InProcess => read_grids(path, requests, read_limits),
            ReadIsolation::Child { reader_exe, limits } => {
                read_grids_isolated(reader_exe, path, requests, read_limits, limits)
            }
        }
    }

    /// [`crate::vdb::read_vec3_grid`], here or in the child: a vector grid as three float
    /// grids `NAME.x`, `NAME.y`, `NAME.z` sharing leaves and transform.
    ///
    /// # Errors
    /// As [`crate::vdb::read_vec3_grid`], plus [`Error::ReaderFailed`] and [`Error::ReaderSpawn`].
    pub fn read_vec3_grid(
        &self,
        path: &Path,
        selector: &GridSelector,
        read_limits: &ReadLimits,
    ) -> Result<[FloatGrid; 3]> {
        match self {
            ReadIsolation::InProcess => read_vec3_grid(path, selector, read_limits),
            ReadIsolation::Child { reader_exe, limits } => {
                read_vec3_grid_isolated(reader_exe, path, selector, read_limits, limits)
            }
        }
    }
}

/// Reads the grids named by `selectors` (all required) in one child process of
/// `reader_exe`.
///
/// # Errors
/// As [`crate::vdb::read_float_grid`]; [`Error::ReaderFailed`] when the child crashes, hangs,
/// exceeds a limit or replies with garbage; [`Error::ReaderSpawn`] when it cannot start.
pub fn read_float_grids_isolated(
    reader_exe: &ReaderCommand,
    path: &Path,
    selectors: &[GridSelector],
    read_limits: &ReadLimits,
    limits: &IsolationLimits,
) -> Result<Vec<FloatGrid>> {
    let requests: Vec<GridRequest> = selectors.iter().cloned().map(GridRequest::required).collect();
    let found = read_grids_isolated(reader_exe, path, &requests, read_limits, limits)?;
    Ok(found
        .into_iter()
        .map(|f| {
            f.expect("invariant: the reply parser accepts ABSENT only for optional requests").grid
        })
        .collect())
}

/// [`crate::vdb::read_grids`] in one child process of `reader_exe`.
///
/// # Errors
/// As [`read_float_grids_isolated`].
pub fn read_grids_isolated(
    reader_exe: &ReaderCommand,
    path: &Path,
    requests: &[GridRequest],
    read_limits: &ReadLimits,
    limits: &IsolationLimits,
) -> Result<Vec<Option<FoundGrid>>> {
    // Missing files, directories, NanoVDB and non-VDB files are refused here, by Rust code
    check_file(path)?;
    let mut args: Vec<OsString> =
        vec!["read".into(), path.into(), read_limits.max_bytes.to_string().into()];
    for request in requests {
        if request.alternatives.is_empty() {
            return Err(Error::invalid("grid request", "no grid selector given"));
        }
        args.push(if request.required { "need" } else { "want" }.into());
        args.push(request.alternatives.len().to_string().into());
        args.extend(request.alternatives.iter().map(|a| OsString::from(a.to_string())));
    }
    let mut run = ReaderRun::spawn(reader_exe, &args, limits)?;
    let mut grid: Option<String> = None;
    let outcome =
        run.parse(read_limits.max_bytes, |decoder| parse_read_reply(decoder, requests, &mut grid));
    run.finish(path, outcome, grid.clone(), limits)?.map_err(|e| child_error(path, e, grid, limits))
}

/// [`crate::vdb::read_vec3_grid`] in one child process of `reader_exe`
/// (`plume __read-grids vec3 FILE MAX_BYTES SEL`).
///
/// The child answers with BEGIN and one GRID record per component; the parent checks
/// that they are `NAME.x`, `NAME.y` and `NAME.z` in that order, with identical leaf
/// origins and transforms, and that each is within a third of `read_limits.max_bytes`
/// (so all three together are within it, as in-process).
///
/// # Errors
/// As [`crate::vdb::read_vec3_grid`]; [`Error::ReaderFailed`] when the child crashes,
/// hangs, exceeds a limit or replies with garbage; [`Error::ReaderSpawn`] when it cannot
/// start.
pub fn read_vec3_grid_isolated(
    reader_exe: &ReaderCommand,
    path: &Path,
    selector: &GridSelector,
    read_limits: &ReadLimits,
    limits: &IsolationLimits,
) -> Result<[FloatGrid; 3]> {
    check_file(path)?;
    let args: Vec<OsString> = vec![
        "vec3".into(),
        path.into(),
        read_limits.max_bytes.to_string().into(),
        selector.to_string().into(),
    ];
    let mut run = ReaderRun::spawn(reader_exe, &args, limits)?;
    let mut grid: Option<String> = None;
    // leaves × BYTES_PER_LEAF ≤ ⌊max / 3⌋ exactly when 3 × leaves × BYTES_PER_LEAF ≤ max
    let outcome = run
        .parse(read_limits.max_bytes / 3, |decoder| parse_vec3_reply(decoder, selector, &mut grid));
    run.finish(path, outcome, grid.clone(), limits)?.map_err(|e| child_error(path, e, grid, limits))
}

/// The records of a `vec3` reply: BEGIN 0 0, then GRID 0 0 for `NAME.x`, `NAME.y` and
/// `NAME.z` in order, sharing origins and transform; or FAILED (after BEGIN or not).
/// `grid` tracks the selector being read, for crash messages.
fn parse_vec3_reply<R: Read>(
    decoder: &mut Decoder<R>,
    selector: &GridSelector,
    grid: &mut Option<String>,
) -> std::result::Result<std::result::Result<[FloatGrid; 3], ChildError>, WireError> {
    let mut components: Vec<FloatGrid> = Vec::with_capacity(3);
    let mut begun = false;
    loop {
        match decoder.next()? {
            Record::Begin { request: 0, alternative: 0 } if !begun => {
                begun = true;
                *grid = Some(selector.to_string());
            }
            Record::Grid { request: 0, alternative: 0, grid: g }
                if begun && components.len() < 3 =>
            {
                let axis = ["x", "y", "z"][components.len()];
                if g.name != format!("{}.{axis}", selector.name) {
                    return Err(malformed_reply(&format!(
                        "GRID {:?} is not component {axis} of the grid begun",
                        g.name
                    )));
                }
                if components.first().is_some_and(|x| {
                    x.origins != g.origins || x.world_from_index != g.world_from_index
                }) {
                    return Err(malformed_reply("vector components differ in leaves or transform"));
                }
                components.push(g);
                if components.len() == 3 {
                    *grid = None;
                }
            }
            Record::Failed(e) => {
                return match decoder.next()? {
                    Record::End => Ok(Err(e)),
                    other => Err(unexpected(&other)),
                };
            }
            Record::End if components.len() == 3 => {
                return Ok(Ok(components
                    .try_into()
                    .expect("invariant: three components were checked")));
            }
            other => return Err(unexpected(&other)),
        }
    }
}

/// [`crate::vdb::list_grids`] in a child process of `reader_exe`.
///
/// # Errors
/// As [`read_float_grids_isolated`].
pub fn list_grids_isolated(
    reader_exe: &ReaderCommand,
    path: &Path,
    limits: &IsolationLimits,
) -> Result<Vec<GridInfo>> {
    check_file(path)?;
    let args: Vec<OsString> = vec!["list".into(), path.into()];
    let mut run = ReaderRun::spawn(reader_exe, &args, limits)?;
    // Listing moves no bulk data
    let outcome = run.parse(0, |decoder| {
        let reply = match decoder.next()? {
            Record::Infos(infos) => Ok(infos),
            Record::Failed(e) => Err(e),
            other => return Err(unexpected(&other)),
        };
        match decoder.next()? {
            Record::End => Ok(reply),
            other => Err(unexpected(&other)),
        }
    });
    run.finish(path, outcome, None, limits)?.map_err(|e| child_error(path, e, None, limits))
}

/// The records of a `read` reply, checked against the requests: each request is answered
/// in order, by BEGIN + GRID for the alternative announced, or by ABSENT if optional.
/// `grid` tracks the selector being read, for crash messages.
fn parse_read_reply<R: Read>(
    decoder: &mut Decoder<R>,
    requests: &[GridRequest],
    grid: &mut Option<String>,
) -> std::result::Result<std::result::Result<Vec<Option<FoundGrid>>, ChildError>, WireError> {
    let mut found: Vec<Option<FoundGrid>> = Vec::with_capacity(requests.len());
    let mut begun: Option<(usize, usize)> = None;
    loop {
        let next = requests.get(found.len());
        match decoder.next()? {
            Record::Begin { request, alternative } => {
                let (request, alternative) = (request as usize, alternative as usize);
                match next {
                    Some(r) if request == found.len() && alternative < r.alternatives.len() => {
                        *grid = Some(r.alternatives[alternative].to_string());
                        begun = Some((request, alternative));
                    }
                    _ => return Err(malformed_reply("BEGIN out of order")),
                }
            }
            Record::Grid { request, alternative, grid: g } => {
                let (request, alternative) = (request as usize, alternative as usize);
                if begun != Some((request, alternative))
                    || next.is_none_or(|r| r.alternatives[alternative].name != g.name)
                {
                    return Err(malformed_reply("GRID does not answer the grid begun"));
                }
                found.push(Some(FoundGrid { alternative, grid: g }));
                begun = None;
                *grid = None;
            }
            Record::Absent { request } => match next {
                Some(r) if request as usize == found.len() && !r.required && begun.is_none() => {
                    found.push(None);
                }
                _ => return Err(malformed_reply("ABSENT out of order")),
            },
            Record::Failed(e) => {
                return match decoder.next()? {
                    Record::End => Ok(Err(e)),
                    other => Err(unexpected(&other)),
                };
            }
            Record::End if found.len() == requests.len() => return Ok(Ok(found)),
            other => return Err(unexpected(&other)),
        }
    }
}

pub(in crate::vdb) fn malformed_reply(message: &str) -> WireError {
    WireError::Malformed(message.to_string())
}

pub(in crate::vdb) fn unexpected(record: &Record) -> WireError {
    let name = match record {
        Record::Begin { .. } => "BEGIN",
        Record::Grid { .. } => "GRID",
        Record::Absent { .. } => "ABSENT",
        Record::Infos(_) => "INFOS",
        Record::Failed(_) => "FAILED",
        Record::End => "END",
        Record::Stream(_) => "STREAM",
        Record::Leaves => "LEAVES",
        Record::Tiles => "TILES",
    };
    WireError::Malformed(format!("unexpected {name} record"))
}

/// The error the child reported cleanly, as the in-process reader would have returned it.
pub(in crate::vdb) fn child_error(
    path: &Path,
    error: ChildError,
    grid: Option<String>,
    limits: &IsolationLimits,
) -> Error {
    let path = path.to_path_buf();
    match error {
        ChildError::Open { message } => Error::Open { path, source: io::Error::other(message) },
        ChildError::Vdb { message } => Error::Vdb { path, message },
        ChildError::GridNotFound { name, available } => {
            Error::GridNotFound { path, name, available }
        }
        ChildError::Unsupported { grid, message } => Error::UnsupportedGrid { path, grid, message },
        ChildError::TooLarge { grid, needed, limit } => {
            Error::TooLarge { path, grid, needed, limit }
        }
        ChildError::OutOfMemory => Error::ReaderFailed {
            path,
            grid,
            what: format!("reader ran out of memory at its limit of {} bytes", limits.memory_bytes),
        },
    }
}

#[cfg(test)]
mod tests {
    use glam::{DAffine3, DVec3, IVec3};

    use super::*;
    use crate::vdb::read::BYTES_PER_LEAF;
    use crate::vdb::wire::Encoder;
    use plume_volume::grid::LEAF_VOXELS;

    fn component(axis: &str, origins: &[IVec3]) -> FloatGrid {
        FloatGrid {
            name: format!("vel.{axis}"),
            world_from_index: DAffine3::from_scale(DVec3::splat(0.5)),
            background: 0.0,
            origins: origins.to_vec(),
            values: vec![1.0; origins.len() * LEAF_VOXELS],
        }
    }

    fn components() -> Vec<FloatGrid> {
        let origins = [IVec3::new(0, 8, -16), IVec3::new(8, 0, 0)];
        ["x", "y", "z"].iter().map(|axis| component(axis, &origins)).collect()
    }

    /// A `vec3` reply made of BEGIN 0 0 (if `begin`) and one GRID 0 0 per grid, then END.
    fn reply(begin: bool, grids: &[FloatGrid]) -> Vec<u8> {
        let mut bytes = Vec::new();
        let mut e = Encoder::new(&mut bytes).unwrap();
        if begin {
            e.begin(0, 0).unwrap();
        }
        for g in grids {
            e.grid(0, 0, g).unwrap();
        }
        e.end().unwrap();
        bytes
    }

    fn parse(
        bytes: &[u8],
        max_grid_bytes: u64,
    ) -> std::result::Result<std::result::Result<[FloatGrid; 3], ChildError>, WireError> {
        let mut decoder = Decoder::new(bytes, max_grid_bytes)?;
        let mut grid = None;
        parse_vec3_reply(&mut decoder, &GridSelector::first("vel"), &mut grid)
    }

    #[track_caller]
    fn assert_malformed(bytes: &[u8], needle: &str) {
        match parse(bytes, u64::MAX) {
            Err(WireError::Malformed(message)) => {
                assert!(message.contains(needle), "{message:?} lacks {needle:?}")
            }
            other => panic!("expected a malformed reply, got {other:?}"),
        }
    }

    #[test]
    fn a_vec3_reply_is_three_components_in_order() {
        let grids = parse(&reply(true, &components()), u64::MAX).unwrap().unwrap();
        assert_eq!(grids.each_ref().map(|g| g.name.as_str()), ["vel.x", "vel.y", "vel.z"]);
        // Each component within a third of the limit: 2 leaves each
        assert!(parse(&reply(true, &components()), 2 * BYTES_PER_LEAF).unwrap().is_ok());
        assert!(matches!(
            parse(&reply(true, &components()), 2 * BYTES_PER_LEAF - 1),
            Err(WireError::Malformed(_))
        ));
        // A clean failure, with or without BEGIN
        for begin in [false, true] {
            let mut bytes = Vec::new();
            let mut e = Encoder::new(&mut bytes).unwrap();
            if begin {
                e.begin(0, 0).unwrap();
            }
            e.failed(&ChildError::Unsupported { grid: "vel".into(), message: "float".into() })
                .unwrap();
            e.end().unwrap();
            assert!(matches!(parse(&bytes, u64::MAX), Ok(Err(ChildError::Unsupported { .. }))));
        }
    }

    #[test]
    fn bad_vec3_replies_are_refused() {
        let good = components();
        let (x, y, z) = (&good[0], &good[1], &good[2]);
        assert_malformed(&reply(false, &good), "unexpected GRID");
        assert_malformed(&reply(true, &[x.clone(), z.clone(), y.clone()]), "is not component y");
        assert_malformed(&reply(true, &[x.clone(), y.clone()]), "unexpected END");
        assert_malformed(
            &reply(true, &[x.clone(), y.clone(), z.clone(), x.clone()]),
            "unexpected GRID",
        );
        let mut moved = y.clone();
        moved.origins[1] = IVec3::new(16, 0, 0);
        assert_malformed(
            &reply(true, &[x.clone(), moved, z.clone()]),
            "differ in leaves or transform",
        );
        let mut shorter = z.clone();
        shorter.origins.pop();
        shorter.values.truncate(LEAF_VOXELS);
        assert_malformed(
            &reply(true, &[x.clone(), y.clone(), shorter]),
            "differ in leaves or transform",
        );
        let mut shifted = y.clone();
        shifted.world_from_index.translation.x = 1.0;
        assert_malformed(
            &reply(true, &[x.clone(), shifted, z.clone()]),
            "differ in leaves or transform",
        );
        let mut renamed = x.clone();
        renamed.name = "density.x".into();
        assert_malformed(&reply(true, &[renamed, y.clone(), z.clone()]), "is not component x");
    }
}
