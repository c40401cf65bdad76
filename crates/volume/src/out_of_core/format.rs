//! The on-disk layout of a brick cache file (format version [`VERSION`]).
//!
//! ```text
//! offset 0      Header (one 4 KiB page): magic, version, byte-order mark, section table,
//!               header checksum
//! page-aligned  VALUES   f32 × 512 per dense block, blocks of all channels   (streamed first)
//!               TABLE    u32 per brick-table cell (x fastest), brick index or u32::MAX
//!               BRICKS   Brick (3 × PackedSlot, 24 bytes) per brick
//!               PYRAMID  NodeBounds (6 × f32) per node, level 0 (one per cell) to the root
//!               PROXY    f64 per FNEE proxy cell: summed light power (may be empty)
//!               META     JSON: transform, table box, counts, grids, source mapping, input
//!                        fingerprint, proxy resolution, clean-up report
//!               CHUNKS   u64 xxh3 per 1 MiB chunk of every other section, in section order
//! ```
//!
//! Every section starts on a page boundary, so a mapped section can be viewed as its
//! element type directly. All integers and floats are little-endian (the byte-order mark
//! refuses a file from a big-endian writer). The CHUNKS section's own xxh3 sits in the
//! header; the header's xxh3 covers the header itself. A section is read only after the
//! checksums of its chunks are checked (at open for small sections, by the background
//! verifier for large ones, see `cache::verify`).

use bytemuck::{Pod, Zeroable};
use serde::{Deserialize, Serialize};

use crate::brick::BuildReport;

/// File magic.
pub const MAGIC: [u8; 8] = *b"PLUMEBC\0";
/// Format version this plume writes and reads. Any change of layout or meaning bumps it;
/// a file of another version is stale (rebuilt when automatic, refused when explicit).
pub const VERSION: u32 = 1;
/// Byte-order mark as written by a little-endian machine.
pub const BYTE_ORDER: u32 = 0x0102_0304;
/// Section alignment and header size.
pub const PAGE: u64 = 4096;
/// Bytes per checksummed chunk.
pub const CHUNK: u64 = 1 << 20;
/// Room for sections in the header.
pub const MAX_SECTIONS: usize = 16;

/// What a section holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum SectionKind {
    /// Dense value blocks.
    Values = 1,
    /// Brick table.
    Table = 2,
    /// Brick records.
    Bricks = 3,
    /// Pyramid nodes, all levels.
    Pyramid = 4,
    /// FNEE proxy cell power.
    Proxy = 5,
    /// JSON metadata.
    Meta = 6,
    /// Chunk checksums of all other sections.
    Chunks = 7,
}

impl SectionKind {
    /// All kinds, in file order.
    pub const ALL: [SectionKind; 7] = [
        SectionKind::Values,
        SectionKind::Table,
        SectionKind::Bricks,
        SectionKind::Pyramid,
        SectionKind::Proxy,
        SectionKind::Meta,
        SectionKind::Chunks,
    ];

    /// Name used in messages.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            SectionKind::Values => "values",
            SectionKind::Table => "brick table",
            SectionKind::Bricks => "bricks",
            SectionKind::Pyramid => "pyramid",
            SectionKind::Proxy => "proxy",
            SectionKind::Meta => "metadata",
            SectionKind::Chunks => "chunk checksums",
        }
    }
}

/// One entry of the header's section table.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct SectionEntry {
    /// [`SectionKind`] as `u32` (0: unused entry).
    pub kind: u32,
    /// Index of the section's first chunk checksum in CHUNKS (unused for CHUNKS).
    pub first_chunk: u32,
    /// Byte offset in the file (a multiple of [`PAGE`]).
    pub offset: u64,
    /// Length in bytes.
    pub len: u64,
    /// xxh3 of the whole section: used for CHUNKS only (others are checked per chunk).
    pub checksum: u64,
}

impl SectionEntry {
    /// Chunks the section spans.
    #[must_use]
    pub fn chunk_count(&self) -> u64 {
        self.len.div_ceil(CHUNK)
    }
}

/// The header page.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct Header {
    /// [`MAGIC`].
    pub magic: [u8; 8],
    /// [`VERSION`].
    pub version: u32,
    /// [`BYTE_ORDER`] in the writer's byte order.
    pub byte_order: u32,
    /// Used entries of `sections`.
    pub section_count: u32,
    /// Zero.
    pub reserved: u32,
    /// Section table.
    pub sections: [SectionEntry; MAX_SECTIONS],
    /// xxh3 of this struct with `checksum` = 0.
    pub checksum: u64,
}

impl Header {
    /// xxh3 of the header with its checksum field zeroed.
    #[must_use]
    pub fn compute_checksum(&self) -> u64 {
        let mut h = *self;
        h.checksum = 0;
        xxhash_rust::xxh3::xxh3_64(bytemuck::bytes_of(&h))
    }

    /// The entry of `kind`, if present.
    #[must_use]
    pub fn section(&self, kind: SectionKind) -> Option<&SectionEntry> {
        self.sections[..(self.section_count as usize).min(MAX_SECTIONS)]
            .iter()
            .find(|s| s.kind == kind as u32)
    }
}

/// Where a cache's data came from, to tell a stale cache from a current one.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct InputFingerprint {
    /// The source file as given to `prepare` (absolute when known).
    pub path: String,
    /// Its size in bytes.
    pub size: u64,
    /// Its modification time, nanoseconds since the Unix epoch.
    pub mtime_ns: i128,
}

/// The JSON metadata section.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Meta {
    /// `plume brick cache`.
    pub format: String,
    /// The plume version that wrote it.
    pub writer: String,
    /// `world_from_index`: the 3×3 matrix by columns, then the translation.
    pub world_from_index: [f64; 12],
    /// Brick coordinate of table cell (0,0,0).
    pub brick_lo: [i32; 3],
    /// Table size in bricks.
    pub dims: [i32; 3],
    /// Brick records.
    pub brick_count: u64,
    /// Dense value blocks.
    pub value_blocks: u64,
    /// Grid names used: density, source (if any), albedo (if any).
    pub density_grid: String,
    /// Source grid (temperature or emission), if any.
    pub source_grid: Option<String>,
    /// Albedo grid, if any.
    pub albedo_grid: Option<String>,
    /// What the stored source means: the emission kind and source mapping
    /// (`medium::Emission::source_key`). A render must use the same.
    pub source_key: String,
    /// Emission kind name (`none`, `blackbody`, `grid`), for `--emission auto`.
    pub emission_kind: String,
    /// The input this was converted from; `None` for generated data.
    pub input: Option<InputFingerprint>,
    /// FNEE proxy stored: its resolution and the light-power key it was summed with.
    pub proxy: Option<ProxyMeta>,
    /// Input clean-up counts.
    pub report: BuildReport,
}

/// What the stored proxy power was computed for.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ProxyMeta {
    /// Cells along the longest axis.
    pub resolution: u32,
    /// `medium::Emission::light_key` of the power function.
    pub power_key: String,
}
