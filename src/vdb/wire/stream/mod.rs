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
//!
//! The child writes these records with the [`Encoder`](super::Encoder) methods of `encode.rs`,
//! the parent reads them with the [`Decoder`](super::Decoder) methods of `decode.rs`.
//!
//! [`STREAM_BATCH`]: crate::vdb::stream::STREAM_BATCH

mod decode;
mod encode;

pub(super) use decode::Batch;

pub(super) const TAG_STREAM: u8 = 0x07;
pub(super) const TAG_LEAVES: u8 = 0x08;
pub(super) const TAG_TILES: u8 = 0x09;

/// Bytes of one tile on the wire.
const TILE_BYTES: usize = 7 * 4;

#[cfg(test)]
mod tests {
    use std::io;

    use glam::IVec3;

    use super::super::tests::encode;
    use super::super::{Decoder, Record, WireError, MAGIC, TAG_END, VERSION};
    use super::*;
    use crate::vdb::stream::{StreamedGrid, Tile, STREAM_BATCH};
    use plume_volume::grid::LEAF_VOXELS;

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
