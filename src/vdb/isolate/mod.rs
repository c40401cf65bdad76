//! Reading untrusted VDB files in a child process, so that no file can crash, hang or
//! exhaust plume.
//!
//! OpenVDB 10.0.1 segfaults or hangs on a few per cent of randomly mutated copies of real
//! files (`tests/fuzz_mutants.rs`). No amount of checking in the shim makes a C++ parser of
//! that size safe, so plume runs it where a crash cannot hurt: `plume __read-grids …`, a
//! hidden subcommand of the same binary, started with
//!
//! - `RLIMIT_DATA` = [`IsolationLimits::memory_bytes`]: an allocation sized by a lying
//!   header fails (`std::bad_alloc` → a clean "out of memory" reply, or an abort);
//! - `RLIMIT_CPU` = [`IsolationLimits::cpu_seconds`], `RLIMIT_CORE` = 0, no core dumps
//!   (`PR_SET_DUMPABLE` 0), `PR_SET_PDEATHSIG` so that it dies with its parent, and
//!   `oom_score_adj` 1000 so that the kernel's OOM killer takes it first;
//! - a wall-clock deadline ([`IsolationLimits::timeout`]) enforced by the parent, which
//!   `poll`s the pipes and kills the child when it passes.
//!
//! The child streams the grids back over its stdout in the format of `wire/` (magic,
//! version, then one record per grid with bulk `f32` data); the parent parses it
//! defensively, with every length checked before anything is sized from it. A `BEGIN`
//! record is flushed before each grid is read, so a crash names the grid. Every failure
//! becomes [`Error::ReaderFailed`], one line, exit code 3.
//!
//! In-process reading ([`super::read_grids`], [`super::list_grids`]) stays available for
//! trusted files and for library callers; [`ReadIsolation`] chooses.
//!
//! # Child command line
//!
//! ```text
//! plume __read-grids list FILE
//! plume __read-grids read FILE MAX_BYTES (need|want) N SEL_1 … SEL_N  [(need|want) N …]
//! plume __read-grids stream FILE MAX_BYTES SEL
//! plume __read-grids vec3 FILE MAX_BYTES SEL
//! ```
//!
//! `need` is a required [`GridRequest`], `want` an optional one; `MAX_BYTES` is
//! [`ReadLimits::max_bytes`]; `stream` sends one grid batch by batch of leaves
//! ([`super::stream_float_grid_isolated`]); `vec3` sends one vector grid as three
//! component grids ([`read_vec3_grid_isolated`]). The command can be run by hand to replay a
//! failure (the reply is binary: pipe it into `xxd`).
//!
//! # Files
//!
//! - `parent.rs`: [`ReadIsolation`], the requests sent to the child and the decoding of its
//!   replies;
//! - `process.rs`: one reader process: spawned under its limits, its pipes polled under the
//!   deadline, its exit status turned into an error;
//! - `child.rs`: [`reader_main`], what runs inside `plume __read-grids`.
//!
//! [`GridRequest`]: crate::vdb::GridRequest
//! [`Error::ReaderFailed`]: plume_core::error::Error::ReaderFailed

mod child;
mod parent;
mod process;

use std::time::Duration;

use super::ReadLimits;

pub use child::{reader_main, ReaderFailure};
pub(in crate::vdb) use parent::{child_error, malformed_reply, unexpected};
pub use parent::{
    list_grids_isolated, read_float_grids_isolated, read_grids_isolated, read_vec3_grid_isolated,
    reader_exe, set_reader_command, set_reader_exe, ReadIsolation, ReaderCommand,
};
pub(in crate::vdb) use process::{ChildPipes, Parsed, ReaderRun};

/// The hidden subcommand (`argv[1]`) that runs the reader; `main.rs` dispatches on it
/// before parsing the command line.
pub const READER_SUBCOMMAND: &str = "__read-grids";

/// Default wall-clock limit of one isolated read (`--read-timeout`).
pub const DEFAULT_TIMEOUT: Duration = Duration::from_secs(120);

/// Memory the reader process needs beyond the grids themselves: code, libraries, OpenVDB's
/// registries, stacks and pipe buffers (an empty read peaks at a small part of this).
pub const BASE_MEMORY_BYTES: u64 = 256 << 20;

/// Resource limits of the reader process.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct IsolationLimits {
    /// `RLIMIT_DATA` of the child, bytes (heap and private writable mappings).
    pub memory_bytes: u64,
    /// `RLIMIT_CPU` of the child, seconds (SIGXCPU, then SIGKILL a second later).
    pub cpu_seconds: u64,
    /// Wall-clock limit from spawn to exit; the parent kills the child when it passes.
    pub timeout: Duration,
}

impl IsolationLimits {
    /// Limits for reads under `read_limits`: memory `2 × max_bytes + 256 MiB` (OpenVDB's
    /// tree plus the voxelized copy of one grid; grids are sent and freed one at a time),
    /// CPU time equal to `timeout`.
    #[must_use]
    pub fn new(read_limits: &ReadLimits, timeout: Duration) -> IsolationLimits {
        IsolationLimits {
            memory_bytes: read_limits.max_bytes.saturating_mul(2).saturating_add(BASE_MEMORY_BYTES),
            cpu_seconds: timeout.as_secs_f64().ceil().max(1.0) as u64,
            timeout,
        }
    }
}
