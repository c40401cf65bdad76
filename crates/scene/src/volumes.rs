//! The volumes of a scene: each one's input ([`VolumeInput`]: file, grids, placement), what
//! it emits ([`EmissionSettings`]) and its medium ([`MediumSettings`]).
//!
//! A scene has one volume or several. The first is `SceneDescription::volume`, `emission`
//! and `medium`; the 2nd, 3rd, … are `SceneDescription::more_volumes`, one [`VolumeEntry`]
//! each. `SceneDescription::entries` gives them all alike, as [`EntryRef`]s that also know
//! the keys that name their fields in errors ([`EntryRef::key`]).
//!
//! A scene file gives one volume as `[volume]`, `[emission]`, `[medium]`, or a list of
//! `[[volumes]]`, each entry with the keys of `[volume]` and optional `emission` and
//! `medium` sub-tables ([`VolumeEntryKeys`]). An entry's emission and medium keys that it
//! leaves out are the top-level `[emission]` and `[medium]` values (themselves defaulted).
//!
//! **Instances.** A volume (`[volume]`, an entry, `--add-volume`) may give `instances`, a
//! list of placements ([`Placement`]): the volume then appears once per instance, placed
//! by the instance after its own placement (`world = M_instance · M · world_file`), and
//! not at its own placement alone. Its data are read once and shared. A scene with
//! instances renders as one of several volumes ([`crate::SceneDescription::is_several`]).
//!
//! **Leaf:** nothing here imports the crate's root; the root's `SceneDescription` and
//! `Shot` build on these types.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::albedo::Albedo;
use crate::choice::{EmissionSource, Interpolation};
use crate::placement::{Placement, Scale, VolumeSpace};
use crate::sets::Convention;

/// The volume file and the grids bound by name (`name[N]` for the N-th of a name), its
/// placement, and how the camera and shadows see it.
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
    /// The volume's name (letters, digits, `_` and `-`), kept with the scene as a label;
    /// it does not change the render.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// The light group (AOV layer) of the volume's emission, seen directly and scattered;
    /// `None`: the `emission` and `scattered` layers.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub group: Option<String>,
    /// Whether camera rays see the volume (its emission and extinction); when not, only
    /// light scattered or shadowed by it is seen.
    #[serde(default = "defaults::yes", skip_serializing_if = "defaults::is_yes")]
    pub visible_to_camera: bool,
    /// Whether the volume's extinction shadows light sampled towards scattering points.
    #[serde(default = "defaults::yes", skip_serializing_if = "defaults::is_yes")]
    pub casts_shadows: bool,
    /// Where the volume appears: once per placement, each applied after the volume's own
    /// (`world = M_instance · M · world_file`), its data shared. `None`: once, at its own
    /// placement. An empty list is refused.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub instances: Option<Vec<Placement>>,
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
            name: None,
            group: None,
            visible_to_camera: true,
            casts_shadows: true,
            instances: None,
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

    /// How many times the volume appears: once per instance, or once without `instances`.
    #[must_use]
    pub fn placed_count(&self) -> usize {
        self.instances.as_ref().map_or(1, Vec::len)
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

/// The 2nd, 3rd, … volume of a scene: its input, emission and medium.
#[derive(Clone, Debug, PartialEq)]
pub struct VolumeEntry {
    /// The file, grids and placement.
    pub volume: VolumeInput,
    /// What emits and how.
    pub emission: EmissionSettings,
    /// Extinction and scattering.
    pub medium: MediumSettings,
}

impl VolumeEntry {
    /// The default grids, emission and medium of `file`.
    #[must_use]
    pub fn new(file: impl Into<PathBuf>) -> VolumeEntry {
        VolumeEntry {
            volume: VolumeInput::new(file),
            emission: EmissionSettings::default(),
            medium: MediumSettings::default(),
        }
    }
}

/// One volume of a scene, the first or a further one, with the keys that name it
/// (`SceneDescription::entries`).
#[derive(Clone, Debug, PartialEq)]
pub struct EntryRef<'a> {
    /// 0 for the first volume, 1 for `more_volumes[0]`, …
    pub index: usize,
    /// `volume` for a scene's one volume given as `[volume]`, else `volumes[INDEX]`.
    pub prefix: String,
    /// The file, grids and placement.
    pub volume: &'a VolumeInput,
    /// What emits and how.
    pub emission: &'a EmissionSettings,
    /// Extinction and scattering.
    pub medium: &'a MediumSettings,
}

impl EntryRef<'_> {
    /// The full key of `field`, a key of `[volume]` (`density_grid`, `matrix`) or of the
    /// emission or medium (`emission.scale`, `medium.g`; `emission` or `medium` for the
    /// whole table).
    ///
    /// Given as `[volume]` (prefix `volume`), emission and medium are top-level tables:
    /// `volume.density_grid`, `emission.scale`, `medium.g`. In a list every key is inside
    /// the entry: `volumes[1].density_grid`, `volumes[1].emission.scale`,
    /// `volumes[1].medium.g`.
    #[must_use]
    pub fn key(&self, field: &str) -> String {
        key(&self.prefix, field)
    }

    /// The albedo scale per channel: `medium.albedo`, else 1 with an albedo grid, else 0.
    #[must_use]
    pub fn albedo_rgb(&self) -> [f32; 3] {
        albedo_rgb(self.volume, self.medium)
    }

    /// The albedo scale's largest channel: paths scatter in this volume when it is above 0.
    #[must_use]
    pub fn albedo(&self) -> f32 {
        let [r, g, b] = self.albedo_rgb();
        r.max(g).max(b)
    }
}

/// The full key of `field` of the volume whose keys start with `prefix`: `volume` (one
/// volume given as `[volume]`) or `volumes[INDEX]`. See [`EntryRef::key`].
#[must_use]
pub fn key(prefix: &str, field: &str) -> String {
    let table = field.split('.').next().unwrap_or(field);
    if prefix == "volume" && (table == "emission" || table == "medium") {
        field.to_string()
    } else {
        format!("{prefix}.{field}")
    }
}

/// The albedo scale per channel of a volume with `medium`: `medium.albedo`, else 1 with
/// an albedo grid, else 0.
#[must_use]
pub fn albedo_rgb(volume: &VolumeInput, medium: &MediumSettings) -> [f32; 3] {
    let default = if volume.albedo_grid.is_some() { 1.0 } else { 0.0 };
    medium.albedo.map_or([default; 3], Albedo::rgb)
}

/// A `[[volumes]]` entry as a scene file (or `--add-volume`) writes it: the keys of
/// `[volume]`, and the `emission` and `medium` keys it gives; [`VolumeEntryKeys::resolve`]
/// takes the others from the top-level tables.
///
/// The fields repeat [`VolumeInput`]'s, serde attributes included, because serde cannot
/// flatten a table into a struct that refuses unknown keys; the conversions both ways
/// take every field by name, so a field added to one and not the other does not compile.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VolumeEntryKeys {
    file: PathBuf,
    #[serde(default = "defaults::density_grid")]
    density_grid: String,
    #[serde(default = "defaults::temperature_grid")]
    temperature_grid: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    emission_grid: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    albedo_grid: Option<String>,
    #[serde(default)]
    interpolation: Interpolation,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    velocity_grid: Option<String>,
    #[serde(default = "defaults::one", skip_serializing_if = "defaults::is_one")]
    velocity_scale: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    translate: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    rotate: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    scale: Option<Scale>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    matrix: Option<[[f64; 4]; 4]>,
    #[serde(default, skip_serializing_if = "defaults::is_world")]
    space: VolumeSpace,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    name: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    group: Option<String>,
    #[serde(default = "defaults::yes", skip_serializing_if = "defaults::is_yes")]
    visible_to_camera: bool,
    #[serde(default = "defaults::yes", skip_serializing_if = "defaults::is_yes")]
    casts_shadows: bool,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    instances: Option<Vec<Placement>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    emission: Option<EmissionKeys>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    medium: Option<MediumKeys>,
}

impl VolumeEntryKeys {
    /// The entry, its emission and medium keys over `emission` and `medium` (the keys it
    /// leaves out take their values).
    #[must_use]
    pub fn resolve(&self, emission: &EmissionSettings, medium: &MediumSettings) -> VolumeEntry {
        let VolumeEntryKeys {
            file,
            density_grid,
            temperature_grid,
            emission_grid,
            albedo_grid,
            interpolation,
            velocity_grid,
            velocity_scale,
            translate,
            rotate,
            scale,
            matrix,
            space,
            name,
            group,
            visible_to_camera,
            casts_shadows,
            instances,
            emission: own_emission,
            medium: own_medium,
        } = self.clone();
        VolumeEntry {
            volume: VolumeInput {
                file,
                density_grid,
                temperature_grid,
                emission_grid,
                albedo_grid,
                interpolation,
                velocity_grid,
                velocity_scale,
                translate,
                rotate,
                scale,
                matrix,
                space,
                name,
                group,
                visible_to_camera,
                casts_shadows,
                instances,
            },
            emission: own_emission.unwrap_or_default().over(emission),
            medium: own_medium.unwrap_or_default().over(medium),
        }
    }

    /// `entry` with every emission and medium key written out, so that it reads back the
    /// same whatever the top-level tables hold (an albedo or absorption colour left out
    /// stays out: a file written so has no top-level `[medium]` to inherit one from).
    #[must_use]
    pub(crate) fn written(entry: &VolumeEntry) -> VolumeEntryKeys {
        let VolumeInput {
            file,
            density_grid,
            temperature_grid,
            emission_grid,
            albedo_grid,
            interpolation,
            velocity_grid,
            velocity_scale,
            translate,
            rotate,
            scale,
            matrix,
            space,
            name,
            group,
            visible_to_camera,
            casts_shadows,
            instances,
        } = entry.volume.clone();
        VolumeEntryKeys {
            file,
            density_grid,
            temperature_grid,
            emission_grid,
            albedo_grid,
            interpolation,
            velocity_grid,
            velocity_scale,
            translate,
            rotate,
            scale,
            matrix,
            space,
            name,
            group,
            visible_to_camera,
            casts_shadows,
            instances,
            emission: Some(EmissionKeys::all(&entry.emission)),
            medium: Some(MediumKeys::all(&entry.medium)),
        }
    }

    /// The volume file.
    #[must_use]
    pub fn file(&self) -> &std::path::Path {
        &self.file
    }
}

/// The keys of `[emission]` an entry gives.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct EmissionKeys {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    source: Option<EmissionSource>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    convention: Option<Convention>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    temperature_map: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    temperature_cutoff: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    scale: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    color: Option<[f32; 3]>,
}

impl EmissionKeys {
    /// These keys over `base`.
    fn over(self, base: &EmissionSettings) -> EmissionSettings {
        let EmissionKeys { source, convention, temperature_map, temperature_cutoff, scale, color } =
            self;
        EmissionSettings {
            source: source.unwrap_or(base.source),
            convention: convention.unwrap_or(base.convention),
            temperature_map: temperature_map.unwrap_or_else(|| base.temperature_map.clone()),
            temperature_cutoff: temperature_cutoff.unwrap_or(base.temperature_cutoff),
            scale: scale.unwrap_or(base.scale),
            color: color.unwrap_or(base.color),
        }
    }

    /// Every key of `e`.
    fn all(e: &EmissionSettings) -> EmissionKeys {
        let EmissionSettings {
            source,
            convention,
            temperature_map,
            temperature_cutoff,
            scale,
            color,
        } = e.clone();
        EmissionKeys {
            source: Some(source),
            convention: Some(convention),
            temperature_map: Some(temperature_map),
            temperature_cutoff: Some(temperature_cutoff),
            scale: Some(scale),
            color: Some(color),
        }
    }
}

/// The keys of `[medium]` an entry gives.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct MediumKeys {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    density_scale: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    albedo: Option<Albedo>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    absorption_color: Option<Albedo>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    g: Option<f64>,
}

impl MediumKeys {
    /// These keys over `base`.
    fn over(self, base: &MediumSettings) -> MediumSettings {
        let MediumKeys { density_scale, albedo, absorption_color, g } = self;
        MediumSettings {
            density_scale: density_scale.unwrap_or(base.density_scale),
            albedo: albedo.or(base.albedo),
            absorption_color: absorption_color.or(base.absorption_color),
            g: g.unwrap_or(base.g),
        }
    }

    /// Every key of `m` (the albedo and absorption colour where given).
    fn all(m: &MediumSettings) -> MediumKeys {
        let MediumSettings { density_scale, albedo, absorption_color, g } = *m;
        MediumKeys { density_scale: Some(density_scale), albedo, absorption_color, g: Some(g) }
    }
}

/// Defaults that serde needs as functions.
mod defaults {
    pub(super) fn is_world(space: &super::VolumeSpace) -> bool {
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
    pub(super) fn yes() -> bool {
        true
    }
    #[allow(clippy::trivially_copy_pass_by_ref)] // serde's signature
    pub(super) fn is_yes(v: &bool) -> bool {
        *v
    }
}
