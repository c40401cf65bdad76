//! Writing the records of a streamed grid (the child's side; format in [`super`]).

use std::io::{self, Write};

use glam::IVec3;

use super::{TAG_LEAVES, TAG_STREAM, TAG_TILES};
use crate::vdb::stream::{StreamedGrid, Tile, STREAM_BATCH};
use crate::vdb::wire::Encoder;
use plume_volume::grid::LEAF_VOXELS;

impl<W: Write> Encoder<W> {
    /// The header of a streamed grid.
    pub(crate) fn stream(&mut self, grid: &StreamedGrid) -> io::Result<()> {
        self.out.write_all(&[TAG_STREAM])?;
        self.str(&grid.name)?;
        for c in grid.world_from_index.to_cols_array() {
            self.out.write_all(&c.to_le_bytes())?;
        }
        self.out.write_all(&grid.background.to_le_bytes())?;
        self.u64(grid.leaf_count)?;
        self.u64(grid.tile_blocks)?;
        let (flag, lo, hi) = match grid.index_bbox {
            Some((lo, hi)) => (1u8, lo, hi),
            None => (0u8, IVec3::ZERO, IVec3::ZERO),
        };
        self.out.write_all(&[flag])?;
        for c in lo.to_array().into_iter().chain(hi.to_array()) {
            self.out.write_all(&c.to_le_bytes())?;
        }
        Ok(())
    }

    /// One batch of leaves: at most [`STREAM_BATCH`], 512 values each.
    ///
    /// # Panics
    /// If the batch is empty, too long, or the values do not match the origins.
    pub(crate) fn leaves(&mut self, origins: &[IVec3], values: &[f32]) -> io::Result<()> {
        assert!((1..=STREAM_BATCH).contains(&origins.len()), "invariant: batch size");
        assert_eq!(values.len(), origins.len() * LEAF_VOXELS, "invariant: 512 values per leaf");
        self.out.write_all(&[TAG_LEAVES])?;
        self.u32(origins.len() as u32)?;
        self.scratch.clear();
        self.scratch.extend(origins.iter().flat_map(|o| o.to_array()).flat_map(i32::to_le_bytes));
        self.out.write_all(&self.scratch)?;
        self.scratch.clear();
        self.scratch.extend(values.iter().flat_map(|v| v.to_le_bytes()));
        self.out.write_all(&self.scratch)
    }

    /// One batch of active tiles: at most [`STREAM_BATCH`].
    ///
    /// # Panics
    /// If the batch is empty or too long.
    pub(crate) fn tiles(&mut self, tiles: &[Tile]) -> io::Result<()> {
        assert!((1..=STREAM_BATCH).contains(&tiles.len()), "invariant: batch size");
        self.out.write_all(&[TAG_TILES])?;
        self.u32(tiles.len() as u32)?;
        self.scratch.clear();
        for t in tiles {
            let ints = t.min.to_array().into_iter().chain(t.max.to_array());
            self.scratch.extend(ints.flat_map(i32::to_le_bytes));
            self.scratch.extend(t.value.to_le_bytes());
        }
        self.out.write_all(&self.scratch)
    }
}
