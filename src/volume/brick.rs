//! [`Volume`]: sparse 8³ bricks in index space holding two channels, density ρ and the
//! emission *source* (temperature in Kelvin or an emission grid value, already mapped so
//! that 0 means "emits nothing").
//!
//! Bricks sit on a dense brick table over the bounding box of all leaves (4 bytes per
//! 8³ voxels of the box, empty or not). A brick whose 512 values are all equal in a
//! channel stores that channel as one constant, so OpenVDB's voxelized active tiles and
//! flat regions cost 4 bytes instead of 2 KiB.
//!
//! Voxel `(i,j,k)` is centred at index `(i,j,k)` and constant over `[i-½, i+½]³`
//! (OpenVDB's convention, METHOD.md §1). The brick with origin `8b` spans
//! `[8b-½, 8b+7½]`.

use glam::{DAffine3, DVec3, IVec3};

use super::pyramid::Pyramid;
use crate::error::{Error, Result};
use crate::vdb::{leaf_offset, FloatGrid, LEAF_VOXELS};

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
/// voxel (OpenVDB's x-major order puts x-neighbours 256 bytes apart). Measured on random
/// chords through a 256³ explosion: see `plume bench core` in the README.
#[inline]
#[must_use]
pub fn brick_offset(x: i32, y: i32, z: i32) -> usize {
    (spread3(x & 7) << 2) | (spread3(y & 7) << 1) | spread3(z & 7)
}

/// Marker for "no brick here" in the brick table.
const NO_BRICK: u32 = u32::MAX;

/// One channel of one brick: either a constant or an offset into the channel's value array.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Slot {
    /// All 512 voxels hold this value.
    Constant(f32),
    /// Values at `offset .. offset + 512` of the channel array, in [`brick_offset`] order.
    Dense(u32),
}

/// Both channels of one brick.
#[derive(Clone, Copy, Debug)]
pub struct Brick {
    /// Density channel.
    pub density: Slot,
    /// Emission source channel.
    pub source: Slot,
    /// Albedo-factor channel (`Constant(1.0)` without an albedo grid).
    pub albedo: Slot,
}

/// How input values were cleaned while building (METHOD policy: NaN, ±inf and negative
/// voxels are clamped to 0 and counted, never passed on as NaN).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct BuildReport {
    /// Density voxels that were NaN, infinite or negative, set to 0.
    pub density_clamped: u64,
    /// Source voxels that were NaN, infinite or negative (or below the emission cutoff after
    /// mapping), set to 0. Voxels below the cutoff are not errors.
    pub source_invalid: u64,
    /// Albedo voxels outside `[0, 1]` (clamped) or NaN (set to 1).
    pub albedo_clamped: u64,
}

/// A sparse brick volume in index space with its `world_from_index` transform.
#[derive(Debug)]
pub struct Volume {
    pub(crate) world_from_index: DAffine3,
    pub(crate) index_from_world: DAffine3,
    /// Brick coordinate (origin / 8) of table cell (0,0,0).
    pub(crate) brick_lo: IVec3,
    /// Table size in bricks.
    pub(crate) dims: IVec3,
    /// Brick index per table cell (x fastest), or [`NO_BRICK`].
    pub(crate) table: Vec<u32>,
    pub(crate) bricks: Vec<Brick>,
    pub(crate) density_values: Vec<f32>,
    pub(crate) source_values: Vec<f32>,
    pub(crate) albedo_values: Vec<f32>,
    pub(crate) pyramid: Pyramid,
    /// Input clean-up counts.
    pub report: BuildReport,
}

fn floor_div(a: i32, b: i32) -> i32 {
    a.div_euclid(b)
}

impl Volume {
    /// Build a volume from a density grid and an optional source grid.
    ///
    /// `source_map` turns a raw source value (e.g. a temperature grid value) into the
    /// stored source (Kelvin after mapping, 0 below the emission cutoff); it must return
    /// 0 for "no emission". Both grids must share one transform.
    ///
    /// # Errors
    /// Incompatible transforms, an empty volume, or a bounding box too large for the brick
    /// table ([`MAX_TABLE_ENTRIES`]).
    pub fn build(
        density: &FloatGrid,
        source: Option<&FloatGrid>,
        source_map: impl Fn(f32) -> f32 + Sync,
    ) -> Result<Volume> {
        Volume::build_with_albedo(density, source, source_map, None)
    }

    /// [`Volume::build`] with an optional albedo grid: its values, clamped to `[0, 1]`
    /// (NaN → 1, counted), become a per-voxel albedo factor (1 outside its leaves).
    ///
    /// # Errors
    /// As [`Volume::build`].
    pub fn build_with_albedo(
        density: &FloatGrid,
        source: Option<&FloatGrid>,
        source_map: impl Fn(f32) -> f32 + Sync,
        albedo: Option<&FloatGrid>,
    ) -> Result<Volume> {
        for s in source.iter().chain(albedo.iter()) {
            let a = density.world_from_index;
            let b = s.world_from_index;
            let scale = a.matrix3.abs().to_cols_array().iter().fold(0.0f64, |m, v| m.max(*v));
            let close = a.matrix3.abs_diff_eq(b.matrix3, 1e-6 * scale.max(1e-30))
                && a.translation.abs_diff_eq(b.translation, 1e-6 * scale.max(1e-30));
            if !close {
                return Err(Error::Scene(format!(
                    "grids {:?} and {:?} have different transforms; plume needs them on one voxel grid",
                    density.name, s.name
                )));
            }
        }
        let mut origins: Vec<IVec3> = density.origins.clone();
        if let Some(s) = source {
            origins.extend_from_slice(&s.origins);
        }
        if let Some(a) = albedo {
            origins.extend_from_slice(&a.origins);
        }
        let index_from_world = density.world_from_index.inverse();
        if !index_from_world.is_finite() || density.world_from_index.matrix3.determinant() == 0.0 {
            return Err(Error::Scene(format!("grid {:?} has a singular transform", density.name)));
        }
        if origins.is_empty() {
            return Ok(Volume::empty(density.world_from_index, index_from_world));
        }
        let brick_of = |o: IVec3| IVec3::new(floor_div(o.x, BRICK), floor_div(o.y, BRICK), floor_div(o.z, BRICK));
        let mut lo = IVec3::MAX;
        let mut hi = IVec3::MIN;
        for &o in &origins {
            let b = brick_of(o);
            lo = lo.min(b);
            hi = hi.max(b);
        }
        let dims64 = (hi.as_i64vec3() - lo.as_i64vec3()) + 1;
        let entries = dims64.x as u64 * dims64.y as u64 * dims64.z as u64;
        if entries > MAX_TABLE_ENTRIES {
            return Err(Error::Scene(format!(
                "grid {:?} spans {}x{}x{} bricks ({} voxels across); plume's brick table is limited to {} bricks",
                density.name, dims64.x, dims64.y, dims64.z, dims64.max_element() * 8, MAX_TABLE_ENTRIES
            )));
        }
        let dims = dims64.as_ivec3();
        let cell = |b: IVec3| -> usize {
            let r = b - lo;
            (r.x as usize) + dims.x as usize * (r.y as usize + dims.y as usize * r.z as usize)
        };
        // Leaf lookup per table cell for both grids.
        let mut dens_leaf = vec![NO_BRICK; entries as usize];
        for (i, &o) in density.origins.iter().enumerate() {
            dens_leaf[cell(brick_of(o))] = i as u32;
        }
        let mut src_leaf = vec![NO_BRICK; if source.is_some() { entries as usize } else { 0 }];
        if let Some(s) = source {
            for (i, &o) in s.origins.iter().enumerate() {
                src_leaf[cell(brick_of(o))] = i as u32;
            }
        }
        let mut albedo_leaf = vec![NO_BRICK; if albedo.is_some() { entries as usize } else { 0 }];
        if let Some(a) = albedo {
            for (i, &o) in a.origins.iter().enumerate() {
                albedo_leaf[cell(brick_of(o))] = i as u32;
            }
        }
        let mut table = vec![NO_BRICK; entries as usize];
        let mut bricks = Vec::new();
        let mut density_values = Vec::new();
        let mut source_values = Vec::new();
        let mut albedo_values = Vec::new();
        let mut report = BuildReport::default();
        let mut scratch = [0.0f32; LEAF_VOXELS];
        let density_background = clean(density.background, &mut 0);
        let source_background = source.map_or(0.0, |s| clean(source_map(s.background), &mut 0));
        for idx in 0..entries as usize {
            let dl = dens_leaf[idx];
            let sl = src_leaf.get(idx).copied().unwrap_or(NO_BRICK);
            let al = albedo_leaf.get(idx).copied().unwrap_or(NO_BRICK);
            if dl == NO_BRICK && sl == NO_BRICK && al == NO_BRICK {
                continue;
            }
            let density_slot = if dl == NO_BRICK {
                Slot::Constant(density_background)
            } else {
                for (d, &v) in scratch.iter_mut().zip(density.leaf_values(dl as usize)) {
                    *d = clean(v, &mut report.density_clamped);
                }
                store(&scratch, &mut density_values)
            };
            let source_slot = match source {
                Some(s) if sl != NO_BRICK => {
                    for (d, &v) in scratch.iter_mut().zip(s.leaf_values(sl as usize)) {
                        *d = clean(source_map(v), &mut report.source_invalid);
                    }
                    store(&scratch, &mut source_values)
                }
                _ => Slot::Constant(source_background),
            };
            let albedo_slot = match albedo {
                Some(a) if al != NO_BRICK => {
                    for (d, &v) in scratch.iter_mut().zip(a.leaf_values(al as usize)) {
                        *d = clean_albedo(v, &mut report.albedo_clamped);
                    }
                    store(&scratch, &mut albedo_values)
                }
                Some(a) => Slot::Constant(clean_albedo(a.background, &mut 0)),
                None => Slot::Constant(1.0),
            };
            table[idx] = bricks.len() as u32;
            bricks.push(Brick { density: density_slot, source: source_slot, albedo: albedo_slot });
        }
        let mut volume = Volume {
            world_from_index: density.world_from_index,
            index_from_world,
            brick_lo: lo,
            dims,
            table,
            bricks,
            density_values,
            source_values,
            albedo_values,
            pyramid: Pyramid::default(),
            report,
        };
        volume.pyramid = Pyramid::build(&volume);
        Ok(volume)
    }

    fn empty(world_from_index: DAffine3, index_from_world: DAffine3) -> Volume {
        let mut v = Volume {
            world_from_index,
            index_from_world,
            brick_lo: IVec3::ZERO,
            dims: IVec3::ZERO,
            table: Vec::new(),
            bricks: Vec::new(),
            density_values: Vec::new(),
            source_values: Vec::new(),
            albedo_values: Vec::new(),
            pyramid: Pyramid::default(),
            report: BuildReport::default(),
        };
        v.pyramid = Pyramid::build(&v);
        v
    }

    /// True when the volume holds no bricks.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.bricks.is_empty()
    }

    /// Affine map from index to world space.
    #[must_use]
    pub fn world_from_index(&self) -> DAffine3 {
        self.world_from_index
    }

    /// Affine map from world to index space.
    #[must_use]
    pub fn index_from_world(&self) -> DAffine3 {
        self.index_from_world
    }

    /// Index-space box covered by the brick table: `[lo, hi]`, voxel faces included.
    #[must_use]
    pub fn index_bounds(&self) -> (DVec3, DVec3) {
        let lo = (self.brick_lo * BRICK).as_dvec3() - 0.5;
        let hi = ((self.brick_lo + self.dims) * BRICK).as_dvec3() - 0.5;
        (lo, hi)
    }

    /// Number of stored bricks.
    #[must_use]
    pub fn brick_count(&self) -> usize {
        self.bricks.len()
    }

    /// Bricks stored with at least one dense channel.
    #[must_use]
    pub fn dense_brick_count(&self) -> usize {
        self.bricks
            .iter()
            .filter(|b| matches!(b.density, Slot::Dense(_)) || matches!(b.source, Slot::Dense(_)))
            .count()
    }

    /// Heap bytes held by bricks, table and pyramid.
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        self.table.len() * 4
            + self.bricks.len() * std::mem::size_of::<Brick>()
            + (self.density_values.len() + self.source_values.len() + self.albedo_values.len()) * 4
            + self.pyramid.memory_bytes()
    }

    /// Table cell of brick coordinate `b`, or `None` outside the table.
    #[inline]
    pub(crate) fn cell(&self, b: IVec3) -> Option<usize> {
        let r = b - self.brick_lo;
        if r.cmplt(IVec3::ZERO).any() || r.cmpge(self.dims).any() {
            return None;
        }
        Some(r.x as usize + self.dims.x as usize * (r.y as usize + self.dims.y as usize * r.z as usize))
    }

    /// The brick at brick coordinate `b`, if any.
    #[inline]
    pub(crate) fn brick(&self, b: IVec3) -> Option<&Brick> {
        let i = *self.table.get(self.cell(b)?)?;
        (i != NO_BRICK).then(|| &self.bricks[i as usize])
    }

    /// Value of a slot at local voxel `(x,y,z)`.
    #[inline]
    pub(crate) fn slot_value(values: &[f32], slot: Slot, x: i32, y: i32, z: i32) -> f32 {
        match slot {
            Slot::Constant(v) => v,
            Slot::Dense(off) => values[off as usize + brick_offset(x, y, z)],
        }
    }

    /// `(density, source)` of voxel `ijk` (nearest-voxel lookup; 0 outside all bricks).
    #[must_use]
    pub fn voxel(&self, ijk: IVec3) -> (f32, f32) {
        let b = IVec3::new(floor_div(ijk.x, BRICK), floor_div(ijk.y, BRICK), floor_div(ijk.z, BRICK));
        match self.brick(b) {
            None => (0.0, 0.0),
            Some(br) => {
                let l = ijk - b * BRICK;
                (
                    Self::slot_value(&self.density_values, br.density, l.x, l.y, l.z),
                    Self::slot_value(&self.source_values, br.source, l.x, l.y, l.z),
                )
            }
        }
    }

    /// Albedo factor of voxel `ijk` (1 outside bricks or without an albedo grid).
    #[must_use]
    pub fn voxel_albedo(&self, ijk: IVec3) -> f32 {
        let b = IVec3::new(floor_div(ijk.x, BRICK), floor_div(ijk.y, BRICK), floor_div(ijk.z, BRICK));
        self.brick(b).map_or(1.0, |br| {
            let l = ijk - b * BRICK;
            Self::slot_value(&self.albedo_values, br.albedo, l.x, l.y, l.z)
        })
    }

    /// `(density, source)` at an index-space point: the voxel `⌊p + ½⌋`.
    #[must_use]
    pub fn lookup_index(&self, p_index: DVec3) -> (f32, f32) {
        self.voxel((p_index + 0.5).floor().as_ivec3())
    }

    /// `(density, source)` at a world-space point.
    #[must_use]
    pub fn lookup_world(&self, p_world: DVec3) -> (f32, f32) {
        self.lookup_index(self.index_from_world.transform_point3(p_world))
    }

    /// World-space volume of one voxel, `|det A|`.
    #[must_use]
    pub fn voxel_volume(&self) -> f64 {
        self.world_from_index.matrix3.determinant().abs()
    }
}

/// NaN, ±inf and negative values become 0 and are counted.
#[inline]
fn clean(v: f32, count: &mut u64) -> f32 {
    if v.is_finite() && v >= 0.0 {
        v
    } else {
        *count += 1;
        0.0
    }
}

/// Albedo factor: clamped to `[0, 1]`, NaN → 1; changed values are counted.
#[inline]
fn clean_albedo(v: f32, count: &mut u64) -> f32 {
    if (0.0..=1.0).contains(&v) {
        v
    } else {
        *count += 1;
        if v.is_nan() { 1.0 } else { v.clamp(0.0, 1.0) }
    }
}

/// Store 512 values given in OpenVDB leaf order as a constant slot when uniform, else
/// append them in [`brick_offset`] order.
fn store(values: &[f32; LEAF_VOXELS], out: &mut Vec<f32>) -> Slot {
    let first = values[0];
    if values.iter().all(|&v| v.to_bits() == first.to_bits()) {
        Slot::Constant(first)
    } else {
        let off = out.len();
        out.resize(off + LEAF_VOXELS, 0.0);
        let brick = &mut out[off..];
        for x in 0..8 {
            for y in 0..8 {
                for z in 0..8 {
                    brick[brick_offset(x, y, z)] = values[leaf_offset(x, y, z)];
                }
            }
        }
        Slot::Dense(off as u32)
    }
}

impl Volume {
    /// Pyramid levels, finest (one node per brick-table cell) first.
    #[must_use]
    pub fn pyramid_levels(&self) -> &[super::pyramid::Level] {
        &self.pyramid.levels
    }
}

/// Brick access for the light-sampling builders (`volume::proxy`, `light::nee`), which
/// must visit every voxel exactly once and sum power in a fixed order.
impl Volume {
    /// Brick coordinates (brick origin / 8) covered by the brick table: `lo .. lo + dims`.
    #[must_use]
    pub(crate) fn brick_range(&self) -> (IVec3, IVec3) {
        (self.brick_lo, self.dims)
    }

    /// `(density, source)` of local voxel `l` (each component in `0..8`) of `brick`.
    #[inline]
    #[must_use]
    pub(crate) fn brick_voxel(&self, brick: &Brick, l: IVec3) -> (f32, f32) {
        (
            Self::slot_value(&self.density_values, brick.density, l.x, l.y, l.z),
            Self::slot_value(&self.source_values, brick.source, l.x, l.y, l.z),
        )
    }

    /// `Some((density, source))` when both channels of `brick` are constant.
    #[inline]
    #[must_use]
    pub(crate) fn brick_constant(brick: &Brick) -> Option<(f32, f32)> {
        match (brick.density, brick.source) {
            (Slot::Constant(d), Slot::Constant(s)) => Some((d, s)),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::brick_offset;

    #[test]
    fn brick_offset_is_a_bijection_with_cache_line_blocks() {
        let mut seen = [false; 512];
        for x in 0..8 {
            for y in 0..8 {
                for z in 0..8 {
                    let o = brick_offset(x, y, z);
                    assert!(!seen[o]);
                    seen[o] = true;
                    // 16 floats per 64-byte line: a 2×2×4 block shares a line.
                    assert_eq!(o / 16, brick_offset(x & !1, y & !1, z & !3) / 16);
                }
            }
        }
    }
}
