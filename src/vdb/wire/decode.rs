//! The parent's side of the reply format (see [`super`]): [`Decoder`] parses it record by
//! record, treating it as hostile (every length checked before anything is sized from it),
//! and [`parse_reply`] is the fuzzing entry point over a whole reply.

use std::io::Read;

use glam::{DAffine3, IVec3};

use super::stream::{Batch, TAG_LEAVES, TAG_STREAM, TAG_TILES};
use super::{ChildError, Record, WireError, BULK_CHUNK, MAGIC, MAX_METADATA_BYTES};
use super::{MAX_STRING_BYTES, TAG_ABSENT, TAG_BEGIN, TAG_END, TAG_FAILED, TAG_GRID};
use super::{TAG_INFOS, VERSION};
use crate::vdb::read::BYTES_PER_LEAF;
use crate::vdb::{FloatGrid, GridInfo, LEAF_DIM, LEAF_VOXELS};

pub(super) fn malformed<T>(message: impl Into<String>) -> Result<T, WireError> {
    Err(WireError::Malformed(message.into()))
}

/// Parses records; the parent's side.
pub(crate) struct Decoder<R: Read> {
    input: R,
    /// Largest bulk payload of one grid, as for the in-process reader.
    max_grid_bytes: u64,
    /// What strings and lists may still allocate.
    metadata_budget: usize,
    pub(super) scratch: Vec<u8>,
    /// The last LEAVES or TILES record.
    pub(super) batch: Batch,
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
        Ok(FloatGrid { name, world_from_index, background, origins, values })
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
    pub(super) fn fill_scratch(&mut self, bytes: usize) -> Result<(), WireError> {
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

    pub(super) fn flag(&mut self) -> Result<bool, WireError> {
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

    pub(super) fn u32(&mut self) -> Result<u32, WireError> {
        Ok(u32::from_le_bytes(self.bytes()?))
    }

    pub(super) fn u64(&mut self) -> Result<u64, WireError> {
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
