//! Streaming one float grid leaf by leaf, in bounded memory: [`stream_float_grid`] and
//! [`ReadIsolation::stream_float_grid`], for conversions that must never hold a whole
//! grid (the brick cache of `plume prepare`).
//!
//! The shim opens the file with OpenVDB's delayed loading (the file is memory-mapped; leaf
//! buffers stay in it until touched), reads the grid's topology, then copies the leaves
//! out [`STREAM_BATCH`] at a time in tree order, detaching and freeing each leaf once
//! copied. What stays resident is the topology (nodes without their values, about 150
//! bytes per leaf), the list of leaf origins and one batch; that is what
//! [`ReadLimits::max_bytes`] bounds here (not the voxelized size, as for
//! [`read_float_grid`](super::read_float_grid)).
//!
//! A visitor sees, in this order:
//! 1. `header` once, with the grid's name, transform, background, leaf and tile-block
//!    counts and bounds, before any leaf is loaded;
//! 2. each leaf stored in the file, as [`LeafData::Values`], in OpenVDB's tree order;
//! 3. each 8³ block covered by an active tile (at any level, root tiles included), as
//!    [`LeafData::Constant`], tile after tile, x slowest and z fastest within a tile.
//!
//! These are exactly the blocks of [`read_float_grid`](super::read_float_grid), in the
//! same order and with the same values, bit for bit. Every leaf origin and tile is
//! checked against the header (aligned, inside the bounds, leaves in strictly increasing
//! tree order so never repeated, counts as announced) before the visitor sees it, in both
//! isolation modes. An error from a visitor stops the stream and is returned; so is an
//! error of the file found after some leaves were visited (a corrupt leaf buffer).

mod isolated;

pub(crate) use isolated::serve_stream;
pub use isolated::stream_float_grid_isolated;

use std::path::Path;

use glam::{DAffine3, IVec3};

use super::ffi;
use super::read::{check_file, check_status, vdb_error, vdb_message, BYTES_PER_LEAF};
use super::{GridSelector, ReadIsolation, ReadLimits, LEAF_DIM, LEAF_VOXELS};
use plume_core::error::{Error, Result};

/// Leaves copied per call into the shim, and most leaves or tiles per record of the
/// isolated reader's reply (512 KiB of values).
pub(crate) const STREAM_BATCH: usize = 256;

/// Bytes of one batch of leaves (values and origins).
const BATCH_BYTES: u64 = STREAM_BATCH as u64 * BYTES_PER_LEAF;

/// A grid being streamed, as known before its first leaf is loaded.
#[derive(Clone, Debug, PartialEq)]
pub struct StreamedGrid {
    /// Grid name as stored in the file (for duplicates, the bare name).
    pub name: String,
    /// Affine map from index coordinates to world coordinates (voxel (i,j,k) is centred at
    /// index (i,j,k)).
    pub world_from_index: DAffine3,
    /// Value outside all leaves and active tiles.
    pub background: f32,
    /// Leaves stored in the file: the [`LeafData::Values`] blocks.
    pub leaf_count: u64,
    /// 8³ blocks covered by active tiles: the [`LeafData::Constant`] blocks. A single
    /// root tile gives 512³ of them; a visitor that cannot take that many should refuse
    /// in `header`.
    pub tile_blocks: u64,
    /// Inclusive index bounds of every block (leaves and tiles), `None` when there is
    /// none. Blocks are whole 8³ cells, so this is at least the active voxels' bounds.
    pub index_bbox: Option<(IVec3, IVec3)>,
}

/// The values of one 8³ block, at [`leaf_offset`](super::leaf_offset) order.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LeafData<'a> {
    /// A leaf stored in the file; inactive voxels keep their stored value.
    Values(&'a [f32; LEAF_VOXELS]),
    /// A block inside an active tile: this value everywhere.
    Constant(f32),
}

/// The visitor of `header`.
pub type HeaderVisitor<'v> = dyn FnMut(&StreamedGrid) -> Result<()> + 'v;
/// The visitor of each block.
pub type LeafVisitor<'v> = dyn FnMut(IVec3, LeafData<'_>) -> Result<()> + 'v;

impl ReadIsolation {
    /// [`stream_float_grid`], here or in the child (see [`stream_float_grid_isolated`]).
    ///
    /// # Errors
    /// As [`stream_float_grid`], plus [`Error::ReaderFailed`] and [`Error::ReaderSpawn`].
    pub fn stream_float_grid(
        &self,
        path: &Path,
        selector: &GridSelector,
        limits: &ReadLimits,
        header: &mut HeaderVisitor<'_>,
        leaf: &mut LeafVisitor<'_>,
    ) -> Result<StreamedGrid> {
        match self {
            ReadIsolation::InProcess => stream_float_grid(path, selector, limits, header, leaf),
            ReadIsolation::Child { reader_exe, limits: isolation } => stream_float_grid_isolated(
                reader_exe, path, selector, limits, isolation, header, leaf,
            ),
        }
    }
}

/// What identifies the version of a `.vdb` being streamed (OpenVDB maps it and reads
/// leaves from it as they are asked for): checked before each batch of leaves, and by a
/// conversion (`cache::convert`) from its start to its end.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct FileStamp {
    dev: u64,
    ino: u64,
    bytes: u64,
    mtime: (i64, i64),
}

impl FileStamp {
    /// The file at `path` now.
    pub(crate) fn of(path: &Path) -> std::io::Result<FileStamp> {
        use std::os::unix::fs::MetadataExt;
        let m = std::fs::metadata(path)?;
        Ok(FileStamp {
            dev: m.dev(),
            ino: m.ino(),
            bytes: m.len(),
            mtime: (m.mtime(), m.mtime_nsec()),
        })
    }

    /// How the file now at `path` differs from this version, if it does.
    pub(crate) fn change(&self, path: &Path) -> Option<String> {
        let now = match FileStamp::of(path) {
            Ok(now) => now,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Some("it was removed".into())
            }
            Err(e) => return Some(format!("it cannot be examined again ({e})")),
        };
        let sizes = format!("now {} bytes, {} when opened", now.bytes, self.bytes);
        if (now.dev, now.ino) != (self.dev, self.ino) {
            Some(format!("it was replaced by another file ({sizes})"))
        } else if now.bytes < self.bytes {
            Some(format!("it was truncated ({sizes})"))
        } else {
            (now != *self).then(|| format!("it was modified ({sizes})"))
        }
    }

    /// The error for `change`.
    pub(crate) fn failed(path: &Path, change: &str) -> Error {
        Error::InputFailed {
            kind: "VDB file",
            path: path.to_path_buf(),
            what: format!("{change} while plume streamed it; the conversion stopped (run the command again once the file is complete)"),
        }
    }
}

/// Streams one scalar grid through `header` and `leaf` in this process (see the module
/// documentation for the order), holding only its topology and one batch of leaves.
///
/// # Errors
/// - As [`read_float_grid`](super::read_float_grid): [`Error::Open`], [`Error::Vdb`]
///   (including a NaN or infinite value, found when its leaf is reached),
///   [`Error::GridNotFound`], [`Error::UnsupportedGrid`];
/// - [`Error::TooLarge`] when the topology plus one batch needs more than
///   `limits.max_bytes`;
/// - the first error a visitor returns.
pub fn stream_float_grid(
    path: &Path,
    selector: &GridSelector,
    limits: &ReadLimits,
    header: &mut HeaderVisitor<'_>,
    leaf: &mut LeafVisitor<'_>,
) -> Result<StreamedGrid> {
    let mut stream = LocalStream::open(path, selector, limits)?;
    header(stream.grid())?;
    let corrupt = |m: String| vdb_message(path, format!("grid {selector}: {m}"));
    let refused = |r: Refusal| match r {
        Refusal::Corrupt(m) => corrupt(m),
        Refusal::Visitor(e) => e,
    };
    let mut delivery = Delivery::new(stream.grid().clone(), leaf);
    while let Some((origins, values)) = stream.next_batch()? {
        delivery.leaves(origins, values).map_err(refused)?;
    }
    for tile in stream.tiles() {
        delivery.tile(tile).map_err(refused)?;
    }
    delivery.finish().map_err(refused)
}

/// An active tile: a constant cube of voxels, inclusive bounds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Tile {
    pub(crate) min: IVec3,
    pub(crate) max: IVec3,
    pub(crate) value: f32,
}

impl Tile {
    /// The 8³ blocks it covers, after checking that it is a tile of a 5-4-3 tree: a cube of
    /// edge 8, 128 or 4096 aligned to its edge, with a finite value.
    pub(crate) fn blocks(&self) -> std::result::Result<u64, String> {
        let (min, max) = (self.min.to_array(), self.max.to_array());
        let edge = i64::from(max[0]) - i64::from(min[0]) + 1;
        let cube = (0..3).all(|a| i64::from(max[a]) - i64::from(min[a]) + 1 == edge);
        let aligned = matches!(edge, 8 | 128 | 4096)
            && (0..3).all(|a| i64::from(min[a]).rem_euclid(edge) == 0);
        if !cube || !aligned {
            return Err(format!(
                "active tile {}..{} is not a node-aligned cube",
                self.min, self.max
            ));
        }
        if !self.value.is_finite() {
            return Err(format!("active tile at {} holds a NaN or infinite value", self.min));
        }
        Ok((edge as u64 / LEAF_DIM as u64).pow(3))
    }
}

/// Why a [`Delivery`] stopped.
pub(crate) enum Refusal {
    /// The stream contradicts its header or the tree's invariants.
    Corrupt(String),
    /// The visitor returned this error.
    Visitor(Error),
}

/// Position of a leaf in OpenVDB's tree order for a 5-4-3 tree: the root orders its 4096³
/// children by origin, lexicographically (`std::map<Coord, …>`); internal nodes order
/// their children by offset, x-major, 32³ then 16³ of them.
fn tree_order(o: IVec3) -> (i32, i32, i32, u32) {
    let slot = |shift: i32, bits: i32| {
        let mask = (1 << bits) - 1;
        (((o.x >> shift) & mask) << (2 * bits)
            | ((o.y >> shift) & mask) << bits
            | ((o.z >> shift) & mask)) as u32
    };
    (o.x >> 12, o.y >> 12, o.z >> 12, slot(7, 5) << 12 | slot(3, 4))
}

/// Checks each block of a stream against its header, then hands it to the visitor: the
/// same checks for the in-process stream and for the isolated reader's reply.
pub(crate) struct Delivery<'v, 'f> {
    grid: StreamedGrid,
    visit: &'v mut LeafVisitor<'f>,
    leaves: u64,
    tile_blocks: u64,
    last: Option<(i32, i32, i32, u32)>,
    in_tiles: bool,
}

impl<'v, 'f> Delivery<'v, 'f> {
    pub(crate) fn new(grid: StreamedGrid, visit: &'v mut LeafVisitor<'f>) -> Delivery<'v, 'f> {
        Delivery { grid, visit, leaves: 0, tile_blocks: 0, last: None, in_tiles: false }
    }

    /// Whether the block of `min..=max` lies inside the announced bounds.
    fn inside(&self, min: IVec3, max: IVec3) -> bool {
        self.grid.index_bbox.is_some_and(|(lo, hi)| min.cmpge(lo).all() && max.cmple(hi).all())
    }

    /// Leaves in tree order: `values` holds [`LEAF_VOXELS`] per origin.
    pub(crate) fn leaves(
        &mut self,
        origins: &[IVec3],
        values: &[f32],
    ) -> std::result::Result<(), Refusal> {
        let corrupt = |m: String| Err(Refusal::Corrupt(m));
        if self.in_tiles {
            return corrupt("leaves after the tiles".into());
        }
        if values.len() != origins.len() * LEAF_VOXELS {
            return corrupt("a batch's values do not match its origins".into());
        }
        for (&origin, block) in origins.iter().zip(values.chunks_exact(LEAF_VOXELS)) {
            if self.leaves >= self.grid.leaf_count {
                return corrupt(format!("more than the {} leaves announced", self.grid.leaf_count));
            }
            if origin % LEAF_DIM != IVec3::ZERO {
                return corrupt(format!("leaf origin {origin} is not a multiple of 8"));
            }
            // Cannot overflow: the origin is aligned and bounds are i32
            let last_voxel = origin + IVec3::splat(LEAF_DIM - 1);
            if !self.inside(origin, last_voxel) {
                return corrupt(format!("leaf {origin} lies outside the announced bounds"));
            }
            let key = tree_order(origin);
            if self.last.is_some_and(|last| last >= key) {
                return corrupt(format!("leaf {origin} is out of tree order (repeated?)"));
            }
            self.last = Some(key);
            let block = block.try_into().expect("invariant: chunks_exact(LEAF_VOXELS)");
            (self.visit)(origin, LeafData::Values(block)).map_err(Refusal::Visitor)?;
            self.leaves += 1;
        }
        Ok(())
    }

    /// One active tile, visited as one constant block per 8³ cell (x slowest).
    pub(crate) fn tile(&mut self, tile: &Tile) -> std::result::Result<(), Refusal> {
        self.in_tiles = true;
        let blocks = tile.blocks().map_err(Refusal::Corrupt)?;
        if !self.inside(tile.min, tile.max) {
            return Err(Refusal::Corrupt(format!(
                "tile {}..{} lies outside the announced bounds",
                tile.min, tile.max
            )));
        }
        if blocks > self.grid.tile_blocks - self.tile_blocks {
            return Err(Refusal::Corrupt(format!(
                "more than the {} tile blocks announced",
                self.grid.tile_blocks
            )));
        }
        self.tile_blocks += blocks;
        // Bounds are checked and aligned, so every origin is an i32 and steps stay in range
        let axis = |a: usize| (tile.min[a]..=tile.max[a]).step_by(LEAF_DIM as usize);
        for x in axis(0) {
            for y in axis(1) {
                for z in axis(2) {
                    (self.visit)(IVec3::new(x, y, z), LeafData::Constant(tile.value))
                        .map_err(Refusal::Visitor)?;
                }
            }
        }
        Ok(())
    }

    /// The header, once every announced leaf and tile block has been delivered.
    pub(crate) fn finish(self) -> std::result::Result<StreamedGrid, Refusal> {
        if self.leaves != self.grid.leaf_count || self.tile_blocks != self.grid.tile_blocks {
            return Err(Refusal::Corrupt(format!(
                "{} leaves and {} tile blocks delivered, {} and {} announced",
                self.leaves, self.tile_blocks, self.grid.leaf_count, self.grid.tile_blocks
            )));
        }
        Ok(self.grid)
    }
}

/// One grid open in the shim for streaming, in this process; what both the in-process
/// stream and the isolated reader's child run.
pub(crate) struct LocalStream<'p> {
    path: &'p Path,
    selector: &'p GridSelector,
    /// OpenVDB's mapping of the file, watched (`mapfault`): a truncation while streaming
    /// in this process ends plume with a line naming the file. Declared before `shim` so
    /// that it is dropped before the file is unmapped.
    #[allow(dead_code)]
    watches: Vec<plume_volume::out_of_core::mapfault::Watch>,
    /// The file's version when opened, checked before each batch of leaves is loaded.
    stamp: std::io::Result<FileStamp>,
    shim: cxx::UniquePtr<ffi::LeafStream>,
    grid: StreamedGrid,
    tiles: Vec<Tile>,
    /// The batch buffers the shim fills: 3 components and 512 values per leaf.
    raw_origins: Vec<i32>,
    values: Vec<f32>,
    origins: Vec<IVec3>,
}

impl<'p> LocalStream<'p> {
    /// Opens the grid and reads its topology, with every check of
    /// [`read_float_grid`](super::read_float_grid) that does not need the values.
    pub(crate) fn open(
        path: &'p Path,
        selector: &'p GridSelector,
        limits: &ReadLimits,
    ) -> Result<LocalStream<'p>> {
        let path_str = check_file(path)?;
        let stamp = FileStamp::of(path);
        // OpenVDB maps the file and reads its topology from the mapping inside this call: a
        // truncation meanwhile faults before the mapping can be found and watched
        let opening = plume_volume::out_of_core::mapfault::Watch::any_address("VDB file", path);
        let shim = ffi::open_leaf_stream(path_str, &selector.name, selector.occurrence)
            .map_err(|e| vdb_error(path, &e))?;
        // Delayed loading has mapped the file (its topology was read from the mapping)
        let watches = plume_volume::out_of_core::mapfault::watch_mappings_of(path, "VDB file");
        drop(opening);
        let h = shim.stream_header().map_err(|e| vdb_error(path, &e))?;
        check_status(path, path_str, selector, h.status, &h.value_type, &h.transform)?;
        let needed = h.resident_bytes.saturating_add(BATCH_BYTES);
        if needed > limits.max_bytes {
            return Err(Error::TooLarge {
                path: path.to_path_buf(),
                grid: selector.to_string(),
                needed,
                limit: limits.max_bytes,
            });
        }
        let corrupt =
            |m: String| vdb_message(path, format!("grid {selector}: {m}; the file is corrupt"));
        if !h.background.is_finite() {
            return Err(corrupt("the background is NaN or infinite".into()));
        }
        let tiles: Vec<Tile> = shim
            .stream_tiles()
            .map_err(|e| vdb_error(path, &e))?
            .iter()
            .map(|t| Tile {
                min: IVec3::from_array(t.min),
                max: IVec3::from_array(t.max),
                value: t.value,
            })
            .collect();
        let mut tile_blocks = 0u64;
        for tile in &tiles {
            tile_blocks = tile_blocks.saturating_add(tile.blocks().map_err(corrupt)?);
        }
        let grid = StreamedGrid {
            name: selector.name.clone(),
            world_from_index: DAffine3::from_cols_array(&h.world_from_index),
            background: h.background,
            leaf_count: h.leaf_count,
            tile_blocks,
            index_bbox: h
                .has_bbox
                .then(|| (IVec3::from_array(h.bbox_min), IVec3::from_array(h.bbox_max))),
        };
        Ok(LocalStream {
            path,
            selector,
            watches,
            stamp,
            shim,
            grid,
            tiles,
            raw_origins: vec![0; 3 * STREAM_BATCH],
            values: vec![0.0; LEAF_VOXELS * STREAM_BATCH],
            origins: Vec::with_capacity(STREAM_BATCH),
        })
    }

    pub(crate) fn grid(&self) -> &StreamedGrid {
        &self.grid
    }

    /// The active tiles, in tree order.
    pub(crate) fn tiles(&self) -> &[Tile] {
        &self.tiles
    }

    /// The next batch of leaves (origins, and 512 values each), `None` after the last.
    ///
    /// # Errors
    /// [`Error::Vdb`] when OpenVDB cannot load a leaf, or a leaf holds a NaN or infinite
    /// value (the file is corrupt, as [`read_float_grid`](super::read_float_grid) says);
    /// [`Error::InputFailed`] when the file changed since it was opened.
    pub(crate) fn next_batch(&mut self) -> Result<Option<(&[IVec3], &[f32])>> {
        // Before OpenVDB reads the next leaves from the mapped file: a truncated file
        // would fault (SIGBUS), and OpenVDB can crash on the zeros past its new end
        if let Some(change) = self.stamp.as_ref().ok().and_then(|s| s.change(self.path)) {
            return Err(FileStamp::failed(self.path, &change));
        }
        let n = self
            .shim
            .pin_mut()
            .next_leaves(&mut self.raw_origins, &mut self.values)
            .map_err(|e| vdb_error(self.path, &e))?;
        if n == 0 {
            return Ok(None);
        }
        self.origins.clear();
        self.origins.extend(self.raw_origins[..3 * n].chunks_exact(3).map(IVec3::from_slice));
        let values = &self.values[..LEAF_VOXELS * n];
        if let Some(i) =
            values.chunks_exact(LEAF_VOXELS).position(|b| b.iter().any(|v| !v.is_finite()))
        {
            return Err(vdb_message(
                self.path,
                format!(
                    "grid {}: leaf {} holds NaN or infinite values; the file is corrupt",
                    self.selector, self.origins[i]
                ),
            ));
        }
        Ok(Some((&self.origins, values)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tree_order_follows_the_root_map_then_node_offsets() {
        // Root children compare by origin, x first, signed
        assert!(tree_order(IVec3::new(-4096, 4000, 0)) < tree_order(IVec3::new(0, -8, 0)));
        assert!(tree_order(IVec3::new(0, -4096, 0)) < tree_order(IVec3::new(0, 0, -4096)));
        // Inside one root child: 128³ slot first (x-major), then the 8³ slot
        assert!(tree_order(IVec3::new(0, 0, 120)) < tree_order(IVec3::new(0, 8, 0)));
        assert!(tree_order(IVec3::new(0, 120, 120)) < tree_order(IVec3::new(8, 0, 0)));
        assert!(tree_order(IVec3::new(120, 120, 120)) < tree_order(IVec3::new(0, 0, 128)));
        assert!(tree_order(IVec3::new(-8, 0, 0)) > tree_order(IVec3::new(-128, 0, 0)));
    }

    #[test]
    fn tiles_must_be_node_cubes() {
        let tile = |min: [i32; 3], edge: i32| Tile {
            min: IVec3::from_array(min),
            max: IVec3::from_array(min) + (edge - 1),
            value: 1.0,
        };
        assert_eq!(tile([8, -16, 0], 8).blocks(), Ok(1));
        assert_eq!(tile([-128, 0, 128], 128).blocks(), Ok(16 * 16 * 16));
        assert_eq!(tile([0, 0, -4096], 4096).blocks(), Ok(1 << 27));
        assert!(tile([8, 0, 0], 128).blocks().is_err(), "unaligned");
        assert!(tile([0, 0, 0], 16).blocks().is_err(), "not a node size");
        assert_eq!(tile([i32::MAX - 7, 0, 0], 8).blocks(), Ok(1), "the last block of i32");
        let wrapped = Tile {
            min: IVec3::new(i32::MAX - 3, 0, 0),
            max: IVec3::new(i32::MIN + 4, 7, 7),
            value: 1.0,
        };
        assert!(wrapped.blocks().is_err());
        let mut wide = tile([0, 0, 0], 8);
        wide.max.x += 8;
        assert!(wide.blocks().is_err(), "not a cube");
        let mut nan = tile([0, 0, 0], 8);
        nan.value = f32::NAN;
        assert!(nan.blocks().is_err());
    }
}
