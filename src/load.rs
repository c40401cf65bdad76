//! A scene description turned into a loaded scene, in one pass: the volume (read in
//! core from a .vdb, mapped from a `.plume` brick cache, or through an automatic cache
//! for a .vdb too large for the memory budget), the medium and emission, the camera, and
//! the light-sampling structures the integrator needs.
//!
//! ```text
//! SceneDescription + input path + JobSettings
//!   ├─ .plume           → cache::Cache::open → checks against the description
//!   ├─ .vdb, large      → cache::convert::auto_cache (converted once) → same checks
//!   └─ .vdb             → vdb reader (isolated) → Volume::build_with_albedo
//!   → Medium, Camera (given or framed), Lights (NEE table or FNEE proxy) → Scene
//! ```

use std::path::Path;
use std::time::Duration;

use glam::DVec3;

use crate::cache::CacheCheck;
use crate::camera::Camera;
use crate::color::Rgb;
use crate::error::{Error, Result};
use crate::integrator::{LightSampling, Lights, Scene};
use crate::medium::{Emission, EmissionKind, Medium};
use crate::scene::validate::selector;
use crate::scene::{EmissionSettings, EmissionSource, JobSettings, ReadSettings, SceneDescription, UpAxis, VolumeInput};
use crate::vdb::{GridRequest, GridSelector, ReadIsolation, ReadLimits};
use crate::volume::proxy::{CellPower, ProxyGrid};
use crate::volume::{Field, Volume};

/// Emission grid names tried, in order, by `emission.source = "auto"` and by `"grid"`
/// without `volume.emission_grid`.
pub const EMISSION_GRID_CANDIDATES: [&str; 4] = ["emission", "flame", "heat", "flame_noise"];

/// Bytes per GiB, for messages.
pub(crate) const GIB: f64 = 1024.0 * 1024.0 * 1024.0;

/// A scene ready to render, and what the outputs report about how it was loaded.
pub struct LoadedScene {
    /// The scene.
    pub scene: Scene<Volume>,
    /// Emission kind actually used (after `auto`).
    pub emission_kind: EmissionKind,
    /// Name of the source grid used, if any.
    pub source_grid: Option<String>,
    /// When the volume is mapped from a brick cache: its background checksum check, which
    /// must pass before any output is written ([`CacheCheck::verified`]).
    pub cache: Option<CacheCheck>,
}

/// The grids a volume is built from, as read requests: density, then the source
/// (temperature or emission grid, per `emission.source`; none for `none`), then the
/// albedo grid if any. See [`split_found`].
///
/// # Errors
/// A selector that does not parse.
pub(crate) fn grid_requests(volume: &VolumeInput, source: EmissionSource) -> Result<Vec<GridRequest>> {
    let candidates = || -> Result<Vec<GridSelector>> {
        EMISSION_GRID_CANDIDATES.iter().map(|n| selector("volume.emission_grid", n)).collect()
    };
    let temperature = selector("volume.temperature_grid", &volume.temperature_grid)?;
    let mut requests = vec![GridRequest::required(selector("volume.density_grid", &volume.density_grid)?)];
    match source {
        EmissionSource::None => {}
        EmissionSource::Blackbody => requests.push(GridRequest::required(temperature)),
        EmissionSource::Grid => {
            let alternatives = match &volume.emission_grid {
                Some(n) => vec![selector("volume.emission_grid", n)?],
                None => candidates()?,
            };
            requests.push(GridRequest { alternatives, required: true });
        }
        EmissionSource::Auto => {
            let alternatives = std::iter::once(temperature).chain(candidates()?).collect();
            requests.push(GridRequest { alternatives, required: false });
        }
    }
    if let Some(name) = &volume.albedo_grid {
        requests.push(GridRequest::required(selector("volume.albedo_grid", name)?));
    }
    Ok(requests)
}

/// The grids [`grid_requests`] read, by role.
pub(crate) struct FoundGrids<G> {
    /// The density grid.
    pub density: G,
    /// The source grid, if emission has one.
    pub source: Option<G>,
    /// The albedo grid, if asked for.
    pub albedo: Option<G>,
}

/// Sort what [`grid_requests`] found into roles.
pub(crate) fn split_found<G>(source: EmissionSource, found: Vec<Option<G>>) -> FoundGrids<G> {
    let mut found = found.into_iter();
    let density = found.next().flatten().expect("invariant: the density request is required");
    let source = if source == EmissionSource::None { None } else { found.next().flatten() };
    let albedo = found.next().flatten();
    FoundGrids { density, source, albedo }
}

/// The emission kind `source` resolves to, given which source alternative was found.
#[must_use]
pub fn emission_kind(source: EmissionSource, found_alternative: Option<usize>) -> EmissionKind {
    match (source, found_alternative) {
        (EmissionSource::None, _) | (EmissionSource::Auto, None) => EmissionKind::None,
        (EmissionSource::Blackbody, _) => EmissionKind::Blackbody,
        (EmissionSource::Grid, _) => EmissionKind::Grid,
        (EmissionSource::Auto, Some(0)) => EmissionKind::Blackbody,
        (EmissionSource::Auto, Some(_)) => EmissionKind::Grid,
    }
}

/// The emission model of `settings` for `kind`.
///
/// # Errors
/// An unparsable `emission.temperature_map`.
pub fn emission_model(settings: &EmissionSettings, kind: EmissionKind) -> Result<Emission> {
    Ok(Emission {
        kind,
        convention: settings.convention,
        scale: settings.scale,
        color: Rgb(settings.color),
        temperature_map: settings.temperature_map.parse()?,
        cutoff_kelvin: settings.temperature_cutoff,
    })
}

/// The emission model at unit scale and white colour: what brick caches and light power
/// are built with (both are independent of scale and tint).
///
/// # Errors
/// As [`emission_model`].
pub fn unit_emission_model(settings: &EmissionSettings, kind: EmissionKind) -> Result<Emission> {
    emission_model(&EmissionSettings { scale: 1.0, color: [1.0; 3], ..settings.clone() }, kind)
}

/// Read limits and reader isolation of `reading`.
///
/// # Errors
/// A read timeout that is not a positive number of seconds.
pub fn reader(reading: &ReadSettings) -> Result<(ReadLimits, ReadIsolation)> {
    let limits = ReadLimits { max_bytes: reading.max_input_memory.map_or(ReadLimits::default().max_bytes, |b| b.0) };
    let timeout = Duration::try_from_secs_f64(reading.read_timeout)
        .ok()
        .filter(|t| !t.is_zero())
        .ok_or_else(|| Error::invalid("reading.read_timeout", format!("{} is not a positive number of seconds", reading.read_timeout)))?;
    Ok((limits, ReadIsolation::from_flags(reading.no_isolation, &limits, timeout)))
}

/// The memory budget: `render.memory_budget`, or half of physical memory.
#[must_use]
pub fn memory_budget(settings: &JobSettings) -> u64 {
    settings.render.memory_budget.map_or_else(|| ReadLimits::default().max_bytes, |b| b.0)
}

/// The volume of a render and what it was built with.
struct LoadedVolume {
    volume: Volume,
    emission: Emission,
    source_grid: Option<String>,
    /// From a cache: the stored proxy power and its key.
    proxy_power: Option<(CellPower, String)>,
    cache: Option<CacheCheck>,
}

/// Read a .vdb's grids into memory and build the volume.
fn load_vdb(scene: &SceneDescription, input: &Path, settings: &JobSettings) -> Result<LoadedVolume> {
    let (limits, isolation) = reader(&settings.reading)?;
    let requests = grid_requests(&scene.volume, scene.emission.source)?;
    let found = isolation.read_grids(input, &requests, &limits)?;
    let grids = split_found(scene.emission.source, found);
    let kind = emission_kind(scene.emission.source, grids.source.as_ref().map(|f| f.alternative));
    let emission = emission_model(&scene.emission, kind)?;
    let source = grids.source.map(|f| f.grid);
    let albedo = grids.albedo.map(|f| f.grid);
    let volume = Volume::build_with_albedo(&grids.density.grid, source.as_ref(), |v| emission.map_source(v), albedo.as_ref())?;
    Ok(LoadedVolume { volume, emission, source_grid: source.map(|g| g.name), proxy_power: None, cache: None })
}

/// Check a brick cache against the description and take its volume.
fn load_cache(scene: &SceneDescription, cache: crate::cache::Cache) -> Result<LoadedVolume> {
    let kind = crate::cache::convert::check_description(&cache, &scene.volume, scene.emission.source)?;
    let emission = emission_model(&scene.emission, kind)?;
    crate::cache::convert::check_source_key(&cache, &emission)?;
    crate::cache::convert::check_not_stale(&cache)?;
    let proxy_power = cache.proxy_power.zip(cache.meta.proxy.map(|p| p.power_key));
    Ok(LoadedVolume { volume: cache.volume, emission, source_grid: cache.meta.source_grid, proxy_power, cache: Some(cache.check) })
}

/// Load `input` (the description's volume file, its frame token resolved) as
/// `scene` describes it, and build the scene: volume, medium, camera, lights.
///
/// A `.plume` input is mapped; a `.vdb` larger than a quarter of the memory budget goes
/// through an automatic brick cache (`cache::convert`); any other is read into memory.
///
/// # Errors
/// Missing or unreadable file or grid, invalid values, incompatible grids, a stale or
/// damaged cache, or light-sampling tables beyond the memory budget.
pub fn load_scene(scene: &SceneDescription, input: &Path, settings: &JobSettings) -> Result<LoadedScene> {
    // Mapping values are checked before any reading
    emission_model(&scene.emission, EmissionKind::None)?;
    let loaded = if crate::cache::is_cache_path(input) {
        load_cache(scene, crate::cache::Cache::open(input)?)?
    } else if let Some(cache) = crate::cache::convert::auto_cache(scene, input, settings)? {
        load_cache(scene, cache)?
    } else {
        load_vdb(scene, input, settings)?
    };
    let LoadedVolume { volume, emission, source_grid, proxy_power, cache } = loaded;
    let camera = camera(scene, input, &volume)?;
    let medium = Medium { sigma_t: scene.medium.density_scale, albedo: scene.albedo(), g: scene.medium.g, emission };
    // Light-sampling structures, only for the technique in use and only when paths scatter
    let (_, light_sampling) = scene.integrator.parts();
    let lights = if scene.scatters() {
        let proxy_resolution = ProxyGrid::resolution_for(&volume, scene.integrator.proxy_resolution);
        crate::cache::convert::check_light_budget(&volume, light_sampling, memory_budget(settings))?;
        match proxy_power {
            Some((power, key)) if light_sampling == LightSampling::Fnee && power.resolution == proxy_resolution && key == emission.light_key() => {
                Lights { nee: None, proxy: ProxyGrid::from_cell_power(&volume, &power)? }
            }
            _ => Lights::build(&volume, &emission, light_sampling, proxy_resolution)?,
        }
    } else {
        Lights::default()
    };
    Ok(LoadedScene { scene: Scene { field: volume, medium, camera, lights }, emission_kind: emission.kind, source_grid, cache })
}

/// The camera: as given, or framing the volume automatically.
fn camera(scene: &SceneDescription, input: &Path, volume: &Volume) -> Result<Camera> {
    let c = &scene.camera;
    let up = c.up.unwrap_or(match c.up_axis {
        UpAxis::Y => DVec3::Y,
        UpAxis::Z => DVec3::Z,
    });
    let (lo, hi) = if volume.is_empty() { (DVec3::splat(-1.0), DVec3::splat(1.0)) } else { volume.world_bounds() };
    if let Some(from) = c.from {
        return Camera::look_at(from, c.at.unwrap_or(0.5 * (lo + hi)), up, c.fov, c.width, c.height);
    }
    // Automatic framing: a three-quarter view from the front, slightly above
    let view = match c.up_axis {
        UpAxis::Y => DVec3::new(0.35, 0.25, 1.0),
        UpAxis::Z => DVec3::new(0.35, -1.0, 0.25),
    };
    // Bounds too far out for f64 rays come from a corrupt transform, not from the description
    let mut cam = Camera::frame_bounds(lo, hi, view, up, c.fov, c.width, c.height).map_err(|_| {
        let v = |p: DVec3| format!("({:.3e}, {:.3e}, {:.3e})", p.x, p.y, p.z);
        Error::Scene(format!(
            "{}: grid {:?} lies at world coordinates {} .. {}, too far out to frame a camera; its transform is probably corrupt",
            input.display(),
            scene.volume.density_grid,
            v(lo),
            v(hi)
        ))
    })?;
    if let Some(at) = c.at {
        cam = Camera::look_at(cam.origin, at, up, c.fov, c.width, c.height)?;
    }
    Ok(cam)
}
