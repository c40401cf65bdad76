//! The records of a streamed grid (`plume __read-grids stream …`, see `vdb/stream.rs`):
//!
//! ```text
//! 0x07 STREAM  name str, world_from_index 12 × f64, background f32, leaf_count u64,
//!              tile_blocks u64, has_bbox u8, bbox_min 3 × i32, bbox_max 3 × i32
//! 0x08 LEAVES  count u32 (1..=256), origins 3·count × i32, values 512·count × f32
//! 0x09 TILES   count u32 (1..=256), count × (min 3 × i32, max 3 × i32, value f32)
//! ```
//!
//! A stream reply is BEGIN, STREAM, LEAVES…, TILES…, END; FAILED (then END) may replace
//! any record after BEGIN. The decoder bounds every count by [`STREAM_BATCH`] before
//! reading, so a batch never costs the parent more than 512 KiB, and reuses its buffers
//! from batch to batch. It checks what one record can show (finite values, aligned
//! origins); the checks against the header are `stream::Delivery`'s.

use std::io::{self, Read, Write};

use glam::IVec3;

use super::{malformed, Decoder, Encoder, WireError};
use crate::vdb::stream::{StreamedGrid, Tile, STREAM_BATCH};
use crate::vdb::{LEAF_DIM, LEAF_VOXELS};

pub(super) const TAG_STREAM: u8 = 0x07;
pub(super) const TAG_LEAVES: u8 = 0x08;
pub(super) const TAG_TILES: u8 = 0x09;

/// Bytes of one tile on the wire.
const TILE_BYTES: usize = 7 * 4;

/// The decoder's buffers for the last LEAVES or TILES record.
#[derive(Debug, Default)]
pub(super) struct Batch {
    origins: Vec<IVec3>,
    values: Vec<f32>,
    tiles: Vec<Tile>,
}

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

impl<R: Read> Decoder<R> {
    /// The origins and values of the last LEAVES record.
    pub(crate) fn leaf_batch(&self) -> (&[IVec3], &[f32]) {
        (&self.batch.origins, &self.batch.values)
    }

    /// The tiles of the last TILES record.
    pub(crate) fn tile_batch(&self) -> &[Tile] {
        &self.batch.tiles
    }

    pub(super) fn stream_head(&mut self) -> Result<StreamedGrid, WireError> {
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

    pub(super) fn leaves_record(&mut self) -> Result<(), WireError> {
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

    pub(super) fn tiles_record(&mut self) -> Result<(), WireError> {
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

#[cfg(test)]
mod tests {
    use super::super::tests::encode;
    use super::super::{Record, MAGIC, TAG_END, VERSION};
    use super::*;

    fn grid() -> StreamedGrid {
        StreamedGrid {
            name: "density".into(),
            world_from_index: glam::DAffine3::from_scale(glam::DVec3::new(0.5, 0.25, 2.0)),
            background: 0.125,
            leaf_count: 3,
            tile_blocks: 4097,
            index_bbox: Some((IVec3::new(-128, -8, 0), IVec3::new(127, 7, 4095))),
        }
    }

    fn leaves(n: usize) -> (Vec<IVec3>, Vec<f32>) {
        let origins = (0..n as i32).map(|i| IVec3::new(8 * i - 128, -8, 16)).collect();
        let values = (0..n * LEAF_VOXELS).map(|i| i as f32 * 0.25 - 3.0).collect();
        (origins, values)
    }

    fn tiles() -> Vec<Tile> {
        vec![
            Tile { min: IVec3::new(-8, 0, 0), max: IVec3::new(-1, 7, 7), value: 2.5 },
            Tile { min: IVec3::new(0, 0, 0), max: IVec3::new(127, 127, 127), value: -1.0 },
        ]
    }

    /// Decodes every record, recording what the batch records held.
    fn decode(bytes: &[u8]) -> Result<Vec<String>, WireError> {
        let mut d = Decoder::new(bytes, 0)?;
        let mut seen = Vec::new();
        loop {
            match d.next()? {
                Record::End => return Ok(seen),
                Record::Stream(g) => seen.push(format!("{g:?}")),
                Record::Leaves => seen.push(format!("{:?}", d.leaf_batch())),
                Record::Tiles => seen.push(format!("{:?}", d.tile_batch())),
                other => seen.push(format!("{other:?}")),
            }
        }
    }

    #[test]
    fn stream_records_round_trip() {
        let (origins, values) = leaves(3);
        let bytes = encode(|e| {
            e.begin(0, 0).unwrap();
            e.stream(&grid()).unwrap();
            e.leaves(&origins[..2], &values[..2 * LEAF_VOXELS]).unwrap();
            e.leaves(&origins[2..], &values[2 * LEAF_VOXELS..]).unwrap();
            e.tiles(&tiles()).unwrap();
        });
        let mut d = Decoder::new(&bytes[..], 0).unwrap();
        assert!(matches!(d.next().unwrap(), Record::Begin { request: 0, alternative: 0 }));
        match d.next().unwrap() {
            Record::Stream(g) => assert_eq!(g, grid()),
            other => panic!("{other:?}"),
        }
        assert!(matches!(d.next().unwrap(), Record::Leaves));
        assert_eq!(d.leaf_batch(), (&origins[..2], &values[..2 * LEAF_VOXELS]));
        assert!(matches!(d.next().unwrap(), Record::Leaves));
        assert_eq!(d.leaf_batch(), (&origins[2..], &values[2 * LEAF_VOXELS..]));
        assert!(matches!(d.next().unwrap(), Record::Tiles));
        assert_eq!(d.tile_batch(), &tiles()[..]);
        assert!(matches!(d.next().unwrap(), Record::End));

        let empty = StreamedGrid { index_bbox: None, leaf_count: 0, tile_blocks: 0, ..grid() };
        let bytes = encode(|e| e.stream(&empty).unwrap());
        let mut d = Decoder::new(&bytes[..], 0).unwrap();
        assert!(matches!(d.next().unwrap(), Record::Stream(g) if g == empty));
    }

    #[test]
    fn every_truncation_is_an_eof_error() {
        let (origins, values) = leaves(2);
        let bytes = encode(|e| {
            e.stream(&grid()).unwrap();
            e.leaves(&origins, &values).unwrap();
            e.tiles(&tiles()).unwrap();
        });
        assert!(decode(&bytes).is_ok());
        for len in 0..bytes.len() {
            match decode(&bytes[..len]) {
                Err(WireError::Io(e)) => assert_eq!(e.kind(), io::ErrorKind::UnexpectedEof),
                other => panic!("cut at {len}: {other:?}"),
            }
        }
    }

    fn record(tag: u8, body: &[u8]) -> Vec<u8> {
        let mut bytes = MAGIC.to_vec();
        bytes.extend(VERSION.to_le_bytes());
        bytes.push(tag);
        bytes.extend(body);
        bytes.push(TAG_END);
        bytes
    }

    #[test]
    fn batch_counts_are_bounded_before_reading() {
        for tag in [TAG_LEAVES, TAG_TILES] {
            for count in [0u32, STREAM_BATCH as u32 + 1, u32::MAX] {
                match decode(&record(tag, &count.to_le_bytes())) {
                    Err(WireError::Malformed(m)) => assert!(m.contains("batch of"), "{m}"),
                    other => panic!("tag {tag} count {count}: {other:?}"),
                }
            }
        }
    }

    #[test]
    fn bad_leaves_and_headers_are_refused() {
        let (mut origins, mut values) = leaves(1);
        values[9] = f32::INFINITY;
        let bytes = encode(|e| e.leaves(&origins, &values).unwrap());
        assert!(matches!(decode(&bytes), Err(WireError::Malformed(_))));
        values[9] = 0.0;
        origins[0].z = 12;
        let bytes = encode(|e| e.leaves(&origins, &values).unwrap());
        assert!(matches!(decode(&bytes), Err(WireError::Malformed(_))));

        let inverted = StreamedGrid { index_bbox: Some((IVec3::ONE, IVec3::ZERO)), ..grid() };
        let bytes = encode(|e| e.stream(&inverted).unwrap());
        assert!(matches!(decode(&bytes), Err(WireError::Malformed(_))));
        let nan = StreamedGrid { background: f32::NAN, ..grid() };
        let bytes = encode(|e| e.stream(&nan).unwrap());
        assert!(matches!(decode(&bytes), Err(WireError::Malformed(_))));
    }
}
