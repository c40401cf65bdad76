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

pub mod bind;
mod several;
mod shares;

use std::path::Path;

use glam::DVec3;

use crate::cache::CacheCheck;
use crate::load::bind::{
    emission_kind, emission_model, grid_requests, memory_budget, reader, split_found, FileReader,
};
use crate::vdb::{FloatGrid, GridRequest};
use plume_core::error::{Error, Result};
use plume_engine::camera::{Camera, CameraMotion, LookAt};
use plume_engine::integrator::lights::VolumeLayers;
use plume_engine::integrator::{AnyScene, LightSampling, Lights, Scene, Tracking};
use plume_engine::medium::{Emission, EmissionKind, Medium};
use plume_scene::{JobSettings, SceneDescription, UpAxis};
use plume_volume::majorant::MajorantGrid;
use plume_volume::motion::Motion;
use plume_volume::proxy::{CellPower, ProxyGrid};
use plume_volume::velocity::{Velocity, VelocityGrid};
use plume_volume::{Bounds3, Field, Volume};

/// A scene ready to render, and what the outputs report about how it was loaded.
pub struct LoadedScene {
    /// The scene, its volume reconstructed as `volume.interpolation` says.
    pub scene: AnyScene,
    /// Emission kind actually used (after `auto`).
    pub emission_kind: EmissionKind,
    /// Name of the source grid used, if any.
    pub source_grid: Option<String>,
    /// When the volume is mapped from a brick cache: its background checksum check, which
    /// must pass before any output is written ([`CacheCheck::verified`]).
    pub cache: Option<CacheCheck>,
    /// The same for the further volumes of a scene of several that are mapped.
    pub further_caches: Vec<CacheCheck>,
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
fn load_vdb(
    scene: &SceneDescription,
    input: &Path,
    settings: &JobSettings,
) -> Result<LoadedVolume> {
    let FileReader { limits, isolation } = reader(&settings.reading)?;
    let requests = grid_requests(&scene.volume, scene.emission.source)?;
    let found = isolation.read_grids(input, &requests, &limits)?;
    let grids = split_found(scene.emission.source, found);
    let kind = emission_kind(scene.emission.source, grids.source.as_ref().map(|f| f.alternative));
    let emission = emission_model(&scene.emission, kind)?;
    let source = grids.source.map(|f| f.grid);
    let albedo = grids.albedo.map(|f| f.grid);
    let volume = Volume::build_with_albedo(
        &grids.density.grid,
        source.as_ref(),
        |v| emission.map_source(v),
        albedo.as_ref(),
    )?;
    Ok(LoadedVolume {
        volume,
        emission,
        source_grid: source.map(|g| g.name),
        proxy_power: None,
        cache: None,
    })
}

/// The volume of `input` as `scene`'s (one) volume describes it: mapped from a `.plume`
/// brick cache, through an automatic cache for a `.vdb` larger than a quarter of `budget`,
/// or read into memory.
fn load_volume(
    scene: &SceneDescription,
    input: &Path,
    settings: &JobSettings,
    budget: u64,
) -> Result<LoadedVolume> {
    if crate::cache::is_cache_path(input) {
        load_cache(scene, crate::cache::Cache::open(input)?)
    } else if let Some(cache) = crate::cache::convert::auto_cache(scene, input, settings, budget)? {
        load_cache(scene, cache)
    } else {
        load_vdb(scene, input, settings)
    }
}

/// The medium of `scene`'s (one) volume, emitting as `emission`: coefficients per world
/// unit, or per unit of the placed volume (Cycles' Object space) when `placement` scales.
fn placed_medium(
    scene: &SceneDescription,
    emission: Emission,
    placement: Option<glam::DAffine3>,
) -> Medium {
    let (density_scale, emission) =
        match placement.map(|m| scene.volume.space.coefficient_factor(m)) {
            Some(f) if f != 1.0 => (
                scene.medium.density_scale * f,
                Emission { scale: (f64::from(emission.scale) * f) as f32, ..emission },
            ),
            _ => (scene.medium.density_scale, emission),
        };
    Medium::principled(
        density_scale,
        scene.albedo_rgb(),
        scene.medium.absorption_color.map_or([0.0; 3], plume_scene::Albedo::rgb),
        scene.medium.g,
        emission,
    )
}

/// The AOV layer of a volume's light `group` among the scene's layers of light groups
/// (`SceneDescription::aov_groups`).
fn group_layer(scene: &SceneDescription, group: Option<&String>) -> Option<usize> {
    let group = group?;
    scene.aov_groups().iter().position(|g| g == group)
}

/// The world box a volume fills, or the unit box around the origin for an empty one.
fn bounds_of(volume: &Volume) -> Bounds3 {
    if volume.is_empty() {
        Bounds3 { lo: DVec3::splat(-1.0), hi: DVec3::splat(1.0) }
    } else {
        volume.world_bounds()
    }
}

/// The lights besides the volumes, sized to the scene's box `bounds`; `None` without any.
fn external_lights(
    scene: &SceneDescription,
    Bounds3 { lo, hi }: Bounds3,
) -> Result<Option<plume_engine::light::external::ExternalLights>> {
    if !scene.lights.any() {
        return Ok(None);
    }
    plume_engine::light::external::settings::build(
        &scene.lights,
        up_axis(scene),
        0.5 * (hi - lo).length(),
    )
}

/// Check a brick cache against the description and take its volume.
fn load_cache(scene: &SceneDescription, cache: crate::cache::Cache) -> Result<LoadedVolume> {
    let kind =
        crate::cache::convert::check_description(&cache, &scene.volume, scene.emission.source)?;
    let emission = emission_model(&scene.emission, kind)?;
    crate::cache::convert::check_source_key(&cache, &emission)?;
    crate::cache::convert::check_not_stale(&cache)?;
    let proxy_power = cache.proxy_power.zip(cache.meta.proxy.map(|p| p.power_key));
    Ok(LoadedVolume {
        volume: cache.volume,
        emission,
        source_grid: cache.meta.source_grid,
        proxy_power,
        cache: Some(cache.check),
    })
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
pub fn load_scene(
    scene: &SceneDescription,
    input: &Path,
    settings: &JobSettings,
    frame: Option<i64>,
) -> Result<LoadedScene> {
    // Mapping values are checked before any reading
    emission_model(&scene.emission, EmissionKind::None)?;
    if scene.is_several() {
        return several::load_several(scene, input, settings, frame);
    }
    let budget = memory_budget(settings);
    let LoadedVolume { volume, emission, source_grid, proxy_power, cache } =
        load_volume(scene, input, settings, budget)?;
    // Placed in the world before anything is built from world space
    let placement = scene.volume.placement().transform("volume")?;
    let volume = match placement {
        Some(m) => volume.placed(m),
        None => volume,
    };
    let camera = camera(scene, input, bounds_of(&volume), frame)?;
    let medium = placed_medium(scene, emission, placement);
    // Light-sampling structures, only for the technique in use and only when paths scatter
    let (_, light_sampling) = scene.integrator.parts();
    let mut lights = if scene.scatters() {
        let proxy_resolution =
            ProxyGrid::resolution_for(&volume, scene.integrator.proxy_resolution);
        crate::cache::convert::check_light_budget(
            &volume,
            light_sampling,
            scene.integrator.nee_table,
            budget,
        )?;
        match proxy_power {
            Some((power, key))
                if light_sampling == LightSampling::Fnee
                    && power.resolution == proxy_resolution
                    && key == emission.light_key() =>
            {
                Lights { proxy: ProxyGrid::from_cell_power(&volume, &power)?, ..Lights::default() }
            }
            _ => Lights::build_with(
                &volume,
                &emission,
                light_sampling,
                proxy_resolution,
                scene.integrator.nee_table,
            )?,
        }
    } else {
        Lights::default()
    };
    // Lights besides the volume: seen by camera rays even when nothing scatters
    lights.external = external_lights(scene, bounds_of(&volume))?;
    if let Some(layer) = group_layer(scene, scene.volume.group.as_ref()) {
        lights.volume_layers = VolumeLayers::One(layer);
    }
    let motion = match (&scene.volume.velocity_grid, scene.shutter_seconds()) {
        (Some(name), Some(shutter)) => Some(Motion::new(
            &volume,
            Velocity::Grid(match placement {
                Some(m) => read_velocity(input, name, settings)?.placed(m),
                None => read_velocity(input, name, settings)?,
            }),
            scene.volume.velocity_scale,
            shutter,
        )),
        _ => None,
    };
    // Majorants for null collisions in a still volume (a moving one has its own)
    let majorants = (motion.is_none()
        && plume_engine::integrator::Integrator::for_scene(scene).tracking != Tracking::Regular)
        .then(|| MajorantGrid::new(&volume, 0.0));
    let scene = AnyScene::new(
        Scene { field: volume, medium, camera, lights, motion, majorants },
        scene.volume.interpolation,
    );
    Ok(LoadedScene {
        scene,
        emission_kind: emission.kind,
        source_grid,
        cache,
        further_caches: Vec::new(),
    })
}

/// The velocity grid `name` of the .vdb `input`: a vec3 grid `name` (Blender, Houdini
/// `vel`), else three float grids `name.x`, `name.y`, `name.z`. A staggered (face-centred)
/// grid is read as if its values were at voxel centres: velocity only moves the lookup
/// point, and half a voxel of shift in where it is sampled is below what blur shows.
///
/// # Errors
/// A grid `name` that is not a vector grid, no complete x/y/z triple, a brick cache given
/// as input (velocity is not stored in caches), non-finite velocities.
fn read_velocity(input: &Path, name: &str, settings: &JobSettings) -> Result<VelocityGrid> {
    if crate::cache::is_cache_path(input) {
        return Err(Error::invalid(
            "volume.velocity_grid",
            format!(
                "{}: brick caches hold no velocity; render the .vdb for motion blur",
                input.display()
            ),
        ));
    }
    let FileReader { limits, isolation } = reader(&settings.reading)?;
    let what = format!("{}: grid {name:?}", input.display());
    let selector = plume_scene::validate::selector("volume.velocity_grid", name)?;
    match isolation.read_vec3_grid(input, &selector, &limits) {
        Ok([x, y, z]) => return VelocityGrid::from_components([&x, &y, &z], &what),
        Err(Error::GridNotFound { .. }) => {}
        Err(e) => return Err(e),
    }
    // No vector grid of that name: its components as float grids
    let requests: Vec<GridRequest> = ["x", "y", "z"]
        .iter()
        .map(|c| {
            plume_scene::validate::selector("volume.velocity_grid", &format!("{name}.{c}"))
                .map(GridRequest::required)
        })
        .collect::<Result<_>>()?;
    let found = isolation.read_grids(input, &requests, &limits).map_err(|e| match e {
        Error::GridNotFound { .. } => Error::Scene(format!("{what}: no vector grid {name:?} and no complete float triple {name}.x, {name}.y, {name}.z ({e})")),
        e => e,
    })?;
    let grids: Vec<FloatGrid> = found
        .into_iter()
        .map(|f| f.expect("invariant: required grids are found or an error").grid)
        .collect();
    VelocityGrid::from_components([&grids[0], &grids[1], &grids[2]], &what)
}

/// The scene's up axis (`camera.up_axis`): the zenith of environment maps and the sky.
fn up_axis(scene: &SceneDescription) -> DVec3 {
    match scene.camera.up_axis {
        UpAxis::Y => DVec3::Y,
        UpAxis::Z => DVec3::Z,
    }
}

/// The placement of an animated camera at frame position `x` (`camera.keys`, linear
/// between keys, held before the first and after the last).
fn keyed(scene: &SceneDescription, x: f64) -> LookAt {
    let c = &scene.camera;
    let look = |k: &plume_scene::CameraKey| LookAt {
        from: k.from,
        at: k.at,
        up: k.up.or(c.up).unwrap_or(up_axis(scene)),
        fov: k.fov.unwrap_or(c.horizontal_fov()),
    };
    let keys = &c.keys;
    let i = keys.iter().rposition(|k| k.frame <= x).unwrap_or(0);
    if i + 1 >= keys.len() || x <= keys[0].frame {
        return look(&keys[if x <= keys[0].frame { 0 } else { i }]);
    }
    let (a, b) = (&keys[i], &keys[i + 1]);
    look(a).lerp(&look(b), (x - a.frame) / (b.frame - a.frame))
}

/// The camera of an animated scene at frame `frame`: the keys' placement at the frame, and
/// its path over the shutter (knots at the opening, at every key inside, at the closing).
fn keyed_camera(scene: &SceneDescription, frame: Option<i64>) -> Result<(Camera, DVec3)> {
    let c = &scene.camera;
    let f = frame.unwrap_or(0) as f64;
    let here = keyed(scene, f);
    let mut camera = Camera::look_at(here.from, here.at, here.up, here.fov, c.width, c.height)?;
    if let Some([open, close]) = scene.shutter_seconds() {
        let (o, e) = (f + open * c.fps, f + close * c.fps);
        let mut knots = vec![(open, keyed(scene, o))];
        knots.extend(
            c.keys
                .iter()
                .filter(|k| k.frame > o && k.frame < e)
                .map(|k| ((k.frame - f) / c.fps, keyed(scene, k.frame))),
        );
        knots.push((close, keyed(scene, e)));
        if close > open && knots.windows(2).any(|w| w[0].1 != w[1].1) {
            camera.motion = Some(CameraMotion::new(&knots, c.width, c.height)?);
        }
    }
    Ok((camera, here.at))
}

/// The camera: placed as given, animated by keys, or framing the volume automatically;
/// then its lens: a thin lens, or orthographic.
fn camera(
    scene: &SceneDescription,
    input: &Path,
    bounds: Bounds3,
    frame: Option<i64>,
) -> Result<Camera> {
    let (camera, at) = if scene.camera.keys.is_empty() {
        placed_camera(scene, input, bounds)?
    } else {
        keyed_camera(scene, frame)?
    };
    camera_optics(camera, &scene.camera, at, bounds)
}

/// `camera` through the lens `c` asks for: orthographic (by default as wide as the
/// volume's bounding sphere, with a margin), or a thin lens focused by default at the
/// point looked at, `at`.
fn camera_optics(
    camera: Camera,
    c: &plume_scene::CameraSettings,
    at: DVec3,
    Bounds3 { lo, hi }: Bounds3,
) -> Result<Camera> {
    match c.projection {
        plume_scene::Projection::Orthographic => {
            let aspect = f64::from(camera.width) / f64::from(camera.height);
            let radius = (0.5 * (hi - lo).length()).max(1e-12);
            camera.orthographic(c.ortho_width.unwrap_or(2.04 * radius * aspect.max(1.0)))
        }
        plume_scene::Projection::Perspective => match c.lens_radius() {
            r if r > 0.0 => {
                let focus = c.focus_distance.unwrap_or((at - camera.origin).dot(camera.forward()));
                camera.with_thin_lens(r, focus)
            }
            _ => Ok(camera),
        },
    }
}

/// The still camera: as given, or framing the box `bounds` automatically; and the point
/// it looks at.
fn placed_camera(
    scene: &SceneDescription,
    input: &Path,
    Bounds3 { lo, hi }: Bounds3,
) -> Result<(Camera, DVec3)> {
    let c = &scene.camera;
    let fov = c.horizontal_fov();
    let up = c.up.unwrap_or(up_axis(scene));
    if let Some(from) = c.from {
        let at = c.at.unwrap_or(0.5 * (lo + hi));
        return Ok((Camera::look_at(from, at, up, fov, c.width, c.height)?, at));
    }
    // Automatic framing: a three-quarter view from the front, slightly above
    let view = match c.up_axis {
        UpAxis::Y => DVec3::new(0.35, 0.25, 1.0),
        UpAxis::Z => DVec3::new(0.35, -1.0, 0.25),
    };
    // Bounds too far out for f64 rays come from a corrupt transform, not from the description
    let mut cam = Camera::frame_bounds(lo, hi, view, up, fov, c.width, c.height).map_err(|_| {
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
        cam = Camera::look_at(cam.origin, at, up, fov, c.width, c.height)?;
    }
    Ok((cam, c.at.unwrap_or(0.5 * (lo + hi))))
}
