//! Reading the records of a streamed grid (the parent's side; format in [`super`]): every
//! count is bounded by [`STREAM_BATCH`] before anything is read, and the batch buffers are
//! reused from record to record.

use std::io::Read;

use glam::IVec3;

use super::TILE_BYTES;
use crate::vdb::stream::{StreamedGrid, Tile, STREAM_BATCH};
use crate::vdb::wire::decode::malformed;
use crate::vdb::wire::{Decoder, WireError};
use crate::vdb::{LEAF_DIM, LEAF_VOXELS};

/// The decoder's buffers for the last LEAVES or TILES record.
#[derive(Debug, Default)]
pub(in crate::vdb::wire) struct Batch {
    origins: Vec<IVec3>,
    values: Vec<f32>,
    tiles: Vec<Tile>,
}

impl<R: Read> Decoder<R> {
    /// The origins and values of the last LEAVES record.
    pub(crate) fn leaf_batch(&self) -> (&[IVec3], &[f32]) {
        (&self.batch.origins, &self.batch.values)
    }

    /// The tiles of the last TILES record.
    pub(crate) fn tile_batch(&self) -> &[Tile] {
        &self.batch.tiles
    }

    pub(in crate::vdb::wire) fn stream_head(&mut self) -> Result<StreamedGrid, WireError> {
        let (name, world_from_index, background) = self.grid_head()?;
        let leaf_count = self.u64()?;
        let tile_blocks = self.u64()?;
        let has_bbox = self.flag()?;
        let mut bbox = [0i32; 6];
        for c in &mut bbox {
            *c = self.u32()? as i32;
        }
        let (lo, hi) =
            (IVec3::new(bbox[0], bbox[1], bbox[2]), IVec3::new(bbox[3], bbox[4], bbox[5]));
        if has_bbox && !lo.cmple(hi).all() {
            return malformed(format!("grid {name:?}: inverted bounds {lo}..{hi}"));
        }
        Ok(StreamedGrid {
            name,
            world_from_index,
            background,
            leaf_count,
            tile_blocks,
            index_bbox: has_bbox.then_some((lo, hi)),
        })
    }

    /// A batch count, refused before anything is read if it is 0 or above [`STREAM_BATCH`].
    fn batch_count(&mut self, what: &str) -> Result<usize, WireError> {
        let count = self.u32()? as usize;
        if count == 0 || count > STREAM_BATCH {
            return malformed(format!("{what} batch of {count} (1 to {STREAM_BATCH})"));
        }
        Ok(count)
    }

    pub(in crate::vdb::wire) fn leaves_record(&mut self) -> Result<(), WireError> {
        let count = self.batch_count("leaf")?;
        self.fill_scratch(count * 12)?;
        let origins = &mut self.batch.origins;
        origins.clear();
        origins.extend(self.scratch.chunks_exact(12).map(|b| {
            let c = |k: usize| i32::from_le_bytes([b[k], b[k + 1], b[k + 2], b[k + 3]]);
            IVec3::new(c(0), c(4), c(8))
        }));
        if let Some(o) = origins.iter().find(|o| (**o % LEAF_DIM) != IVec3::ZERO) {
            return malformed(format!("leaf origin {o} is not a multiple of 8"));
        }
        self.fill_scratch(count * LEAF_VOXELS * 4)?;
        let values = &mut self.batch.values;
        values.clear();
        values.extend(
            self.scratch.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        );
        if values.iter().any(|v| !v.is_finite()) {
            return malformed("non-finite leaf values");
        }
        Ok(())
    }

    pub(in crate::vdb::wire) fn tiles_record(&mut self) -> Result<(), WireError> {
        let count = self.batch_count("tile")?;
        self.fill_scratch(count * TILE_BYTES)?;
        let tiles = &mut self.batch.tiles;
        tiles.clear();
        for b in self.scratch.chunks_exact(TILE_BYTES) {
            let word = |k: usize| [b[4 * k], b[4 * k + 1], b[4 * k + 2], b[4 * k + 3]];
            let int = |k: usize| i32::from_le_bytes(word(k));
            tiles.push(Tile {
                min: IVec3::new(int(0), int(1), int(2)),
                max: IVec3::new(int(3), int(4), int(5)),
                value: f32::from_le_bytes(word(6)),
            });
        }
        // Shape and value are checked by Tile::blocks before a tile is visited
        Ok(())
    }
}
