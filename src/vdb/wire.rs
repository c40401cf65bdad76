//! The isolated reader's reply format: what `plume __read-grids` writes to its stdout and
//! the parent parses (see `isolate.rs`).
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
//!   0x07 STREAM, 0x08 LEAVES, 0x09 TILES             a streamed grid (`wire/stream.rs`)
//! str     := length u32, UTF-8 bytes
//! error   := kind u8, fields (see `ChildError`)
//! ```
//!
//! Records answer the requests in order: each request gets BEGIN then GRID, or ABSENT, or
//! the stream fails. A grid's bulk data goes out as whole slices, not value by value.
//! A `stream` command is answered by BEGIN, STREAM, LEAVES…, TILES…, END instead.

mod stream;

use std::io::{self, Read, Write};

use glam::{DAffine3, IVec3};

use self::stream::{Batch, TAG_LEAVES, TAG_STREAM, TAG_TILES};
use super::read::BYTES_PER_LEAF;
use super::stream::StreamedGrid;
use super::{FloatGrid, GridInfo, LEAF_DIM, LEAF_VOXELS};
use crate::error::Error;

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

/// Writes records; the child's side.
pub(crate) struct Encoder<W: Write> {
    out: W,
    scratch: Vec<u8>,
}

impl<W: Write> Encoder<W> {
    /// Writes the stream header.
    pub(crate) fn new(mut out: W) -> io::Result<Encoder<W>> {
        out.write_all(&MAGIC)?;
        out.write_all(&VERSION.to_le_bytes())?;
        Ok(Encoder { out, scratch: Vec::with_capacity(BULK_CHUNK * 4) })
    }

    /// Announces the grid about to be read, and flushes so that the parent knows it even
    /// if the read then crashes.
    pub(crate) fn begin(&mut self, request: u32, alternative: u32) -> io::Result<()> {
        self.out.write_all(&[TAG_BEGIN])?;
        self.u32(request)?;
        self.u32(alternative)?;
        self.out.flush()
    }

    pub(crate) fn grid(
        &mut self,
        request: u32,
        alternative: u32,
        grid: &FloatGrid,
    ) -> io::Result<()> {
        self.out.write_all(&[TAG_GRID])?;
        self.u32(request)?;
        self.u32(alternative)?;
        self.str(&grid.name)?;
        for c in grid.world_from_index.to_cols_array() {
            self.out.write_all(&c.to_le_bytes())?;
        }
        self.out.write_all(&grid.background.to_le_bytes())?;
        self.u64(grid.origins.len() as u64)?;
        for chunk in grid.origins.chunks(BULK_CHUNK / 3) {
            self.scratch.clear();
            for o in chunk {
                for c in o.to_array() {
                    self.scratch.extend_from_slice(&c.to_le_bytes());
                }
            }
            self.out.write_all(&self.scratch)?;
        }
        for chunk in grid.values.chunks(BULK_CHUNK) {
            self.scratch.clear();
            self.scratch.extend(chunk.iter().flat_map(|v| v.to_le_bytes()));
            self.out.write_all(&self.scratch)?;
        }
        self.out.flush()
    }

    pub(crate) fn absent(&mut self, request: u32) -> io::Result<()> {
        self.out.write_all(&[TAG_ABSENT])?;
        self.u32(request)
    }

    pub(crate) fn infos(&mut self, infos: &[GridInfo]) -> io::Result<()> {
        self.out.write_all(&[TAG_INFOS])?;
        self.u32(len_u32(infos.len()))?;
        for info in infos {
            self.str(&info.name)?;
            self.u64(info.file_index as u64)?;
            self.str(&info.selector)?;
            self.str(&info.value_type)?;
            self.str(&info.class)?;
            self.u64(info.active_voxels)?;
            self.u64(info.leaf_count)?;
            self.u64(info.active_tiles)?;
            match info.index_bbox {
                Some(bbox) => {
                    self.out.write_all(&[1])?;
                    for c in bbox.iter().flatten() {
                        self.out.write_all(&c.to_le_bytes())?;
                    }
                }
                None => self.out.write_all(&[0])?,
            }
            for v in info.voxel_size {
                self.out.write_all(&v.to_le_bytes())?;
            }
            self.str(&info.transform)?;
            for stat in [info.min, info.max, info.mean] {
                match stat {
                    Some(v) => {
                        self.out.write_all(&[1])?;
                        self.out.write_all(&v.to_le_bytes())?;
                    }
                    None => self.out.write_all(&[0])?,
                }
            }
            self.u64(info.memory_bytes)?;
        }
        Ok(())
    }

    pub(crate) fn failed(&mut self, error: &ChildError) -> io::Result<()> {
        self.out.write_all(&[TAG_FAILED])?;
        match error {
            ChildError::Open { message } => {
                self.out.write_all(&[1])?;
                self.str(message)
            }
            ChildError::Vdb { message } => {
                self.out.write_all(&[2])?;
                self.str(message)
            }
            ChildError::GridNotFound { name, available } => {
                self.out.write_all(&[3])?;
                self.str(name)?;
                self.u32(len_u32(available.len()))?;
                available.iter().try_for_each(|a| self.str(a))
            }
            ChildError::Unsupported { grid, message } => {
                self.out.write_all(&[4])?;
                self.str(grid)?;
                self.str(message)
            }
            ChildError::TooLarge { grid, needed, limit } => {
                self.out.write_all(&[5])?;
                self.str(grid)?;
                self.u64(*needed)?;
                self.u64(*limit)
            }
            ChildError::OutOfMemory => self.out.write_all(&[6]),
        }
    }

    /// Ends the stream and flushes it.
    pub(crate) fn end(mut self) -> io::Result<W> {
        self.out.write_all(&[TAG_END])?;
        self.out.flush()?;
        Ok(self.out)
    }

    fn u32(&mut self, v: u32) -> io::Result<()> {
        self.out.write_all(&v.to_le_bytes())
    }

    fn u64(&mut self, v: u64) -> io::Result<()> {
        self.out.write_all(&v.to_le_bytes())
    }

    /// Strings longer than [`MAX_STRING_BYTES`] are cut at a character boundary (the
    /// parser would refuse them whole).
    fn str(&mut self, s: &str) -> io::Result<()> {
        let mut end = s.len().min(MAX_STRING_BYTES);
        while !s.is_char_boundary(end) {
            end -= 1;
        }
        self.u32(len_u32(end))?;
        self.out.write_all(&s.as_bytes()[..end])
    }
}

/// Lists are bounded far below `u32::MAX` by the metadata budget, so saturating is only a
/// guard: the parser then refuses the list.
fn len_u32(len: usize) -> u32 {
    u32::try_from(len).unwrap_or(u32::MAX)
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

fn malformed<T>(message: impl Into<String>) -> Result<T, WireError> {
    Err(WireError::Malformed(message.into()))
}

/// Parses records; the parent's side.
pub(crate) struct Decoder<R: Read> {
    input: R,
    /// Largest bulk payload of one grid, as for the in-process reader.
    max_grid_bytes: u64,
    /// What strings and lists may still allocate.
    metadata_budget: usize,
    scratch: Vec<u8>,
    /// The last LEAVES or TILES record.
    batch: Batch,
}

impl<R: Read> Decoder<R> {
    /// Checks the stream header.
    pub(crate) fn new(mut input: R, max_grid_bytes: u64) -> Result<Decoder<R>, WireError> {
        let mut magic = [0u8; 8];
        input.read_exact(&mut magic)?;
        if magic != MAGIC {
            return malformed(format!("bad magic {magic:02x?}"));
        }
        let mut version = [0u8; 4];
        input.read_exact(&mut version)?;
        let version = u32::from_le_bytes(version);
        if version != VERSION {
            return malformed(format!(
                "format version {version}, expected {VERSION} (was plume replaced while running?)"
            ));
        }
        Ok(Decoder {
            input,
            max_grid_bytes,
            metadata_budget: MAX_METADATA_BYTES,
            scratch: Vec::new(),
            batch: Batch::default(),
        })
    }

    /// The underlying reader, e.g. to check that nothing follows END.
    pub(crate) fn input(&mut self) -> &mut R {
        &mut self.input
    }

    pub(crate) fn next(&mut self) -> Result<Record, WireError> {
        match self.u8()? {
            TAG_BEGIN => Ok(Record::Begin { request: self.u32()?, alternative: self.u32()? }),
            TAG_GRID => {
                let request = self.u32()?;
                let alternative = self.u32()?;
                Ok(Record::Grid { request, alternative, grid: self.grid()? })
            }
            TAG_ABSENT => Ok(Record::Absent { request: self.u32()? }),
            TAG_INFOS => {
                let count = self.count(std::mem::size_of::<GridInfo>(), "grid infos")?;
                let mut infos = Vec::with_capacity(count);
                for _ in 0..count {
                    infos.push(self.info()?);
                }
                Ok(Record::Infos(infos))
            }
            TAG_FAILED => Ok(Record::Failed(self.error()?)),
            TAG_END => Ok(Record::End),
            TAG_STREAM => Ok(Record::Stream(self.stream_head()?)),
            TAG_LEAVES => {
                self.leaves_record()?;
                Ok(Record::Leaves)
            }
            TAG_TILES => {
                self.tiles_record()?;
                Ok(Record::Tiles)
            }
            tag => malformed(format!("unknown record tag 0x{tag:02x}")),
        }
    }

    /// A grid's name, finite transform and finite background: how both a whole grid and a
    /// stream begin.
    pub(super) fn grid_head(&mut self) -> Result<(String, DAffine3, f32), WireError> {
        let name = self.str()?;
        let mut cols = [0.0f64; 12];
        for c in &mut cols {
            *c = self.f64()?;
        }
        if cols.iter().any(|c| !c.is_finite()) {
            return malformed(format!("grid {name:?}: non-finite transform"));
        }
        let background = self.f32()?;
        if !background.is_finite() {
            return malformed(format!("grid {name:?}: non-finite background"));
        }
        Ok((name, DAffine3::from_cols_array(&cols), background))
    }

    fn grid(&mut self) -> Result<FloatGrid, WireError> {
        let (name, world_from_index, background) = self.grid_head()?;
        let leaf_count = self.u64()?;
        let bytes = leaf_count.checked_mul(BYTES_PER_LEAF);
        let leaves = match (bytes, usize::try_from(leaf_count)) {
            (Some(bytes), Ok(leaves)) if bytes <= self.max_grid_bytes => leaves,
            _ => {
                return malformed(format!(
                    "grid {name:?}: {leaf_count} leaves exceed the input memory limit of {} bytes",
                    self.max_grid_bytes
                ))
            }
        };
        // Capacity is reserved, not touched: pages are committed only as data arrives.
        let mut origins: Vec<IVec3> = Vec::new();
        let mut values: Vec<f32> = Vec::new();
        if origins.try_reserve_exact(leaves).is_err()
            || values.try_reserve_exact(leaves * LEAF_VOXELS).is_err()
        {
            return malformed(format!("grid {name:?}: cannot allocate {leaf_count} leaves"));
        }
        let mut remaining = leaves;
        while remaining > 0 {
            let n = remaining.min(BULK_CHUNK / 3);
            self.fill_scratch(n * 12)?;
            for b in self.scratch.chunks_exact(12) {
                let c = |k: usize| i32::from_le_bytes([b[k], b[k + 1], b[k + 2], b[k + 3]]);
                origins.push(IVec3::new(c(0), c(4), c(8)));
            }
            remaining -= n;
        }
        if let Some(o) = origins.iter().find(|o| (**o % LEAF_DIM) != IVec3::ZERO) {
            return malformed(format!("grid {name:?}: leaf origin {o} is not a multiple of 8"));
        }
        let mut remaining = leaves * LEAF_VOXELS;
        while remaining > 0 {
            let n = remaining.min(BULK_CHUNK);
            self.fill_scratch(n * 4)?;
            values.extend(
                self.scratch.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            );
            remaining -= n;
        }
        if values.iter().any(|v| !v.is_finite()) {
            return malformed(format!("grid {name:?}: non-finite values"));
        }
        Ok(FloatGrid {
            name,
            world_from_index,
            background,
            origins,
            values,
        })
    }

    fn info(&mut self) -> Result<GridInfo, WireError> {
        let name = self.str()?;
        let file_index = usize::try_from(self.u64()?)
            .or_else(|_| malformed("grid info: file index out of range"))?;
        let selector = self.str()?;
        let value_type = self.str()?;
        let class = self.str()?;
        let active_voxels = self.u64()?;
        let leaf_count = self.u64()?;
        let active_tiles = self.u64()?;
        let index_bbox = if self.flag()? {
            let mut bbox = [[0i32; 3]; 2];
            for c in bbox.iter_mut().flatten() {
                *c = self.u32()? as i32;
            }
            Some(bbox)
        } else {
            None
        };
        let voxel_size = [self.f64()?, self.f64()?, self.f64()?];
        let transform = self.str()?;
        let mut stats = [None; 3];
        for s in &mut stats {
            if self.flag()? {
                *s = Some(self.f64()?);
            }
        }
        let memory_bytes = self.u64()?;
        Ok(GridInfo {
            name,
            file_index,
            selector,
            value_type,
            class,
            active_voxels,
            leaf_count,
            active_tiles,
            index_bbox,
            voxel_size,
            transform,
            min: stats[0],
            max: stats[1],
            mean: stats[2],
            memory_bytes,
        })
    }

    fn error(&mut self) -> Result<ChildError, WireError> {
        Ok(match self.u8()? {
            1 => ChildError::Open { message: self.str()? },
            2 => ChildError::Vdb { message: self.str()? },
            3 => {
                let name = self.str()?;
                let count = self.count(std::mem::size_of::<String>(), "available grids")?;
                let mut available = Vec::with_capacity(count);
                for _ in 0..count {
                    available.push(self.str()?);
                }
                ChildError::GridNotFound { name, available }
            }
            4 => ChildError::Unsupported { grid: self.str()?, message: self.str()? },
            5 => {
                ChildError::TooLarge { grid: self.str()?, needed: self.u64()?, limit: self.u64()? }
            }
            6 => ChildError::OutOfMemory,
            kind => return malformed(format!("unknown error kind {kind}")),
        })
    }

    /// Reads exactly `bytes` into the scratch buffer.
    fn fill_scratch(&mut self, bytes: usize) -> Result<(), WireError> {
        self.scratch.resize(bytes, 0);
        self.input.read_exact(&mut self.scratch)?;
        Ok(())
    }

    /// Takes `bytes` from the metadata budget.
    fn spend(&mut self, bytes: usize, what: &str) -> Result<(), WireError> {
        match self.metadata_budget.checked_sub(bytes) {
            Some(left) => {
                self.metadata_budget = left;
                Ok(())
            }
            None => {
                malformed(format!("{what}: reply exceeds {MAX_METADATA_BYTES} bytes of metadata"))
            }
        }
    }

    /// A list length, charged to the budget at `item_bytes` per entry.
    fn count(&mut self, item_bytes: usize, what: &str) -> Result<usize, WireError> {
        let count = self.u32()? as usize;
        self.spend(count.saturating_mul(item_bytes), what)?;
        Ok(count)
    }

    fn str(&mut self) -> Result<String, WireError> {
        let len = self.u32()? as usize;
        if len > MAX_STRING_BYTES {
            return malformed(format!("string of {len} bytes (at most {MAX_STRING_BYTES})"));
        }
        self.spend(len, "string")?;
        let mut bytes = vec![0u8; len];
        self.input.read_exact(&mut bytes)?;
        String::from_utf8(bytes).or_else(|_| malformed("string is not UTF-8"))
    }

    fn flag(&mut self) -> Result<bool, WireError> {
        match self.u8()? {
            0 => Ok(false),
            1 => Ok(true),
            b => malformed(format!("flag byte {b}")),
        }
    }

    fn bytes<const N: usize>(&mut self) -> Result<[u8; N], WireError> {
        let mut b = [0u8; N];
        self.input.read_exact(&mut b)?;
        Ok(b)
    }

    fn u8(&mut self) -> Result<u8, WireError> {
        Ok(self.bytes::<1>()?[0])
    }

    fn u32(&mut self) -> Result<u32, WireError> {
        Ok(u32::from_le_bytes(self.bytes()?))
    }

    fn u64(&mut self) -> Result<u64, WireError> {
        Ok(u64::from_le_bytes(self.bytes()?))
    }

    fn f32(&mut self) -> Result<f32, WireError> {
        Ok(f32::from_le_bytes(self.bytes()?))
    }

    fn f64(&mut self) -> Result<f64, WireError> {
        Ok(f64::from_le_bytes(self.bytes()?))
    }
}

/// Parses `bytes` as a whole reply, record by record, as the parent does; the entry point
/// of the coverage-guided fuzz target (`fuzz/fuzz_targets/wire_reply.rs`). Returns the
/// number of records before END, or why the bytes were refused. It must never panic,
/// hang or allocate more than `max_grid_bytes` per grid plus the metadata budget.
///
/// # Errors
/// A description of the first problem: early end, unknown tag, a length over a limit, …
#[doc(hidden)]
pub fn parse_reply(bytes: &[u8], max_grid_bytes: u64) -> Result<usize, String> {
    let describe = |e: WireError| match e {
        WireError::Io(e) => e.to_string(),
        WireError::Malformed(m) => m,
    };
    let mut decoder = Decoder::new(bytes, max_grid_bytes).map_err(describe)?;
    let mut records = 0;
    loop {
        match decoder.next().map_err(describe)? {
            Record::End => return Ok(records),
            _ => records += 1,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
