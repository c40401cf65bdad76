//! A scene of several volumes (`[[volumes]]`): each volume is loaded as it would be alone
//! (read, mapped from a brick cache, or through an automatic cache), placed in the world
//! and given its own medium, and the scene's field is their sum
//! (`plume_engine::overlap::volumes::Volumes`). FNEE draws from each emitting volume's own
//! proxy, chosen by power (`plume_engine::light::mixture`).
//!
//! **Instances.** A volume with `instances` is read once: one field and one FNEE proxy,
//! shared (`Arc`) by one member per instance (`plume_volume::instance`), the field
//! placed by the entry's own placement and each instance carrying rays from its placement
//! into that frame. Each instance has its own medium: in object space the coefficients
//! follow the instance's whole placement (`instance · entry`). Its FNEE weight is the
//! shared proxy's power over the base volume per world volume, `|det L|`
//! (`Instance::base_per_world_volume`): the power of the volume placed there. A single
//! volume with instances is loaded here too (`SceneDescription::is_several`).
//!
//! **Memory.** The budget is shared (`load::shares`): each volume's automatic-cache decision
//! and light tables see its share, what it needs up to an equal part of what the smaller
//! volumes leave, so volumes that would fit alone but not together are paged. Instances
//! share their volume's share: N instances cost one volume's data and proxy, and per
//! instance a member and a placed proxy (a few hundred bytes).
//!
//! **Errors** name the volume's keys (`volumes[1].density_grid`), as validation does.

use std::path::Path;
use std::sync::Arc;

use glam::DAffine3;

use super::bind::{emission_model, memory_budget};
use super::shares;
use super::{
    bounds_of, camera, external_lights, group_layer, load_volume, placed_medium, LoadedScene,
    LoadedVolume,
};
use crate::cache::CacheCheck;
use plume_core::error::{Error, Result};
use plume_engine::integrator::lights::{proxy_weight, VolumeLayers};
use plume_engine::integrator::{AnyScene, LightSampling, Lights, Scene};
use plume_engine::light::mixture::{PlacedProxy, ProxyMixture};
use plume_engine::light::nee_mixture::{emitting_bounds, EmitterMixture, PlacedEmitters};
use plume_engine::light::{EmitterDistribution, LightPower};
use plume_engine::medium::{Emission, EmissionKind, Medium};
use plume_engine::overlap::member::Member;
use plume_engine::overlap::volumes::Volumes;
use plume_scene::placement::instance_placement;
use plume_scene::{EntryRef, Interpolation, JobSettings, SceneDescription};
use plume_volume::instance::Instance;
use plume_volume::proxy::{CellPower, ProxyGrid};
use plume_volume::trilinear::Trilinear;
use plume_volume::{Bounds3, Volume};

/// One volume of the scene, loaded and placed by its entry's placement, and where it
/// appears.
struct Part {
    volume: Volume,
    /// Once at the entry's placement, or once per instance.
    appearances: Vec<Appearance>,
    /// The emission the volume was read with (its proxy power's key).
    emission: Emission,
    proxy_power: Option<(CellPower, String)>,
    visible_to_camera: bool,
    casts_shadows: bool,
    /// The AOV layer of its light group, if it has one.
    layer: Option<usize>,
    /// Its share of the memory budget (`load::shares`).
    budget: u64,
}

/// One place a volume appears: its instance (`None`: where the entry places it) and the
/// medium it has there.
struct Appearance {
    instance: Option<Instance>,
    medium: Medium,
}

impl Appearance {
    /// The world box of `volume` appearing here (as `Member::world_bounds` places it).
    fn bounds(&self, volume: &Volume) -> Bounds3 {
        let b = bounds_of(volume);
        self.instance.map_or(b, |i| i.bounds(b))
    }

    /// Volume of the entry's placed frame per world volume, `|det L|`: 1 without an
    /// instance.
    fn base_per_world_volume(&self) -> f64 {
        self.instance.map_or(1.0, |i| i.base_per_world_volume())
    }
}

/// [`super::load_scene`] for a scene of several volumes: `input` is the first volume's
/// file (its frame token resolved); the others' files are read as they stand in the
/// description.
pub(super) fn load_several(
    scene: &SceneDescription,
    input: &Path,
    settings: &JobSettings,
    frame: Option<i64>,
) -> Result<LoadedScene> {
    let entries = scene.entries();
    let needs: Vec<Option<u64>> = entries.iter().map(|e| shares::need(path_of(e, input))).collect();
    let budgets = shares::shares(&needs, memory_budget(settings));
    let mut parts = Vec::with_capacity(entries.len());
    let (mut first_cache, mut further_caches): (Option<CacheCheck>, Vec<CacheCheck>) =
        (None, Vec::new());
    let mut first: Option<(EmissionKind, Option<String>)> = None;
    for entry in &entries {
        let single = entry_scene(scene, entry);
        emission_model(&single.emission, EmissionKind::None).map_err(|e| rekey(e, entry))?;
        let budget = budgets[entry.index];
        let LoadedVolume { volume, emission, source_grid, proxy_power, cache } =
            load_volume(&single, path_of(entry, input), settings, budget)
                .map_err(|e| rekey(e, entry))?;
        first.get_or_insert((emission.kind, source_grid));
        match (entry.index, cache) {
            (0, cache) => first_cache = cache,
            (_, cache) => further_caches.extend(cache),
        }
        let placement = entry.volume.placement().transform(&entry.prefix)?;
        let volume = match placement {
            Some(m) => volume.placed(m),
            None => volume,
        };
        parts.push(Part {
            appearances: appearances(&single, entry, emission, placement)?,
            volume,
            emission,
            proxy_power,
            visible_to_camera: entry.volume.visible_to_camera,
            casts_shadows: entry.volume.casts_shadows,
            layer: group_layer(scene, entry.volume.group.as_ref()),
            budget,
        });
    }
    // Framing: the union of every appearance's box
    let bounds = parts
        .iter()
        .flat_map(|p| p.appearances.iter().map(|a| a.bounds(&p.volume)))
        .reduce(|a, b| Bounds3 { lo: a.lo.min(b.lo), hi: a.hi.max(b.hi) });
    let bounds = bounds.expect("invariant: a scene of several volumes has volumes");
    let camera = camera(scene, input, bounds, frame)?;
    let mut lights = volume_lights(scene, &parts)?;
    lights.external = external_lights(scene, bounds)?;
    let (emission_kind, source_grid) = first.expect("invariant: at least one volume");
    let scene = match scene.volume.interpolation {
        Interpolation::Nearest => AnyScene::NearestVolumes(several(parts, |v| v, camera, lights)?),
        Interpolation::Linear => {
            AnyScene::LinearVolumes(several(parts, Trilinear::new, camera, lights)?)
        }
    };
    Ok(LoadedScene { scene, emission_kind, source_grid, cache: first_cache, further_caches })
}

/// Where `entry`'s volume appears, placed by the entry as `placement`: there, or at each
/// of its instances, each with the medium of its whole placement (object space divides
/// by its scale).
///
/// # Errors
/// An instance whose placement is invalid (validation refuses it first), named by its key.
fn appearances(
    single: &SceneDescription,
    entry: &EntryRef<'_>,
    emission: Emission,
    placement: Option<DAffine3>,
) -> Result<Vec<Appearance>> {
    let Some(instances) = &entry.volume.instances else {
        let medium = placed_medium(single, emission, placement);
        return Ok(vec![Appearance { instance: None, medium }]);
    };
    let mut appearances = Vec::with_capacity(instances.len());
    for (k, p) in instances.iter().enumerate() {
        let prefix = entry.key(&format!("instances[{k}]"));
        let own = p.transform(&prefix)?;
        // No keys: exactly where the entry places it
        let instance = match own {
            None => None,
            Some(m) => Some(Instance::new(m).ok_or_else(|| {
                let field = if p.matrix.is_some() { "matrix" } else { "scale" };
                Error::invalid(&format!("{prefix}.{field}"), "the transform is singular")
            })?),
        };
        let medium = placed_medium(single, emission, instance_placement(placement, own));
        appearances.push(Appearance { instance, medium });
    }
    Ok(appearances)
}

/// The scene of `parts`, each volume reconstructed by `field` once and shared by its
/// appearances, one member each; their light groups as `plume_engine::integrator`'s
/// groups module takes them: all emission to one layer where one group holds every
/// emitting volume, else a view per group.
fn several<F: plume_volume::Field + Send>(
    parts: Vec<Part>,
    field: impl Fn(Volume) -> F,
    camera: plume_engine::camera::Camera,
    mut lights: Lights,
) -> Result<Scene<Volumes<F>>> {
    let (mut members, mut layer_of) = (Vec::new(), Vec::new());
    for p in parts {
        let shared = Arc::new(field(p.volume));
        layer_of.extend(std::iter::repeat_n(p.layer, p.appearances.len()));
        members.extend(p.appearances.into_iter().map(|a| Member {
            field: Arc::clone(&shared),
            instance: a.instance,
            medium: a.medium,
            visible_to_camera: p.visible_to_camera,
            casts_shadows: p.casts_shadows,
        }));
    }
    let emitting: Vec<Option<usize>> = members
        .iter()
        .zip(&layer_of)
        .filter(|(m, _)| m.medium.emission.kind != EmissionKind::None)
        .map(|(_, l)| *l)
        .collect();
    let volumes = Volumes::new(members)?;
    lights.volume_layers = match emitting.first() {
        Some(&Some(layer)) if emitting.iter().all(|l| *l == Some(layer)) => {
            VolumeLayers::One(layer)
        }
        _ if emitting.iter().any(Option::is_some) => {
            VolumeLayers::Split { ungrouped: emitting.iter().any(Option::is_none) }
        }
        _ => VolumeLayers::Unsplit,
    };
    let volumes = match lights.volume_layers {
        VolumeLayers::Split { .. } => volumes.with_emission_groups(&layer_of)?,
        _ => volumes,
    };
    let medium = volumes.medium();
    Ok(Scene { field: volumes, medium, camera, lights, motion: None, majorants: None })
}

/// FNEE's proxies of the emitting volumes, when paths scatter: each from its cache's
/// stored power where it matches, else built, once per volume and shared by its
/// appearances; chosen by power (an instance's scaled by the world volume it fills).
fn volume_lights(scene: &SceneDescription, parts: &[Part]) -> Result<Lights> {
    let scatters = scene.scatters();
    let (_, light_sampling) = scene.integrator.parts();
    match light_sampling {
        _ if !scatters => Ok(Lights::default()),
        LightSampling::None => Ok(Lights::default()),
        LightSampling::Nee => {
            Ok(Lights { nee_several: volume_emitters(scene, parts)?, ..Lights::default() })
        }
        LightSampling::Fnee => {
            let mut proxies = Vec::new();
            for part in parts {
                let resolution =
                    ProxyGrid::resolution_for(&part.volume, scene.integrator.proxy_resolution);
                let proxy = match &part.proxy_power {
                    Some((power, key))
                        if power.resolution == resolution && *key == part.emission.light_key() =>
                    {
                        ProxyGrid::from_cell_power(&part.volume, power)?
                    }
                    _ => ProxyGrid::build(
                        &part.volume,
                        resolution,
                        plume_engine::integrator::light_power(&part.emission),
                    )?,
                };
                let Some(proxy) = proxy.map(Arc::new) else { continue };
                for a in &part.appearances {
                    let weight =
                        proxy_weight(&proxy, &a.medium.emission) / a.base_per_world_volume();
                    let placed = PlacedProxy { proxy: Arc::clone(&proxy), instance: a.instance };
                    proxies.push((placed, weight));
                }
            }
            Ok(Lights { proxies: ProxyMixture::new(proxies), ..Lights::default() })
        }
    }
}

/// Classic NEE's emitter tables of the emitting volumes: each built once per volume (at
/// the resolution `integrator.nee_table` asks for, within the volume's share of the
/// budget) and shared by its appearances; chosen by power as FNEE's proxies are.
fn volume_emitters(scene: &SceneDescription, parts: &[Part]) -> Result<Option<EmitterMixture>> {
    let mut emitters = Vec::new();
    let mut member = 0;
    for part in parts {
        let first = member;
        member += part.appearances.len();
        crate::cache::convert::check_light_budget(
            &part.volume,
            LightSampling::Nee,
            scene.integrator.nee_table,
            part.budget,
        )?;
        let table = EmitterDistribution::build_as(
            &part.volume,
            LightPower::new(&part.emission),
            scene.integrator.nee_table,
        )?;
        let Some(table) = table.map(|t| Arc::new(t.for_interpolation(scene.volume.interpolation)))
        else {
            continue;
        };
        for a in &part.appearances {
            let e = &a.medium.emission;
            let power = table.total_power() * f64::from(e.scale) * f64::from(e.color.luminance());
            let placed = PlacedEmitters {
                table: Arc::clone(&table),
                member: first,
                instance: a.instance,
                bounds: emitting_bounds(&part.volume, a.instance),
            };
            emitters.push((placed, power / a.base_per_world_volume()));
        }
    }
    Ok(EmitterMixture::new(emitters))
}

/// The file `entry` reads: `input` for the first (its frame token resolved), its own for
/// the others.
fn path_of<'a>(entry: &EntryRef<'a>, input: &'a Path) -> &'a Path {
    if entry.index == 0 {
        input
    } else {
        entry.volume.file.as_path()
    }
}

/// `scene` with `entry` as its one volume (what loading a volume alone reads).
fn entry_scene(scene: &SceneDescription, entry: &EntryRef<'_>) -> SceneDescription {
    let mut single = scene.clone();
    single.volume = entry.volume.clone();
    single.emission = entry.emission.clone();
    single.medium = entry.medium.clone();
    single.more_volumes.clear();
    single
}

/// An error from loading `entry` alone, naming the entry's keys.
fn rekey(e: Error, entry: &EntryRef<'_>) -> Error {
    if entry.prefix == "volume" {
        return e;
    }
    match e {
        Error::InvalidArgument { flag, message } => {
            let field = flag.strip_prefix("volume.").map(str::to_string).or_else(|| {
                (flag.starts_with("emission.") || flag.starts_with("medium.")).then(|| flag.clone())
            });
            Error::InvalidArgument { flag: field.map_or(flag, |f| entry.key(&f)), message }
        }
        Error::GridNotFound { .. } => {
            let Error::GridNotFound { name, .. } = &e else { unreachable!() };
            let v = entry.volume;
            let field = if *name == v.density_grid {
                "density_grid"
            } else if *name == v.temperature_grid {
                "temperature_grid"
            } else if v.emission_grid.as_ref() == Some(name) {
                "emission_grid"
            } else if v.albedo_grid.as_ref() == Some(name) {
                "albedo_grid"
            } else {
                "file"
            };
            Error::Scene(format!("{}: {e}", entry.key(field)))
        }
        e => e,
    }
}
