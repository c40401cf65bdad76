//! The 9³ window of voxels a dual brick reads (its own voxel brick and the 7 neighbours
//! on the +x, +y, +z sides): the corner offsets of a dual cell ([`corner_offset`]), window
//! indices ([`window_index`], [`CORNER_STEP`]) and the slot table that maps an index to a
//! voxel brick and an offset in it ([`window_slot`]).

use glam::IVec3;

use crate::grid::LEAF_VOXELS;
use crate::layout::brick_offset;

/// Corner `c` of a dual cell as an offset: bit 0 → +x, bit 1 → +y, bit 2 → +z.
#[inline]
#[must_use]
pub const fn corner_offset(c: usize) -> IVec3 {
    IVec3::new((c & 1) as i32, ((c >> 1) & 1) as i32, ((c >> 2) & 1) as i32)
}

/// Where local voxel `v` (each coordinate `0..=8`) of a dual brick's 9³ lies, at index
/// `(9 v.z + v.y)·9 + v.x`: `(k << 9) | o`, voxel brick `k` of the 8 (bit 0: +x, bit 1: +y,
/// bit 2: +z) and offset `o` ([`brick_offset`]) in it. One load instead of the Morton
/// interleaving per corner read (bit-identical; measured in docs/BENCHMARKS.md,
/// "Interpolation: trilinear vs nearest"). [`Volume::voxel_block`] places a point lookup's corners
/// with it too: a cell at local `l` of any brick reaches the 9³ voxels from `l`. Padded
/// to 1024 entries, so a read masks its index instead of taking it modulo 729 (the
/// compiler cannot see that the index is below 729; the mask keeps the read in bounds
/// without a check).
pub const DUAL_SLOTS: [u16; 1024] = {
    let mut table = [0u16; 1024];
    let mut i = 0;
    while i < 729 {
        let (x, y, z) = ((i % 9) as i32, ((i / 9) % 9) as i32, (i / 81) as i32);
        let k = ((x >> 3) | ((y >> 3) << 1) | ((z >> 3) << 2)) as u16;
        table[i] = (k << 9) | brick_offset(x, y, z) as u16;
        i += 1;
    }
    table
};

/// Index in [`DUAL_SLOTS`] of local voxel `v` (each coordinate `0..=8`).
#[inline]
pub const fn window_index(v: IVec3) -> usize {
    ((v.z * 9 + v.y) * 9 + v.x) as usize
}

/// What corner `c` of a cell adds to the cell's [`window_index`]: the index of
/// [`corner_offset`]`(c)`.
pub const CORNER_STEP: [usize; 8] = {
    let mut steps = [0; 8];
    let mut c = 0;
    while c < 8 {
        steps[c] = window_index(corner_offset(c));
        c += 1;
    }
    steps
};

/// Voxel brick and offset at [`DUAL_SLOTS`] index `i`.
#[inline]
pub fn window_slot(i: usize) -> (usize, usize) {
    let slot = DUAL_SLOTS[i & 1023];
    (usize::from(slot >> 9) & 7, usize::from(slot) & (LEAF_VOXELS - 1))
}
