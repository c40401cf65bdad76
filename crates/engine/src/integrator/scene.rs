//! The scene a render reads: the field, medium, camera, lights and the structures for
//! motion blur and null-collision tracking ([`Scene`]), and the same with the volume's
//! reconstruction chosen once per render ([`AnyScene`], [`crate::with_scene!`]).

use crate::camera::Camera;
use crate::medium::Medium;
use plume_volume::field::Field;
use plume_volume::trilinear::Trilinear;
use plume_volume::{Interpolation, Volume};

use crate::overlap::volumes::Volumes;

use super::lights::Lights;

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
/// it ran before trilinear existed, and one volume the code it ran before several.
#[derive(Debug)]
pub enum AnyScene {
    /// Piecewise-constant voxels.
    Nearest(Scene<Volume>),
    /// Trilinear reconstruction (METHOD.md §12).
    Linear(Scene<Trilinear>),
    /// Several volumes of piecewise-constant voxels (`overlap`).
    NearestVolumes(Scene<Volumes<Volume>>),
    /// Several volumes reconstructed trilinearly.
    LinearVolumes(Scene<Volumes<Trilinear>>),
}

/// Evaluate `$body` with `$s` bound to the [`Scene`] inside an [`AnyScene`], whichever
/// reconstruction it has.
#[macro_export]
macro_rules! with_scene {
    ($any:expr, $s:ident => $body:expr) => {
        match $any {
            $crate::integrator::scene::AnyScene::Nearest($s) => $body,
            $crate::integrator::scene::AnyScene::Linear($s) => $body,
            $crate::integrator::scene::AnyScene::NearestVolumes($s) => $body,
            $crate::integrator::scene::AnyScene::LinearVolumes($s) => $body,
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
            (several, _) => several,
        }
    }

    /// How the volume is reconstructed.
    #[must_use]
    pub fn interpolation(&self) -> Interpolation {
        match self {
            AnyScene::Nearest(_) | AnyScene::NearestVolumes(_) => Interpolation::Nearest,
            AnyScene::Linear(_) | AnyScene::LinearVolumes(_) => Interpolation::Linear,
        }
    }

    /// The volume's bricks (the first volume's, in a scene of several).
    #[must_use]
    pub fn volume(&self) -> &Volume {
        match self {
            AnyScene::Nearest(s) => &s.field,
            AnyScene::Linear(s) => s.field.volume(),
            AnyScene::NearestVolumes(s) => &s.field.members()[0].field,
            AnyScene::LinearVolumes(s) => s.field.members()[0].field.volume(),
        }
    }

    /// Every volume's bricks, in the scene's order.
    #[must_use]
    pub fn volumes(&self) -> Vec<&Volume> {
        match self {
            AnyScene::Nearest(_) | AnyScene::Linear(_) => vec![self.volume()],
            AnyScene::NearestVolumes(s) => s.field.members().iter().map(|m| &*m.field).collect(),
            AnyScene::LinearVolumes(s) => {
                s.field.members().iter().map(|m| m.field.volume()).collect()
            }
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
            AnyScene::NearestVolumes(s) => &mut s.lights,
            AnyScene::LinearVolumes(s) => &mut s.lights,
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
