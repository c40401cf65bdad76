//! The tracker a sample traces with: regular tracking through a still volume (exact
//! free paths and transmittance, METHOD §3), or null collisions at the sample's shutter
//! time through a moving one (`volume::motion`, `medium::null_tracking`). Chosen once per
//! sample; a still scene runs exactly the regular code.

use crate::medium::null_tracking::{null_track, ratio_transmittance, PointSample};
use crate::medium::tracking::{optical_depth, OpticalDepth};
use crate::medium::{track, Estimator, Medium, TrackResult};
use crate::sampling::Sampler;
use crate::volume::field::{Field, Ray};
use crate::volume::motion::Motion;

/// How a sample tracks rays.
pub enum Tracker<'a, F: Field> {
    /// Regular tracking of a still volume.
    Regular(&'a F),
    /// Null collisions through the volume advected to `time` (seconds).
    Moving {
        /// The frame's volume.
        field: &'a F,
        /// Velocity, shutter, majorants.
        motion: &'a Motion,
        /// The sample's time.
        time: f64,
    },
}

impl<F: Field> Tracker<'_, F> {
    /// The field at world point `p` at the sample's time.
    fn point(field: &F, motion: &Motion, time: f64, medium: &Medium, p: glam::DVec3) -> PointSample {
        let q = motion.source_point(p, time);
        let v = field.reconstruct(q, &|d, s| medium.emission.le(d, s));
        PointSample { density: v.density, source: field.values_at(q).source, emission: v.emission, albedo: field.albedo_at(q) }
    }

    /// A free path and the estimator's emission along `ray` over `[0, t_max]`
    /// ([`track`] or [`null_track`]).
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub fn track(&self, medium: &Medium, ray: &Ray, t_max: f64, estimator: Estimator, need_collision: bool, u: f64, sampler: &mut Sampler) -> TrackResult {
        match *self {
            Tracker::Regular(field) => track(field, medium, ray, t_max, estimator, need_collision, u, sampler),
            Tracker::Moving { field, motion, time } => {
                let eval = |p| Self::point(field, motion, time, medium, p);
                null_track(&motion.majorants, &eval, medium, ray, t_max, estimator, need_collision, u, sampler)
            }
        }
    }

    /// Transmittance along `ray` over `[0, t_max]` and the traversal's steps: exact by
    /// regular tracking (stopped once the optical depth passes 745, where `e^{−OD}` is 0),
    /// or ratio tracking's unbiased estimate.
    #[inline]
    pub fn transmittance(&self, medium: &Medium, ray: &Ray, t_max: f64, sampler: &mut Sampler) -> (f64, u64) {
        match *self {
            Tracker::Regular(field) => {
                let OpticalDepth { optical_depth: od, voxel_steps } = optical_depth(field, medium, ray, t_max, 745.0);
                ((-od).exp(), voxel_steps)
            }
            Tracker::Moving { field, motion, time } => {
                let eval = |p| Self::point(field, motion, time, medium, p);
                (ratio_transmittance(&motion.majorants, &eval, medium, ray, t_max, sampler), 0)
            }
        }
    }
}
