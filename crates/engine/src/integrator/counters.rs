//! Integer counters of a render, gathered per tile and summed in tile order (`--stats`).

use crate::medium::{ShadowResult, TrackResult};
use plume_scene::SampleId;

/// Integer counters gathered per tile and summed in tile order.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Counters {
    /// Camera samples taken.
    pub samples: u64,
    /// Rays tracked: camera and scattered segments, and shadow rays.
    pub walks: u64,
    /// Segments visited by tracking (after merging equal neighbours).
    pub segments: u64,
    /// Voxel steps of all traversals (voxels crossed plus skipped pyramid nodes).
    pub voxel_steps: u64,
    /// Tentative points of null-collision tracking (each a read of the field).
    pub tentative_points: u64,
    /// Real collisions sampled.
    pub collisions: u64,
    /// FNEE direction samples taken.
    pub fnee_samples: u64,
    /// Classic NEE samples taken.
    pub nee_samples: u64,
    /// External light samples taken (suns, sphere lights, environments).
    pub external_light_samples: u64,
    /// Samples dropped because they were NaN or infinite.
    pub nonfinite_samples: u64,
    /// Samples whose scattered paths were deferred (`integrator::deferred`).
    pub deferred_samples: u64,
    /// Rounds of rerun and fill of deferred paths.
    pub deferred_rounds: u64,
    /// Values read in file order for deferred paths.
    pub deferred_lookups: u64,
    /// Deferred samples whose paths were traced directly after the last round.
    pub deferred_direct: u64,
    /// The first dropped sample, for `--debug-pixel` (serialized as
    /// `{"x": …, "y": …, "sample": …}`, or `null`).
    pub first_nonfinite: Option<SampleId>,
}

impl Counters {
    /// Count a tracked segment's work: its segments, voxel steps and tentative points.
    #[inline]
    pub fn add_track(&mut self, r: &TrackResult) {
        self.walks += 1;
        self.segments += u64::from(r.segments);
        self.voxel_steps += r.voxel_steps;
        self.tentative_points += r.tentative_points;
    }

    /// Count a shadow ray's work: its voxel steps and tentative points.
    #[inline]
    pub fn add_shadow(&mut self, r: &ShadowResult) {
        self.walks += 1;
        self.voxel_steps += r.voxel_steps;
        self.tentative_points += r.tentative_points;
    }

    /// Add another tile's counters (keeps the first non-finite sample of `self`).
    pub fn merge(&mut self, o: &Counters) {
        self.samples += o.samples;
        self.walks += o.walks;
        self.segments += o.segments;
        self.voxel_steps += o.voxel_steps;
        self.tentative_points += o.tentative_points;
        self.collisions += o.collisions;
        self.fnee_samples += o.fnee_samples;
        self.nee_samples += o.nee_samples;
        self.external_light_samples += o.external_light_samples;
        self.nonfinite_samples += o.nonfinite_samples;
        self.deferred_samples += o.deferred_samples;
        self.deferred_rounds += o.deferred_rounds;
        self.deferred_lookups += o.deferred_lookups;
        self.deferred_direct += o.deferred_direct;
        if self.first_nonfinite.is_none() {
            self.first_nonfinite = o.first_nonfinite;
        }
    }
}
