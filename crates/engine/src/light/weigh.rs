//! Weighing a brick's voxels by emitted power: what both classic NEE tables (the per-voxel
//! one in `nee`, the per-brick one in `nee_bricks`) are built from.

use glam::IVec3;

use plume_core::error::{Error, Result};
use plume_volume::brick::{Brick, Volume};
use plume_volume::grid::LEAF_VOXELS;

/// Brick-table cell `k` (x fastest) as a coordinate relative to the table's origin.
#[inline]
pub fn cell_coords(k: usize, dims: IVec3) -> IVec3 {
    let (nx, ny) = (dims.x as usize, dims.y as usize);
    IVec3::new((k % nx) as i32, ((k / nx) % ny) as i32, (k / (nx * ny)) as i32)
}

/// The voxels of `brick` with a non-zero source and positive power, `(offset, Φ_i)` to
/// `visit` in offset order (`local` maps an offset to the local voxel: leaf or brick
/// order), until it returns false; `Err` for a negative or non-finite power, naming the
/// voxel. A constant brick is one call of `weigh` and of `visit`, with offset
/// `LEAF_VOXELS` and its voxels' common power. Both NEE tables weigh bricks here.
pub fn weigh_brick(
    volume: &Volume,
    brick: &Brick,
    origin: IVec3,
    weigh: &(impl Fn(f32, f32) -> f64 + ?Sized),
    local: fn(usize) -> IVec3,
    mut visit: impl FnMut(usize, f64) -> bool,
) -> Result<()> {
    let check = |off: usize, density: f32, source: f32, p: f64| {
        if p >= 0.0 && p.is_finite() {
            Ok(p)
        } else {
            let at = origin + if off < LEAF_VOXELS { local(off) } else { IVec3::ZERO };
            Err(Error::Scene(format!("emitted power {p} at voxel {at} (density {density}, source {source}) is negative or not finite")))
        }
    };
    if let Some((density, source)) = Volume::brick_constant(brick) {
        if source != 0.0 {
            let p = check(LEAF_VOXELS, density, source, weigh(density, source))?;
            if p > 0.0 {
                visit(LEAF_VOXELS, p);
            }
        }
        return Ok(());
    }
    for off in 0..LEAF_VOXELS {
        let v = volume.brick_voxel(brick, local(off));
        if v.source != 0.0 {
            let p = check(off, v.density, v.source, weigh(v.density, v.source))?;
            if p > 0.0 && !visit(off, p) {
                break;
            }
        }
    }
    Ok(())
}
