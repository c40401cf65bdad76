//! What a render is, as plain data: the [`SceneDescription`] (what is seen: volume and
//! its grids, emission, medium, camera, lights, integrator) and the [`JobSettings`] (how
//! the job runs: samples, seed, threads, frames, crops and sample ranges, outputs,
//! memory, progress). Together they are a [`Shot`], the content of a scene file
//! (`plume render shot.toml`, [`mod@file`]).
//!
//! Everything here is `serde` data with the command line's defaults, and no command-line
//! type: the `plume` binary turns flags into a [`Shot`] in one conversion, `bench` and
//! library callers build one directly. [`Shot::validate`] is the one validation; it
//! returns a [`ValidShot`], which is what renders take, so nothing is checked twice.
//! Errors name the field by its key (`camera.width`); the binary translates keys back to
//! the flags a user typed, or to the scene file's line.
//!
//! **Architecture invariant:** plain data and the rules about it. Nothing here reads a
//! volume, renders, prints or reads the environment; the one IO is reading and writing
//! scene files ([`mod@file`]).

pub mod albedo;
pub mod choice;
pub mod file;
pub mod frames;
pub mod lights;
pub mod pixels;
pub mod placement;
pub mod selector;
pub mod sets;
mod settings;
pub mod split;
pub mod validate;
mod values;

use std::path::PathBuf;

use glam::DVec3;
use serde::{Deserialize, Serialize};

pub use albedo::Albedo;
pub use choice::{
    CameraCollision, Choice, DeferPaths, EmissionSource, EstimatorKind, Interpolation, Method,
    NeeTable, ProgressFormat, Projection, SampleOrderChoice, SamplerKind, TrackingChoice, UpAxis,
};
pub use lights::{
    DistantSettings, EnvironmentMapSettings, LightSettings, SkySettings, SphereSettings,
};
pub use pixels::{Crop, SampleId};
pub use placement::{Placement, Scale, VolumeSpace};
pub use settings::{
    FarmOptions, JobSettings, OutputSettings, ReadSettings, RenderOptions, ADAPTIVE_BLOCK,
};
pub use validate::ValidShot;
pub use values::{parse_bytes, ByteSize, TileIndex};

pub use sets::{
    Collision, Convention, EmissionKind, Estimator, Filtered, LightSampling, MisHeuristic,
    PointLookup, SplitBy, TemperatureMap, Tracking,
};

/// Everything a `plume render` command says: the scene and how the job runs.
///
/// As a scene file it is one table per part: `[volume]`, `[emission]`, `[medium]`,
/// `[camera]`, `[lights]`, `[integrator]` (the scene) and `[render]`, `[farm]`,
/// `[output]`, `[reading]` (the job).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(from = "ShotFile", into = "ShotFile")]
pub struct Shot {
    /// What is rendered.
    pub scene: SceneDescription,
    /// How the job runs.
    pub settings: JobSettings,
}

/// A [`Shot`] as a scene file lays it out: every table at the top level.
#[derive(Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ShotFile {
    volume: VolumeInput,
    #[serde(default)]
    emission: EmissionSettings,
    #[serde(default)]
    medium: MediumSettings,
    #[serde(default)]
    camera: CameraSettings,
    #[serde(default)]
    lights: LightSettings,
    #[serde(default)]
    integrator: IntegratorSettings,
    #[serde(default)]
    render: settings::RenderOptions,
    #[serde(default)]
    farm: settings::FarmOptions,
    // Optional here so that `-o` beside a scene file can give it; validation requires it
    #[serde(default = "settings::OutputSettings::unset")]
    output: OutputSettings,
    #[serde(default)]
    reading: ReadSettings,
}

impl From<ShotFile> for Shot {
    fn from(f: ShotFile) -> Shot {
        let ShotFile {
            volume,
            emission,
            medium,
            camera,
            lights,
            integrator,
            render,
            farm,
            output,
            reading,
        } = f;
        Shot {
            scene: SceneDescription { volume, emission, medium, camera, lights, integrator },
            settings: JobSettings { render, farm, output, reading },
        }
    }
}

impl From<Shot> for ShotFile {
    fn from(s: Shot) -> ShotFile {
        let Shot {
            scene: SceneDescription { volume, emission, medium, camera, lights, integrator },
            settings: JobSettings { render, farm, output, reading },
        } = s;
        ShotFile {
            volume,
            emission,
            medium,
            camera,
            lights,
            integrator,
            render,
            farm,
            output,
            reading,
        }
    }
}

impl Shot {
    /// A shot of `file` to `output` with every other value at its default.
    #[must_use]
    pub fn new(file: impl Into<PathBuf>, output: impl Into<PathBuf>) -> Shot {
        Shot { scene: SceneDescription::new(file), settings: JobSettings::new(output) }
    }
}

/// What is rendered. The volume's file may hold a frame token (`fire.####.vdb`), resolved
/// per frame by the job.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneDescription {
    /// The volume and the grids that make it.
    pub volume: VolumeInput,
    /// What emits and how.
    pub emission: EmissionSettings,
    /// Extinction and scattering.
    pub medium: MediumSettings,
    /// The camera and the image size.
    pub camera: CameraSettings,
    /// Lights besides the volume's own emission.
    pub lights: LightSettings,
    /// Estimators and light sampling.
    pub integrator: IntegratorSettings,
}

impl SceneDescription {
    /// The shutter in seconds relative to the frame: `camera.shutter` (frames) over
    /// `camera.fps`, by default `[-0.25, 0.25]` frames with a velocity grid or an animated
    /// camera; `None` for a still render.
    #[must_use]
    pub fn shutter_seconds(&self) -> Option<[f64; 2]> {
        if self.volume.velocity_grid.is_none() && self.camera.keys.len() < 2 {
            return None;
        }
        let [open, close] = self.camera.shutter.unwrap_or([-0.25, 0.25]);
        Some([open / self.camera.fps, close / self.camera.fps])
    }

    /// The default description of `file`.
    #[must_use]
    pub fn new(file: impl Into<PathBuf>) -> SceneDescription {
        SceneDescription {
            volume: VolumeInput::new(file),
            emission: EmissionSettings::default(),
            medium: MediumSettings::default(),
            camera: CameraSettings::default(),
            lights: LightSettings::default(),
            integrator: IntegratorSettings::default(),
        }
    }

    /// The albedo scale per channel: `medium.albedo`, else 1 with an albedo grid, else 0.
    #[must_use]
    pub fn albedo_rgb(&self) -> [f32; 3] {
        let default = if self.volume.albedo_grid.is_some() { 1.0 } else { 0.0 };
        self.medium.albedo.map_or([default; 3], Albedo::rgb)
    }

    /// The albedo scale's largest channel: paths scatter when it is above 0.
    #[must_use]
    pub fn albedo(&self) -> f32 {
        let [r, g, b] = self.albedo_rgb();
        r.max(g).max(b)
    }

    /// Whether paths scatter (albedo above 0 and at least one bounce).
    #[must_use]
    pub fn scatters(&self) -> bool {
        self.albedo() > 0.0 && self.integrator.max_depth > 0
    }
}

/// The volume file and the grids bound by name (`name[N]` for the N-th of a name).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VolumeInput {
    /// The .vdb file or .plume brick cache; with frames, a pattern with a frame token.
    pub file: PathBuf,
    /// Density grid.
    #[serde(default = "defaults::density_grid")]
    pub density_grid: String,
    /// Temperature grid (blackbody).
    #[serde(default = "defaults::temperature_grid")]
    pub temperature_grid: String,
    /// Emission grid (`emission.source = "grid"`); default: the first of the usual names.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub emission_grid: Option<String>,
    /// Per-voxel albedo grid (values clamped to [0, 1]), times `medium.albedo`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub albedo_grid: Option<String>,
    /// How values are reconstructed between voxel centres.
    #[serde(default)]
    pub interpolation: Interpolation,
    /// Velocity for motion blur (world units per second): the vector grid `NAME`, or three
    /// float grids `NAME.x`, `NAME.y`, `NAME.z`. Motion blur needs it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity_grid: Option<String>,
    /// Multiplies the velocity.
    #[serde(default = "defaults::one", skip_serializing_if = "defaults::is_one")]
    pub velocity_scale: f64,
    /// Placement after the file's own transform (`placement`): translation, world units.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub translate: Option<[f64; 3]>,
    /// XYZ Euler rotation in degrees (Blender's default mode).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rotate: Option<[f64; 3]>,
    /// Scale, one factor or x, y, z.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scale: Option<Scale>,
    /// The placement as a 4×4 affine matrix, rows as written (in place of the three above).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub matrix: Option<[[f64; 4]; 4]>,
    /// Whether coefficients are per world unit or, as Cycles' *Object* space, per unit of
    /// the placed volume.
    #[serde(default, skip_serializing_if = "defaults::is_world")]
    pub space: VolumeSpace,
}

impl VolumeInput {
    /// The default grids of `file`.
    #[must_use]
    pub fn new(file: impl Into<PathBuf>) -> VolumeInput {
        VolumeInput {
            file: file.into(),
            density_grid: defaults::density_grid(),
            temperature_grid: defaults::temperature_grid(),
            emission_grid: None,
            albedo_grid: None,
            interpolation: Interpolation::default(),
            velocity_grid: None,
            velocity_scale: 1.0,
            translate: None,
            rotate: None,
            scale: None,
            matrix: None,
            space: VolumeSpace::World,
        }
    }

    /// The placement keys together (`placement::Placement::transform` makes the map).
    #[must_use]
    pub fn placement(&self) -> Placement {
        Placement {
            translate: self.translate,
            rotate: self.rotate,
            scale: self.scale,
            matrix: self.matrix,
        }
    }
}

/// What emits and how (`medium::Emission` once the source grid is known).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EmissionSettings {
    /// What drives emission.
    pub source: EmissionSource,
    /// Physical, or Blender Cycles' Principled Volume convention.
    pub convention: Convention,
    /// Temperature grid values to Kelvin: `kelvin` or `linear:OFFSET,SCALE`.
    pub temperature_map: String,
    /// Physical blackbody: temperatures below this (Kelvin) emit nothing.
    pub temperature_cutoff: f32,
    /// Emission scale s_e.
    pub scale: f32,
    /// Emission colour (a tint for blackbody), linear Rec.709.
    pub color: [f32; 3],
}

impl Default for EmissionSettings {
    fn default() -> Self {
        EmissionSettings {
            source: EmissionSource::Auto,
            convention: Convention::Physical,
            temperature_map: "kelvin".into(),
            temperature_cutoff: 500.0,
            scale: 1.0,
            color: [1.0; 3],
        }
    }
}

/// Extinction and scattering.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MediumSettings {
    /// σ_t: extinction per world unit (metre) per unit density.
    pub density_scale: f64,
    /// Single-scattering albedo, grey or a colour, in [0, 1]; default 0, or 1 with an
    /// albedo grid. With an absorption colour it is Cycles' Principled Volume *Color*:
    /// the scattering coefficient per unit of `density_scale`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub albedo: Option<Albedo>,
    /// Cycles' Principled Volume *Absorption Color*, grey or a colour, in [0, 1]: with
    /// the albedo `C` it makes the extinction of channel `c`
    /// `σ_t (C_c + (1 − C_c)(1 − √A_c))` per unit density (chromatic where the channels
    /// differ). Default black: grey extinction `σ_t`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub absorption_color: Option<Albedo>,
    /// Henyey–Greenstein asymmetry in (−1, 1).
    pub g: f64,
}

impl Default for MediumSettings {
    fn default() -> Self {
        MediumSettings { density_scale: 1.0, albedo: None, absorption_color: None, g: 0.0 }
    }
}

/// The camera and the image size. Without `from`, the volume is framed automatically.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CameraSettings {
    /// Position (world).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub from: Option<DVec3>,
    /// Point looked at (default: the volume's centre).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub at: Option<DVec3>,
    /// Up vector (default: from `up_axis`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub up: Option<DVec3>,
    /// Horizontal field of view, degrees (unless `focal_length` is given).
    pub fov: f64,
    /// Focal length in millimetres: with `sensor_width`, sets the horizontal field of
    /// view, `2 atan(sensor_width / (2 focal_length))`, in place of `fov`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub focal_length: Option<f64>,
    /// Sensor width in millimetres (default 36, full frame, as Cycles).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sensor_width: Option<f64>,
    /// Depth of field: the f-number, with `focal_length` (aperture radius
    /// `focal_length / (2 fstop)`, the millimetres taken as thousandths of a world unit).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fstop: Option<f64>,
    /// Depth of field: the lens aperture's radius in world units (in place of `fstop`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub aperture_radius: Option<f64>,
    /// Distance in focus, world units along the view direction (default: to `at`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub focus_distance: Option<f64>,
    /// Perspective (default) or orthographic.
    #[serde(skip_serializing_if = "is_perspective")]
    pub projection: Projection,
    /// Orthographic: the image's width in world units (default: frames the volume).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ortho_width: Option<f64>,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Up axis of automatic framing and of the default `up`.
    pub up_axis: UpAxis,
    /// Shutter open and close in frames relative to the frame (default `[-0.25, 0.25]`
    /// with a velocity grid, none without).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shutter: Option<[f64; 2]>,
    /// Frames per second: converts the shutter to seconds.
    pub fps: f64,
    /// A camera animated over frames: placements at frames, linear between them (and
    /// within each frame's shutter). Replaces `from`, `at`, `up` and `fov` when given.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub keys: Vec<CameraKey>,
}

/// Default sensor width in millimetres (full frame; Cycles' default).
pub const DEFAULT_SENSOR_WIDTH_MM: f64 = 36.0;

fn is_perspective(p: &Projection) -> bool {
    *p == Projection::Perspective
}

impl CameraSettings {
    /// The horizontal field of view in degrees: from `focal_length` and `sensor_width`
    /// when a focal length is given, else `fov`.
    #[must_use]
    pub fn horizontal_fov(&self) -> f64 {
        match self.focal_length {
            Some(f) => {
                let sensor = self.sensor_width.unwrap_or(DEFAULT_SENSOR_WIDTH_MM);
                2.0 * (sensor / (2.0 * f)).atan().to_degrees()
            }
            None => self.fov,
        }
    }

    /// The thin lens's aperture radius in world units: `aperture_radius`, or from `fstop`
    /// and `focal_length` (millimetres as thousandths of a world unit); 0 for a pinhole.
    #[must_use]
    pub fn lens_radius(&self) -> f64 {
        match (self.aperture_radius, self.fstop, self.focal_length) {
            (Some(r), _, _) => r,
            (None, Some(n), Some(f)) => f / 1000.0 / (2.0 * n),
            _ => 0.0,
        }
    }
}

/// One key of an animated camera (`[[camera.keys]]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraKey {
    /// The frame it holds at.
    pub frame: f64,
    /// Position.
    pub from: DVec3,
    /// Point looked at.
    pub at: DVec3,
    /// Up hint (default: from `up_axis`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub up: Option<DVec3>,
    /// Horizontal field of view, degrees (default: `camera.fov`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fov: Option<f64>,
}

impl Default for CameraSettings {
    fn default() -> Self {
        CameraSettings {
            from: None,
            at: None,
            up: None,
            fov: 40.0,
            focal_length: None,
            sensor_width: None,
            fstop: None,
            aperture_radius: None,
            focus_distance: None,
            projection: Projection::Perspective,
            ortho_width: None,
            width: 640,
            height: 480,
            up_axis: UpAxis::Y,
            shutter: None,
            fps: 24.0,
            keys: Vec::new(),
        }
    }
}

/// Estimators and light sampling.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct IntegratorSettings {
    /// Preset of estimator + light sampling.
    pub method: Method,
    /// Overrides the preset's estimator.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub estimator: Option<EstimatorKind>,
    /// The camera segment's estimator (default: ray-march where paths scatter, else
    /// `estimator`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub camera_estimator: Option<EstimatorKind>,
    /// How a camera ray's collision is drawn when paths scatter.
    pub camera_collision: CameraCollision,
    /// Overrides the preset's light sampling.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub light_sampling: Option<LightSampling>,
    /// MIS heuristic between forward sampling and NEE/FNEE.
    pub mis: MisHeuristic,
    /// FNEE proxy resolution (power of two); default 64 or the data resolution.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub proxy_resolution: Option<u32>,
    /// Largest number of scattering events per path.
    pub max_depth: u32,
    /// κ of the blend estimator.
    pub kappa: f64,
    /// How segments are tracked (`integrator::tracker`).
    pub tracking: TrackingChoice,
    /// Resolution of classic NEE's table.
    #[serde(skip_serializing_if = "NeeTable::is_voxel")]
    pub nee_table: NeeTable,
    /// Paths traced from each collision of a camera ray, each carrying `1/split`.
    pub split: u32,
    /// Whether `split` holds everywhere or is the mean of per-pixel counts.
    #[serde(skip_serializing_if = "SplitBy::is_uniform")]
    pub split_by: SplitBy,
    /// How null collisions read a trilinear volume at tentative points.
    pub point_lookup: PointLookup,
}

impl Default for IntegratorSettings {
    fn default() -> Self {
        IntegratorSettings {
            method: Method::LineFnee,
            estimator: None,
            camera_estimator: None,
            camera_collision: CameraCollision::Forced,
            light_sampling: None,
            mis: MisHeuristic::Power,
            proxy_resolution: None,
            max_depth: 64,
            kappa: 4.0,
            tracking: TrackingChoice::Auto,
            nee_table: NeeTable::Voxel,
            split: 8,
            split_by: SplitBy::Uniform,
            point_lookup: PointLookup::Stochastic,
        }
    }
}

impl IntegratorSettings {
    /// The estimator and light sampling: the preset's, overridden by `estimator` and
    /// `light_sampling`.
    #[must_use]
    pub fn parts(&self) -> (Estimator, LightSampling) {
        let (estimator, light_sampling) = self.method.parts();
        (
            self.estimator.unwrap_or(estimator).with_kappa(self.kappa),
            self.light_sampling.unwrap_or(light_sampling),
        )
    }
}

/// Defaults that serde needs as functions.
mod defaults {
    pub fn is_world(space: &super::VolumeSpace) -> bool {
        *space == super::VolumeSpace::World
    }

    pub(super) fn density_grid() -> String {
        "density".into()
    }
    pub(super) fn temperature_grid() -> String {
        "temperature".into()
    }
    pub(super) fn one() -> f64 {
        1.0
    }
    #[allow(clippy::trivially_copy_pass_by_ref)] // serde's signature
    pub(super) fn is_one(v: &f64) -> bool {
        *v == 1.0
    }
}
