//! Classic NEE over several volumes (METHOD.md §14): each emitting volume keeps its own
//! emitter table ([`EmitterDistribution`], `light::nee`), one is chosen with probability
//! `P_i ∝ Φ_i`, and a point is drawn from its table. Where volumes overlap a point can be
//! drawn through any of their tables, so its density per unit world volume is the mixture
//!
//! ```text
//! p_V(y) = Σ_i P_i p_V^i(y),
//! ```
//!
//! each `p_V^i` the volume's own (0 outside its emitting voxels), and the estimator
//! `f τ L_e(y) / (p_V(y) |y − x|²)` uses the whole emission at `y`, every volume's: it is
//! unbiased wherever some volume emits, and MIS with the point estimator's collisions
//! reads the same mixture. `Φ_i` is the table's power times the emission scale and the
//! luminance of the tint, as FNEE's mixture weighs its proxies (`light::mixture`).
//!
//! **Instances** share their volume's table ([`PlacedEmitters`]): a point is drawn in the
//! volume's own frame and carried out, and its density per world volume picks up the
//! change of volume, `p_V(y) = p_V'(y') |det L|` with `y' = L y + c` the point in the
//! volume's frame (`Instance::base_per_world_volume`). Only the tables whose boxes hold
//! `y` are evaluated, found through an R*-tree (`plume_volume::instance::BoundsIndex`).
//!
//! A table at brick resolution reads its volume's voxels; they come from the field
//! ([`plume_volume::Field::member_voxels`]), so the mixture holds no volume itself.

use std::sync::Arc;

use glam::DVec3;

use super::by_power::{shared_bytes, ByPower, Chosen};
use super::nee::{EmitterDistribution, VoxelSample};
use plume_volume::field::{Bounds3, Field};
use plume_volume::instance::{BoundsIndex, Instance};
use plume_volume::Volume;

/// A volume's emitter table where the volume is placed.
#[derive(Clone, Debug)]
pub struct PlacedEmitters {
    /// The table, in its volume's own world frame.
    pub table: Arc<EmitterDistribution>,
    /// The member of the field whose voxels the table reads
    /// ([`plume_volume::Field::member_voxels`]).
    pub member: usize,
    /// The instance's placement of that frame, if any.
    pub instance: Option<Instance>,
    /// The world box of the volume's emission where it is placed (the voxels' box grown
    /// by a voxel, which the trilinear hat reaches).
    pub bounds: Bounds3,
}

impl PlacedEmitters {
    /// `p_V^i(y)` per unit world volume.
    fn pdf(&self, volume: &Volume, y: DVec3) -> f64 {
        match &self.instance {
            None => self.table.pdf(volume, y),
            Some(i) => self.table.pdf(volume, i.point(y)) * i.base_per_world_volume(),
        }
    }
}

/// Several volumes' emitter tables and the probability of choosing each (module docs).
#[derive(Debug)]
pub struct EmitterMixture {
    emitters: ByPower<PlacedEmitters>,
    /// The emitters' boxes.
    index: BoundsIndex,
}

impl EmitterMixture {
    /// The tables with their weights `Φ_i`; tables of zero (or non-finite) weight are
    /// left out. `None` when none is left.
    #[must_use]
    pub fn new(emitters: Vec<(PlacedEmitters, f64)>) -> Option<EmitterMixture> {
        let emitters = ByPower::new(emitters)?;
        let boxes: Vec<Bounds3> = emitters.lights().iter().map(|e| e.bounds).collect();
        Some(EmitterMixture { emitters, index: BoundsIndex::new(&boxes) })
    }

    /// The tables kept, and their probabilities.
    pub fn emitters(&self) -> impl Iterator<Item = (&PlacedEmitters, f64)> {
        self.emitters.iter()
    }

    /// Bytes held by the tables (a shared one once) and the mixture's own.
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        let lights = self.emitters.lights();
        shared_bytes(lights, |e| &e.table, EmitterDistribution::memory_bytes)
            + lights.len() * (std::mem::size_of::<PlacedEmitters>() + 64)
            + self.emitters.table_bytes()
    }

    /// A point `y` of the volume `u_voxel` chooses, drawn from its table with the rest of
    /// `u_voxel` and `u_pos`; `pdf` is the mixture's `p_V(y)`. `None` where the field has
    /// no voxels for the chosen table.
    pub fn sample<F: Field>(
        &self,
        field: &F,
        u_voxel: f64,
        u_pos: [f64; 3],
    ) -> Option<VoxelSample> {
        let Chosen { index: i, pmf: p, u: v } = self.emitters.choose(u_voxel);
        let chosen = &self.emitters.lights()[i];
        let s = chosen.table.sample(field.member_voxels(chosen.member)?, v, u_pos);
        let (p_world, own) = match &chosen.instance {
            None => (s.p_world, s.pdf),
            Some(x) => {
                (x.world_from_base.transform_point3(s.p_world), s.pdf * x.base_per_world_volume())
            }
        };
        // The chosen table's density as drawn; the others' where `y` lies in their boxes
        let others = self.sum_pdf(field, p_world, Some(i));
        Some(VoxelSample { p_world, pdf: p * own + others, voxel: s.voxel })
    }

    /// `p_V(y) = Σ_i P_i p_V^i(y)` over the tables whose boxes hold `y`.
    pub fn pdf<F: Field>(&self, field: &F, y: DVec3) -> f64 {
        self.sum_pdf(field, y, None)
    }

    fn sum_pdf<F: Field>(&self, field: &F, y: DVec3, skip: Option<usize>) -> f64 {
        let mut found = Vec::new();
        self.index.at_point(y, &mut found);
        found
            .into_iter()
            .filter(|&j| Some(j) != skip)
            .filter_map(|j| {
                let e = &self.emitters.lights()[j];
                Some(self.emitters.pmf(j) * e.pdf(field.member_voxels(e.member)?, y))
            })
            .sum()
    }
}

/// The emitters classic NEE samples: one volume's table with its voxels, or several
/// volumes' mixture with the field that holds their voxels.
#[derive(Clone, Copy, Debug)]
pub enum VolumeEmitters<'a, F: Field> {
    /// One volume.
    One {
        /// Its table.
        table: &'a EmitterDistribution,
        /// Its voxels.
        volume: &'a Volume,
    },
    /// Several volumes.
    Several {
        /// Their tables.
        mixture: &'a EmitterMixture,
        /// The field of the volumes.
        field: &'a F,
    },
}

impl<F: Field> VolumeEmitters<'_, F> {
    /// A point drawn ∝ power, with its density per unit world volume.
    #[inline]
    pub fn sample(&self, u_voxel: f64, u_pos: [f64; 3]) -> Option<VoxelSample> {
        match self {
            VolumeEmitters::One { table, volume } => Some(table.sample(volume, u_voxel, u_pos)),
            VolumeEmitters::Several { mixture, field } => mixture.sample(*field, u_voxel, u_pos),
        }
    }

    /// The density per unit world volume of drawing `y`.
    #[inline]
    pub fn pdf(&self, y: DVec3) -> f64 {
        match self {
            VolumeEmitters::One { table, volume } => table.pdf(volume, y),
            VolumeEmitters::Several { mixture, field } => mixture.pdf(*field, y),
        }
    }
}

/// The world box of `volume`'s voxels grown by one voxel on every side, where `instance`
/// (if any) places it: where its emitter table's points can fall.
pub fn emitting_bounds(volume: &Volume, instance: Option<Instance>) -> Bounds3 {
    let b = volume.world_bounds();
    let m = volume.world_from_index.matrix3;
    // The world extent of one voxel along each world axis
    let pad = m.x_axis.abs() + m.y_axis.abs() + m.z_axis.abs();
    let grown = Bounds3 { lo: b.lo - pad, hi: b.hi + pad };
    instance.map_or(grown, |i| i.bounds(grown))
}
