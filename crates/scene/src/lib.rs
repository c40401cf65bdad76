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
pub mod several_volumes;
pub mod split;
pub mod validate;
mod values;
pub mod volumes;

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
pub use volumes::{
    EmissionSettings, EntryRef, MediumSettings, VolumeEntry, VolumeEntryKeys, VolumeInput,
};

pub use sets::{
    Collision, Convention, EmissionKind, Estimator, Filtered, LightSampling, MisHeuristic,
    PointLookup, SplitBy, TemperatureMap, Tracking,
};

/// Everything a `plume render` command says: the scene and how the job runs.
///
/// As a scene file it is one table per part: `[volume]` (or a list of `[[volumes]]`),
/// `[emission]`, `[medium]`, `[camera]`, `[lights]`, `[integrator]` (the scene) and
/// `[render]`, `[farm]`, `[output]`, `[reading]` (the job).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "ShotFile", into = "ShotFile")]
pub struct Shot {
    /// What is rendered.
    pub scene: SceneDescription,
    /// How the job runs.
    pub settings: JobSettings,
}

/// A [`Shot`] as a scene file lays it out: every table at the top level. One volume is
/// `volume` with the top-level `emission` and `medium`; several are `volumes`, whose
/// entries take the emission and medium keys they leave out from the top-level tables.
#[derive(Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ShotFile {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    volume: Option<VolumeInput>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    volumes: Option<Vec<VolumeEntryKeys>>,
    // A list written out gives every entry's emission and medium whole: no top-level tables
    #[serde(default, skip_serializing_if = "Option::is_none")]
    emission: Option<EmissionSettings>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    medium: Option<MediumSettings>,
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

/// What a scene file's volume tables say that no scene can be, given whether it has
/// `[volume]` and how many `[[volumes]]` entries: `(key, message)`.
pub(crate) fn volume_tables_error(
    volume: bool,
    volumes: Option<usize>,
) -> Option<(&'static str, &'static str)> {
    match (volume, volumes) {
        (true, Some(_)) => {
            Some(("volumes", "give one volume as [volume] or a list as [[volumes]], not both"))
        }
        (false, Some(0)) => Some(("volumes", "is empty: give at least one [[volumes]] entry")),
        _ => None,
    }
}

impl TryFrom<ShotFile> for Shot {
    type Error = String;

    fn try_from(f: ShotFile) -> Result<Shot, String> {
        let ShotFile {
            volume,
            volumes,
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
        if volume.is_none() && volumes.is_none() {
            // As serde says it of any other required key
            return Err("missing field `volume`".into());
        }
        let count = volumes.as_ref().map(Vec::len);
        if let Some((key, message)) = volume_tables_error(volume.is_some(), count) {
            return Err(format!("key `{key}`: {message}"));
        }
        let (emission, medium) = (emission.unwrap_or_default(), medium.unwrap_or_default());
        let (first, more_volumes, listed) = match (volume, volumes) {
            (Some(volume), _) => (VolumeEntry { volume, emission, medium }, Vec::new(), false),
            (None, list) => {
                let list = list.unwrap_or_default();
                let mut entries = list.iter().map(|e| e.resolve(&emission, &medium));
                let first = entries.next().expect("invariant: checked to be non-empty");
                (first, entries.collect(), true)
            }
        };
        let VolumeEntry { volume, emission, medium } = first;
        Ok(Shot {
            scene: SceneDescription {
                volume,
                emission,
                medium,
                more_volumes,
                listed,
                camera,
                lights,
                integrator,
            },
            settings: JobSettings { render, farm, output, reading },
        })
    }
}

impl From<Shot> for ShotFile {
    fn from(s: Shot) -> ShotFile {
        let Shot {
            scene:
                SceneDescription {
                    volume,
                    emission,
                    medium,
                    more_volumes,
                    listed,
                    camera,
                    lights,
                    integrator,
                },
            settings: JobSettings { render, farm, output, reading },
        } = s;
        let (volume, volumes, emission, medium) = if listed || !more_volumes.is_empty() {
            let first = VolumeEntry { volume, emission, medium };
            let list = std::iter::once(&first).chain(&more_volumes).map(VolumeEntryKeys::written);
            (None, Some(list.collect()), None, None)
        } else {
            (Some(volume), None, Some(emission), Some(medium))
        };
        ShotFile {
            volume,
            volumes,
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

/// What is rendered: one volume or several, the camera, lights and method. A volume's
/// file may hold a frame token (`fire.####.vdb`), resolved per frame by the job.
///
/// The first volume is `volume`, `emission` and `medium`; the 2nd, 3rd, … are
/// `more_volumes` ([`entries`](SceneDescription::entries) gives them all alike). Any of
/// them may appear several times (`VolumeInput::instances`).
#[derive(Clone, Debug, PartialEq)]
pub struct SceneDescription {
    /// The (first) volume and the grids that make it.
    pub volume: VolumeInput,
    /// What the (first) volume emits and how.
    pub emission: EmissionSettings,
    /// The (first) volume's extinction and scattering.
    pub medium: MediumSettings,
    /// The 2nd, 3rd, … volumes (`[[volumes]]` after the first, `--add-volume`).
    pub more_volumes: Vec<VolumeEntry>,
    /// Whether the volumes were given as a list (`[[volumes]]`), even of one: the first
    /// volume's keys are then `volumes[0].…` ([`EntryRef::key`]), and a scene file written
    /// from it lists them again.
    pub listed: bool,
    /// The camera and the image size.
    pub camera: CameraSettings,
    /// Lights besides the volumes' own emission.
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
            more_volumes: Vec::new(),
            listed: false,
            camera: CameraSettings::default(),
            lights: LightSettings::default(),
            integrator: IntegratorSettings::default(),
        }
    }

    /// How many volumes the scene has: 1 and the further ones (entries, not instances:
    /// [`placed_volume_count`](SceneDescription::placed_volume_count)).
    #[must_use]
    pub fn volume_count(&self) -> usize {
        1 + self.more_volumes.len()
    }

    /// How many volumes the scene places in the world: each entry once, or once per
    /// instance.
    #[must_use]
    pub fn placed_volume_count(&self) -> usize {
        self.volume.placed_count()
            + self.more_volumes.iter().map(|e| e.volume.placed_count()).sum::<usize>()
    }

    /// Whether the scene renders as several volumes: more than one entry, or any volume
    /// with `instances` (even one instance of one volume). What several volumes cannot do
    /// yet is refused for it (`several_volumes`), and it is loaded as several.
    #[must_use]
    pub fn is_several(&self) -> bool {
        !self.more_volumes.is_empty() || self.volume.instances.is_some()
    }

    /// Every volume in order, the first included, each with the prefix of its keys:
    /// `volume` for one volume given as `[volume]`, else `volumes[0]`, `volumes[1]`, …
    #[must_use]
    pub fn entries(&self) -> Vec<EntryRef<'_>> {
        let first = EntryRef {
            index: 0,
            prefix: if self.listed { "volumes[0]" } else { "volume" }.to_string(),
            volume: &self.volume,
            emission: &self.emission,
            medium: &self.medium,
        };
        let more = self.more_volumes.iter().enumerate().map(|(i, e)| EntryRef {
            index: i + 1,
            prefix: format!("volumes[{}]", i + 1),
            volume: &e.volume,
            emission: &e.emission,
            medium: &e.medium,
        });
        std::iter::once(first).chain(more).collect()
    }

    /// The first volume's albedo scale per channel: `medium.albedo`, else 1 with an
    /// albedo grid, else 0 (each volume's: [`EntryRef::albedo_rgb`]).
    #[must_use]
    pub fn albedo_rgb(&self) -> [f32; 3] {
        volumes::albedo_rgb(&self.volume, &self.medium)
    }

    /// The first volume's albedo scale's largest channel (each volume's:
    /// [`EntryRef::albedo`]).
    #[must_use]
    pub fn albedo(&self) -> f32 {
        let [r, g, b] = self.albedo_rgb();
        r.max(g).max(b)
    }

    /// The AOV layers of light groups, in order: the lights' groups
    /// ([`LightSettings::groups`]), then the volumes' groups not among them. A volume and a
    /// light of the same group share its layer.
    #[must_use]
    pub fn aov_groups(&self) -> Vec<String> {
        let mut groups = self.lights.groups();
        for g in self.entries().iter().filter_map(|e| e.volume.group.clone()) {
            if !groups.contains(&g) {
                groups.push(g);
            }
        }
        groups
    }

    /// Whether paths scatter: an albedo above 0 in any volume, and at least one bounce.
    #[must_use]
    pub fn scatters(&self) -> bool {
        self.integrator.max_depth > 0 && self.entries().iter().any(|e| e.albedo() > 0.0)
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

#[cfg(test)]
mod tests;
