//! The child's side of the reply format (see [`super`]): [`Encoder`] writes the stream
//! header and one record per call, bulk data as whole slices.

use std::io::{self, Write};

use super::{ChildError, BULK_CHUNK, MAGIC, MAX_STRING_BYTES, VERSION};
use super::{TAG_ABSENT, TAG_BEGIN, TAG_END, TAG_FAILED, TAG_GRID, TAG_INFOS};
use crate::vdb::{FloatGrid, GridInfo};

/// Writes records; the child's side.
pub(crate) struct Encoder<W: Write> {
    pub(super) out: W,
    pub(super) scratch: Vec<u8>,
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

    pub(super) fn u32(&mut self, v: u32) -> io::Result<()> {
        self.out.write_all(&v.to_le_bytes())
    }

    pub(super) fn u64(&mut self, v: u64) -> io::Result<()> {
        self.out.write_all(&v.to_le_bytes())
    }

    /// Strings longer than [`MAX_STRING_BYTES`] are cut at a character boundary (the
    /// parser would refuse them whole).
    pub(super) fn str(&mut self, s: &str) -> io::Result<()> {
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
