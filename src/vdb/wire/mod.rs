//! The isolated reader's reply format: what `plume __read-grids` writes to its stdout and
//! the parent parses (see `vdb/isolate/`).
//!
//! The parser treats the stream as hostile: the child runs OpenVDB on an untrusted file, so
//! a memory error there could make it write anything. Every length is checked against a
//! limit before anything is sized from it, bulk data is appended as it arrives (so a lying
//! count costs only the bytes actually sent), and values are checked as they are decoded.
//!
//! # Format (version 1, little-endian)
//!
//! ```text
//! stream  := MAGIC (8 bytes "plumeRD\n") VERSION (u32) record* END
//! record  := tag (u8) body
//!   0x01 BEGIN   request u32, alternative u32        about to read that grid (progress)
//!   0x02 GRID    request u32, alternative u32, name str, world_from_index 12 × f64,
//!                background f32, leaf_count u64, origins 3·leaf_count × i32,
//!                values 512·leaf_count × f32
//!   0x03 ABSENT  request u32                         optional request, no alternative exists
//!   0x04 INFOS   count u32, count × grid info        the reply to a listing
//!   0x05 FAILED  error                               the read failed cleanly; END follows
//!   0x06 END                                         nothing follows
//!   0x07 STREAM, 0x08 LEAVES, 0x09 TILES             a streamed grid (`wire/stream/`)
//! str     := length u32, UTF-8 bytes
//! error   := kind u8, fields (see `ChildError`)
//! ```
//!
//! Records answer the requests in order: each request gets BEGIN then GRID, or ABSENT, or
//! the stream fails. A grid's bulk data goes out as whole slices, not value by value.
//! A `stream` command is answered by BEGIN, STREAM, LEAVES…, TILES…, END instead, and a
//! `vec3` command (one vector grid) by BEGIN 0 0 then three GRID 0 0 records, the
//! components `NAME.x`, `NAME.y`, `NAME.z` with identical origins and transform, each
//! within a third of the memory limit (the parent checks all of it; the records are the
//! version-1 records, so the version is unchanged).
//!
//! `Encoder` (`encode.rs`) writes the records in the child, `Decoder` (`decode.rs`)
//! parses them in the parent; the records of a streamed grid are in `stream/`.

mod decode;
mod encode;
mod stream;

use std::io;

use super::stream::StreamedGrid;
use super::{FloatGrid, GridInfo};
use plume_core::error::Error;

pub use decode::parse_reply;
pub(crate) use decode::Decoder;
pub(crate) use encode::Encoder;

/// First bytes of every reply.
pub(crate) const MAGIC: [u8; 8] = *b"plumeRD\n";
/// Format version; parent and child are the same binary, so a mismatch means the binary
/// was replaced while plume ran.
pub(crate) const VERSION: u32 = 1;

const TAG_BEGIN: u8 = 0x01;
const TAG_GRID: u8 = 0x02;
const TAG_ABSENT: u8 = 0x03;
const TAG_INFOS: u8 = 0x04;
const TAG_FAILED: u8 = 0x05;
const TAG_END: u8 = 0x06;

/// Longest string (grid name, type, error message) accepted.
pub(crate) const MAX_STRING_BYTES: usize = 64 * 1024;
/// Most bytes of strings and list entries one reply may make the parent allocate, bulk
/// grid data excepted (that is bounded by `ReadLimits::max_bytes` per grid).
pub(crate) const MAX_METADATA_BYTES: usize = 64 << 20;

/// Values converted per bulk write or read (256 KiB of bytes).
const BULK_CHUNK: usize = 64 * 1024;

/// A failure the child reports cleanly: the in-process reader's errors, minus the path
/// (the parent knows it).
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum ChildError {
    /// [`Error::Open`]: the OS error's text.
    Open { message: String },
    /// [`Error::Vdb`].
    Vdb { message: String },
    /// [`Error::GridNotFound`].
    GridNotFound { name: String, available: Vec<String> },
    /// [`Error::UnsupportedGrid`].
    Unsupported { grid: String, message: String },
    /// [`Error::TooLarge`].
    TooLarge { grid: String, needed: u64, limit: u64 },
    /// An allocation failed under the child's memory limit.
    OutOfMemory,
}

impl ChildError {
    /// The child's view of an in-process error. The shim reports `std::bad_alloc` as the
    /// message "out of memory"; under the reader's memory limit that is what hostile sizes
    /// end in.
    pub(crate) fn from_error(error: &Error) -> ChildError {
        match error {
            Error::Open { source, .. } => ChildError::Open { message: source.to_string() },
            Error::Vdb { message, .. } if message == "out of memory" => ChildError::OutOfMemory,
            Error::Vdb { message, .. } => ChildError::Vdb { message: message.clone() },
            Error::GridNotFound { name, available, .. } => {
                ChildError::GridNotFound { name: name.clone(), available: available.clone() }
            }
            Error::UnsupportedGrid { grid, message, .. } => {
                ChildError::Unsupported { grid: grid.clone(), message: message.clone() }
            }
            Error::TooLarge { grid, needed, limit, .. } => {
                ChildError::TooLarge { grid: grid.clone(), needed: *needed, limit: *limit }
            }
            other => ChildError::Vdb { message: other.to_string() },
        }
    }
}

/// One parsed record. `Leaves` and `Tiles` leave their batch in
/// [`Decoder::leaf_batch`] and [`Decoder::tile_batch`].
#[derive(Debug)]
pub(crate) enum Record {
    Begin { request: u32, alternative: u32 },
    Grid { request: u32, alternative: u32, grid: FloatGrid },
    Absent { request: u32 },
    Infos(Vec<GridInfo>),
    Failed(ChildError),
    End,
    Stream(StreamedGrid),
    Leaves,
    Tiles,
}

/// Why a reply could not be parsed.
#[derive(Debug)]
pub(crate) enum WireError {
    /// Reading the pipe failed; `ErrorKind::UnexpectedEof` when the stream stopped early,
    /// `ErrorKind::TimedOut` when the parent's deadline passed.
    Io(io::Error),
    /// The bytes are not a valid reply.
    Malformed(String),
}

impl From<io::Error> for WireError {
    fn from(e: io::Error) -> WireError {
        WireError::Io(e)
    }
}

#[cfg(test)]
mod tests {
    use std::io;

    use glam::{DAffine3, IVec3};

    use super::*;
    use crate::vdb::read::BYTES_PER_LEAF;
    use plume_volume::grid::LEAF_VOXELS;

    fn grid(leaves: usize) -> FloatGrid {
        FloatGrid {
            name: "density".into(),
            world_from_index: DAffine3::from_scale(glam::DVec3::splat(0.5)),
            background: 0.25,
            origins: (0..leaves as i32).map(|i| IVec3::new(8 * i, -8, 16)).collect(),
            values: (0..leaves * LEAF_VOXELS).map(|i| i as f32 * 0.5).collect(),
        }
    }

    fn info() -> GridInfo {
        GridInfo {
            name: "dénsity".into(),
            file_index: 3,
            selector: "dénsity[1]".into(),
            value_type: "float".into(),
            class: "fog volume".into(),
            active_voxels: 1 << 40,
            leaf_count: 7,
            active_tiles: 2,
            index_bbox: Some([[-1, 2, -3], [4, i32::MAX, i32::MIN]]),
            voxel_size: [0.5, 0.25, 1e-9],
            transform: "affine".into(),
            min: Some(-1.0),
            max: None,
            mean: Some(f64::MAX),
            memory_bytes: 12345,
        }
    }

    /// A reply written by `f`, ended (shared with the stream records' tests).
    pub(super) fn encode(f: impl FnOnce(&mut Encoder<&mut Vec<u8>>)) -> Vec<u8> {
        let mut bytes = Vec::new();
        let mut e = Encoder::new(&mut bytes).unwrap();
        f(&mut e);
        e.end().unwrap();
        bytes
    }

    fn decode_all(bytes: &[u8], max_grid_bytes: u64) -> Result<Vec<Record>, WireError> {
        let mut d = Decoder::new(bytes, max_grid_bytes)?;
        let mut records = Vec::new();
        loop {
            match d.next()? {
                Record::End => return Ok(records),
                r => records.push(r),
            }
        }
    }

    #[test]
    fn records_round_trip() {
        let g = grid(3);
        let errors = [
            ChildError::Open { message: "No such file".into() },
            ChildError::Vdb { message: "bad".into() },
            ChildError::GridNotFound {
                name: "d".into(),
                available: vec!["a".into(), "b[1]".into()],
            },
            ChildError::Unsupported { grid: "v".into(), message: "vec3s".into() },
            ChildError::TooLarge { grid: "g".into(), needed: 10, limit: 5 },
            ChildError::OutOfMemory,
        ];
        let bytes = encode(|e| {
            e.begin(0, 1).unwrap();
            e.grid(0, 1, &g).unwrap();
            e.absent(1).unwrap();
            e.infos(&[info(), info()]).unwrap();
            for err in &errors {
                e.failed(err).unwrap();
            }
        });
        let records = decode_all(&bytes, u64::MAX).unwrap();
        assert!(matches!(records[0], Record::Begin { request: 0, alternative: 1 }));
        match &records[1] {
            Record::Grid { request: 0, alternative: 1, grid } => {
                assert_eq!(grid.name, g.name);
                assert_eq!(grid.world_from_index, g.world_from_index);
                assert_eq!(grid.background, g.background);
                assert_eq!(grid.origins, g.origins);
                assert_eq!(grid.values, g.values);
            }
            other => panic!("{other:?}"),
        }
        assert!(matches!(records[2], Record::Absent { request: 1 }));
        match &records[3] {
            Record::Infos(infos) => {
                assert_eq!(infos.len(), 2);
                let json = |i: &GridInfo| serde_json::to_string(i).unwrap();
                assert_eq!(json(&infos[1]), json(&info()));
            }
            other => panic!("{other:?}"),
        }
        for (record, expected) in records[4..].iter().zip(&errors) {
            match record {
                Record::Failed(e) => assert_eq!(e, expected),
                other => panic!("{other:?}"),
            }
        }
    }

    #[test]
    fn every_truncation_is_an_error_not_a_panic() {
        let bytes = encode(|e| {
            e.begin(0, 0).unwrap();
            e.grid(0, 0, &grid(2)).unwrap();
            e.infos(&[info()]).unwrap();
            e.failed(&ChildError::GridNotFound { name: "x".into(), available: vec!["y".into()] })
                .unwrap();
        });
        for len in 0..bytes.len() {
            match decode_all(&bytes[..len], u64::MAX) {
                Err(WireError::Io(e)) => assert_eq!(e.kind(), io::ErrorKind::UnexpectedEof),
                other => panic!("cut at {len}: {other:?}"),
            }
        }
    }

    #[test]
    fn lying_lengths_are_refused_before_allocating() {
        // A grid claiming 2^61 leaves, then nothing.
        let mut bytes = MAGIC.to_vec();
        bytes.extend(VERSION.to_le_bytes());
        bytes.push(TAG_GRID);
        bytes.extend([0u8; 8]);
        bytes.extend(1u32.to_le_bytes());
        bytes.push(b'd');
        bytes.extend([0u8; 12 * 8 + 4]);
        bytes.extend((1u64 << 61).to_le_bytes());
        assert!(matches!(decode_all(&bytes, u64::MAX), Err(WireError::Malformed(_))));
        // Within a limit it is refused against the limit.
        let ok = encode(|e| e.grid(0, 0, &grid(4)).unwrap());
        assert!(decode_all(&ok, 4 * BYTES_PER_LEAF).is_ok());
        assert!(matches!(decode_all(&ok, 4 * BYTES_PER_LEAF - 1), Err(WireError::Malformed(_))));
        // A huge string, and a list that would blow the metadata budget.
        let mut bytes = MAGIC.to_vec();
        bytes.extend(VERSION.to_le_bytes());
        bytes.push(TAG_FAILED);
        bytes.push(2);
        bytes.extend(u32::MAX.to_le_bytes());
        assert!(matches!(decode_all(&bytes, u64::MAX), Err(WireError::Malformed(_))));
        let mut bytes = MAGIC.to_vec();
        bytes.extend(VERSION.to_le_bytes());
        bytes.push(TAG_INFOS);
        bytes.extend(u32::MAX.to_le_bytes());
        assert!(matches!(decode_all(&bytes, u64::MAX), Err(WireError::Malformed(_))));
    }

    #[test]
    fn bad_values_are_refused() {
        let mut g = grid(1);
        g.values[7] = f32::NAN;
        let bytes = encode(|e| e.grid(0, 0, &g).unwrap());
        assert!(matches!(decode_all(&bytes, u64::MAX), Err(WireError::Malformed(_))));
        let mut g = grid(1);
        g.origins[0].y = 3;
        let bytes = encode(|e| e.grid(0, 0, &g).unwrap());
        assert!(matches!(decode_all(&bytes, u64::MAX), Err(WireError::Malformed(_))));
        let mut bytes = encode(|_| {});
        bytes[0] ^= 1;
        assert!(matches!(decode_all(&bytes, u64::MAX), Err(WireError::Malformed(_))));
    }
}
