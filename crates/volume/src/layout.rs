//! The brick layout every part of the volume shares: brick size, voxel order inside a
//! brick ([`brick_offset`], Morton order), the table's empty marker, a brick's channel
//! slots (a constant or a dense block: [`Slot`], packed as [`PackedSlot`]), the
//! [`Brick`] record, and the build's clean-up counts ([`BuildReport`]).

use glam::IVec3;

/// Brick edge in voxels.
pub const BRICK: i32 = 8;

/// Most brick-table entries plume will allocate (4 bytes each): 2³⁰, i.e. a bounding box
/// of 8192³ voxels. Larger boxes are refused with a clear error rather than exhausting
/// memory on a file whose few leaves lie far apart.
pub const MAX_TABLE_ENTRIES: u64 = 1 << 30;

/// Spread the 3 bits of `v` to positions 0, 3, 6.
const fn spread3(v: i32) -> usize {
    ((v & 1) | ((v & 2) << 2) | ((v & 4) << 4)) as usize
}

/// Offset of local voxel `(x, y, z)` (each in `0..8`) inside a stored brick: Morton
/// (Z-order) interleaving `… z1 x0 y0 z0`, so one 64-byte cache line holds a 2×2×4 block
/// and a ray in any direction touches a new line every 2–4 voxels rather than every
/// voxel (OpenVDB's x-major order puts x-neighbours 256 bytes apart). `plume bench core`
/// measures it on random chords through a 256³ explosion.
#[inline]
#[must_use]
pub const fn brick_offset(x: i32, y: i32, z: i32) -> usize {
    (spread3(x & 7) << 2) | (spread3(y & 7) << 1) | spread3(z & 7)
}

/// Local voxel `(x, y, z)` at brick-order offset `i` (the inverse of [`brick_offset`]).
#[must_use]
pub const fn brick_local(i: usize) -> IVec3 {
    const fn compact3(v: usize) -> i32 {
        ((v & 1) | ((v >> 2) & 2) | ((v >> 4) & 4)) as i32
    }
    IVec3::new(compact3(i >> 2), compact3(i >> 1), compact3(i))
}

/// Marker for "no brick here" in the brick table.
pub const NO_BRICK: u32 = u32::MAX;

/// One channel of one brick, decoded: a constant or a block of the value array.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Slot {
    /// All 512 voxels hold this value.
    Constant(f32),
    /// Values at `512·block .. 512·(block + 1)` of the value array, in [`brick_offset`] order.
    Dense(u32),
}

/// A [`Slot`] as stored (in memory and in cache files): a tag and 32 bits of payload.
/// Plain old data, so brick records can be mapped straight from a cache file; any bit
/// pattern decodes to *some* slot (unknown tags read as constants), so a damaged file
/// cannot make decoding undefined.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PackedSlot {
    tag: u32,
    bits: u32,
}

const TAG_CONSTANT: u32 = 0;

const TAG_DENSE: u32 = 1;

/// Only while building: the channel has not been given for this brick yet.
const TAG_UNSET: u32 = 2;

impl PackedSlot {
    /// A constant slot.
    #[must_use]
    pub const fn constant(v: f32) -> PackedSlot {
        PackedSlot { tag: TAG_CONSTANT, bits: v.to_bits() }
    }

    /// A dense slot holding value block `block`.
    #[must_use]
    pub const fn dense(block: u32) -> PackedSlot {
        PackedSlot { tag: TAG_DENSE, bits: block }
    }

    /// A slot not yet assigned.
    pub const UNSET: PackedSlot = PackedSlot { tag: TAG_UNSET, bits: 0 };

    /// The decoded slot.
    #[inline]
    #[must_use]
    pub fn get(self) -> Slot {
        if self.tag == TAG_DENSE {
            Slot::Dense(self.bits)
        } else {
            Slot::Constant(f32::from_bits(self.bits))
        }
    }
}

/// The three channels of one brick.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Brick {
    /// Density channel.
    pub density: PackedSlot,
    /// Emission source channel.
    pub source: PackedSlot,
    /// Albedo-factor channel (`Constant(1.0)` without an albedo grid).
    pub albedo: PackedSlot,
}

/// How input values were cleaned while building (METHOD policy: NaN, ±inf and negative
/// voxels are clamped to 0 and counted, never passed on as NaN).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct BuildReport {
    /// Density voxels that were NaN, infinite or negative, set to 0.
    pub density_clamped: u64,
    /// Source voxels that were NaN, infinite or negative (or below the emission cutoff after
    /// mapping), set to 0. Voxels below the cutoff are not errors.
    pub source_invalid: u64,
    /// Albedo voxels outside `[0, 1]` (clamped) or NaN (set to 1).
    pub albedo_clamped: u64,
}

/// `a` divided by `b`, rounded towards −∞ (brick coordinates of negative voxels).
#[must_use]
pub fn floor_div(a: i32, b: i32) -> i32 {
    a.div_euclid(b)
}

/// Brick coordinate of a voxel or leaf origin.
#[must_use]
pub fn brick_of(o: IVec3) -> IVec3 {
    IVec3::new(floor_div(o.x, BRICK), floor_div(o.y, BRICK), floor_div(o.z, BRICK))
}
