use super::*;
use crate::layout::brick_offset;

/// Voxel brick and offset of local voxel `v` of a dual brick (`DUAL_SLOTS`). The walk
/// reads corners by window index (`CORNER_STEP`); the tests check the table with this.
fn dual_slot(v: IVec3) -> (usize, usize) {
    window_slot(window_index(v))
}

/// [`dual_block_mask`] against its definition: dual block `s` is set where some voxel
/// block `s + {0,1}³` of the 5³ the 8 voxel bricks' masks describe is, for random
/// masks of every density (sparse ones leave most dual blocks clear).
#[test]
fn dual_block_mask_dilates_the_voxel_masks() {
    let mut s = plume_core::sampling::Sampler::new(0xb10c, 0, 0);
    for case in 0..400 {
        let keep = [0.02, 0.1, 0.5, 0.95][case % 4];
        let voxel: [u64; 8] = std::array::from_fn(|_| {
            (0..64).filter(|_| s.next_f64() < keep).fold(0u64, |m, b| m | 1 << b)
        });
        // Voxel block `w` (each coordinate 0..=4) of the 9³ the dual brick reads
        let occupied = |w: IVec3| {
            let k = usize::from(w.x >= 4) | usize::from(w.y >= 4) << 1 | usize::from(w.z >= 4) << 2;
            let l = w & 3;
            voxel[k] >> (l.x + 4 * l.y + 16 * l.z) & 1 == 1
        };
        let got = dual_block_mask(voxel);
        for b in 0..64 {
            let s = IVec3::new(b & 3, (b >> 2) & 3, b >> 4);
            let want = (0..8).any(|c| occupied(s + corner_offset(c)));
            assert_eq!(
                got >> b & 1 == 1,
                want,
                "case {case}, dual block {s}: {got:#x} from {voxel:x?}"
            );
        }
    }
}

/// The table of where each of a dual brick's 9³ voxels lies is the Morton offset in
/// the right one of the 8 voxel bricks, for every voxel.
#[test]
fn dual_slots_name_the_brick_and_offset_of_every_voxel() {
    for z in 0..9 {
        for y in 0..9 {
            for x in 0..9 {
                let v = IVec3::new(x, y, z);
                let k = usize::from(x >= 8) | usize::from(y >= 8) << 1 | usize::from(z >= 8) << 2;
                assert_eq!(dual_slot(v), (k, brick_offset(x & 7, y & 7, z & 7)), "voxel {v}");
            }
        }
    }
}
