//! Regular tracking over a stretch of a ray, for null-collision tracking's dense
//! stretches (`medium::null_tracking`, "Dense stretches"): the free path of point, line
//! and blend (`free_path_stretch`, which is also every whole free-path walk), or
//! ray-march's expected value carrying ratio tracking's weight (`track_expected` from
//! the stretch's start), each continuing the free path with what is left of its
//! exponential.

use super::{free_path_stretch, track_expected, MarchStart};
use crate::medium::forced::Collision;
use crate::medium::{DistanceSample, Estimator, Medium};
use plume_core::sampling::Sampler;
use plume_volume::field::{Field, Ray};

/// How a stretch of a ray is walked exactly ([`walk_stretch`]). `e` is the free path's
/// exponential (what is left of it, for null-collision tracking's dense stretches): the
/// free path ends where the optical depth from the stretch's start reaches it.
#[derive(Clone, Copy, Debug)]
pub enum StretchKind {
    /// The free path, with the point, line or blend estimate of the emission.
    FreePath {
        /// The estimator.
        estimator: Estimator,
        /// The exponential.
        e: f64,
    },
    /// Ray-march's expected value, starting with ratio tracking's `weight`; the collision
    /// is located only with `need_collision`.
    Expected {
        /// Whether the walk locates the collision.
        need_collision: bool,
        /// The exponential.
        e: f64,
        /// The weight carried into the stretch.
        weight: f64,
    },
}

/// What an exact walk over a stretch of a ray found ([`walk_stretch`]).
#[derive(Clone, Copy, Debug)]
pub struct StretchWalk {
    /// The collision, if the free path ended in the stretch.
    pub collision: Option<DistanceSample>,
    /// The estimate over the stretch (the free path's up to the collision; ray-march's
    /// with the weight it started with).
    pub emission: [f64; 3],
    /// The optical depth walked: `e` at a collision, the stretch's otherwise.
    pub optical_depth: f64,
    /// The weight carried out: 1 for a free path; for ray-march the weight it started
    /// with times the stretch's transmittance, 0 once the roulette ended the march.
    pub weight: f64,
    /// Pieces visited.
    pub segments: u32,
    /// Voxel steps of the traversal.
    pub voxel_steps: u64,
}

/// Regular tracking of `ray` over `[t0, t1]` as `kind` says, for null-collision
/// tracking's dense stretches (`medium::null_tracking`).
// Each argument is a distinct input of the walk (randomness stays an argument: STYLE §3)
#[allow(clippy::too_many_arguments)]
pub fn walk_stretch<F: Field>(
    field: &F,
    medium: &Medium,
    ray: &Ray,
    t0: f64,
    t1: f64,
    kind: StretchKind,
    sampler: &mut Sampler,
) -> StretchWalk {
    match kind {
        StretchKind::FreePath { estimator, e } => {
            free_path_stretch(field, medium, ray, t0, t1, estimator, e)
        }
        StretchKind::Expected { need_collision, e, weight } => {
            let collision = if need_collision { Collision::Analog } else { Collision::Skip };
            let start = MarchStart { t0, e, weight };
            let r = track_expected::<F, false>(
                field, medium, ray, start, t1, collision, 0.0, sampler, None,
            );
            StretchWalk {
                collision: matches!(r.event, DistanceSample::Collided { .. }).then_some(r.event),
                emission: r.emission,
                optical_depth: r.optical_depth,
                weight: r.transmittance,
                segments: r.segments,
                voxel_steps: r.voxel_steps,
            }
        }
    }
}
