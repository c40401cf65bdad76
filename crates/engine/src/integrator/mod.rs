//! Integrators: radiance along camera rays.
//!
//! [`Integrator`] (in `volpath.rs`) traces forward paths with line-integrated emission and
//! optional NEE/FNEE; with `max_depth = 0` or albedo 0 it is the emission–absorption
//! integrator `L = ∫₀^d τ(s) L_e(s) ds`. Alpha is `1 − τ(d)` of the camera segment
//! (estimated: the escape indicator, or the exact ray-marched transmittance).

pub mod aov;
pub mod deferred;
pub mod lights;
pub mod split_map;
pub mod tracker;
pub mod volpath;

use plume_scene::{Estimator, SceneDescription};

use crate::camera::Camera;
use crate::medium::Medium;
use plume_volume::field::Field;
use plume_volume::trilinear::Trilinear;
use plume_volume::{Interpolation, Volume};

pub use aov::{AovLayout, AovSample, Aovs, Component, NoAovs};
pub use lights::{light_power, LightSampling, Lights, MisHeuristic};
pub use split_map::{SplitBy, SplitMap};
pub use tracker::{PointLookup, Tracking};
pub use volpath::Integrator;

/// Everything a render reads: immutable and `Sync`, built once.
#[derive(Debug)]
pub struct Scene<F: Field> {
    /// The volume (or an analytic field in tests).
    pub field: F,
    /// Coefficients and emission.
    pub medium: Medium,
    /// The camera.
    pub camera: Camera,
    /// Light-sampling structures (NEE distribution, FNEE proxy), when used.
    pub lights: Lights,
    /// Motion blur (velocity, shutter, majorants); `None`: a still volume, regular
    /// tracking.
    pub motion: Option<plume_volume::motion::Motion>,
    /// Majorants for null-collision tracking of a still volume (`integrator::tracker`,
    /// [`Tracking`] other than `Regular`); `None`: every segment tracks regularly.
    pub majorants: Option<plume_volume::majorant::MajorantGrid>,
}

/// A loaded volume's scene, with the volume reconstructed as the description asks.
///
/// Render code is generic over the [`Field`]; [`crate::with_scene!`] picks the
/// monomorphized version once per call, so nearest reconstruction runs exactly the code
/// it ran before trilinear existed.
#[derive(Debug)]
pub enum AnyScene {
    /// Piecewise-constant voxels.
    Nearest(Scene<Volume>),
    /// Trilinear reconstruction (METHOD.md §12).
    Linear(Scene<Trilinear>),
}

/// Evaluate `$body` with `$s` bound to the [`Scene`] inside an [`AnyScene`], whichever
/// reconstruction it has.
#[macro_export]
macro_rules! with_scene {
    ($any:expr, $s:ident => $body:expr) => {
        match $any {
            $crate::integrator::AnyScene::Nearest($s) => $body,
            $crate::integrator::AnyScene::Linear($s) => $body,
        }
    };
}

impl AnyScene {
    /// `scene` reconstructed by `interpolation`. Trilinear adds its dual pyramid (no copy
    /// of the voxels) and draws NEE points from the trilinear hat (`light/nee.rs`).
    #[must_use]
    pub fn new(scene: Scene<Volume>, interpolation: Interpolation) -> AnyScene {
        match interpolation {
            Interpolation::Nearest => AnyScene::Nearest(scene),
            Interpolation::Linear => {
                let Scene { field, medium, camera, lights, motion, majorants } = scene;
                AnyScene::Linear(Scene {
                    field: Trilinear::new(field),
                    medium,
                    camera,
                    lights: lights.for_interpolation(Interpolation::Linear),
                    motion,
                    majorants,
                })
            }
        }
    }

    /// The same scene reconstructed by `interpolation`: the volume is moved, never copied
    /// or re-read; trilinear builds its dual pyramid, nearest drops it. NEE follows.
    #[must_use]
    pub fn into_interpolation(self, interpolation: Interpolation) -> AnyScene {
        match (self, interpolation) {
            (AnyScene::Nearest(s), i) => AnyScene::new(s, i),
            (AnyScene::Linear(s), Interpolation::Nearest) => {
                let Scene { field, medium, camera, lights, motion, majorants } = s;
                AnyScene::Nearest(Scene {
                    field: field.into_volume(),
                    medium,
                    camera,
                    lights: lights.for_interpolation(Interpolation::Nearest),
                    motion,
                    majorants,
                })
            }
            (linear, Interpolation::Linear) => linear,
        }
    }

    /// How the volume is reconstructed.
    #[must_use]
    pub fn interpolation(&self) -> Interpolation {
        match self {
            AnyScene::Nearest(_) => Interpolation::Nearest,
            AnyScene::Linear(_) => Interpolation::Linear,
        }
    }

    /// The volume's bricks.
    #[must_use]
    pub fn volume(&self) -> &Volume {
        match self {
            AnyScene::Nearest(s) => &s.field,
            AnyScene::Linear(s) => s.field.volume(),
        }
    }

    /// The medium.
    #[must_use]
    pub fn medium(&self) -> &Medium {
        with_scene!(self, s => &s.medium)
    }

    /// The camera.
    #[must_use]
    pub fn camera(&self) -> &Camera {
        with_scene!(self, s => &s.camera)
    }

    /// The light-sampling structures.
    #[must_use]
    pub fn lights(&self) -> &Lights {
        with_scene!(self, s => &s.lights)
    }

    /// Replace the volume's light-sampling structures (built for nearest reconstruction;
    /// NEE is switched to this scene's reconstruction). External lights stay unless
    /// `lights` brings its own.
    pub fn set_lights(&mut self, mut lights: Lights) {
        let interpolation = self.interpolation();
        let old = match self {
            AnyScene::Nearest(s) => &mut s.lights,
            AnyScene::Linear(s) => &mut s.lights,
        };
        if lights.external.is_none() {
            lights.external = old.external.take();
        }
        *old = match interpolation {
            Interpolation::Nearest => lights,
            Interpolation::Linear => lights.for_interpolation(Interpolation::Linear),
        };
    }
}

impl Integrator {
    /// The integrator this description asks for.
    #[must_use]
    pub fn for_scene(scene: &SceneDescription) -> Integrator {
        let (estimator, light_sampling) = scene.integrator.parts();
        Integrator::for_scene_with(scene, estimator, light_sampling)
    }

    /// The integrator this description asks for, with another estimator and light
    /// sampling (benchmarks compare them on one scene); the tracking is resolved for them.
    #[must_use]
    pub fn for_scene_with(scene: &SceneDescription, estimator: Estimator, light_sampling: LightSampling) -> Integrator {
        // Where paths scatter the camera segment is ray-marched unless asked otherwise: its
        // emission is then exact along each ray, and its collision can be forced
        let camera_estimator = scene.integrator.camera_estimator.map(|k| k.with_kappa(scene.integrator.kappa));
        Integrator {
            estimator,
            camera_estimator: camera_estimator.or(scene.scatters().then_some(Estimator::RayMarch)),
            light_sampling,
            mis: scene.integrator.mis,
            max_depth: if scene.albedo() > 0.0 { scene.integrator.max_depth } else { 0 },
            tracking: scene.integrator.tracking.resolve(estimator, light_sampling),
            split: scene.integrator.split,
            split_by: scene.integrator.split_by,
            camera_collision: scene.integrator.camera_collision.collision(),
            point_lookup: scene.integrator.point_lookup,
        }
    }
}

/// Integer counters gathered per tile and summed in tile order.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Counters {
    /// Camera samples taken.
    pub samples: u64,
    /// Segments visited by tracking (after merging equal neighbours).
    pub segments: u64,
    /// Voxel steps of all traversals (voxels crossed plus skipped pyramid nodes).
    pub voxel_steps: u64,
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
    pub first_nonfinite: Option<crate::render::SampleId>,
}

impl Counters {
    /// Add another tile's counters (keeps the first non-finite sample of `self`).
    pub fn merge(&mut self, o: &Counters) {
        self.samples += o.samples;
        self.segments += o.segments;
        self.voxel_steps += o.voxel_steps;
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

/// Receives a path's events when a sample is replayed with `--debug-pixel`. The render
/// loop uses [`NoTrace`], which compiles to nothing.
pub trait Trace {
    /// Record one event; `message` is only called when tracing.
    fn event(&mut self, message: impl FnOnce() -> String);
}

/// Tracing off.
pub struct NoTrace;

impl Trace for NoTrace {
    #[inline(always)]
    fn event(&mut self, _message: impl FnOnce() -> String) {}
}

/// Tracing into a list of lines.
#[derive(Default)]
pub struct LineTrace(pub Vec<String>);

impl Trace for LineTrace {
    fn event(&mut self, message: impl FnOnce() -> String) {
        self.0.push(message());
    }
}
