//! Generated volumes written straight to a brick cache (`plume synth flare -o X.plume`):
//! z-slab by z-slab, each slab's bricks generated in parallel and appended in order, so
//! memory holds one slab of bricks (at 4096³, about 16,000 bricks, 64 MiB) plus the brick
//! table, never the volume. The result does not depend on the thread count.

use std::path::Path;
use std::time::Instant;

use rayon::prelude::*;

use super::convert::{kind_name, Converted};
use crate::load::bind::unit_emission_model;
use plume_core::error::Result;
use plume_engine::integrator::light_power;
use plume_engine::medium::EmissionKind;
use plume_scene::EmissionSettings;
use plume_synth::Flare;
use plume_volume::brick::Channel;
use plume_volume::grid::LEAF_VOXELS;
use plume_volume::out_of_core::writer::{CacheInfo, CacheWriter, ProxySpec};

/// One generated brick: coordinate, density and temperature in leaf order.
type GeneratedBrick = (glam::IVec3, Box<[f32; LEAF_VOXELS]>, Box<[f32; LEAF_VOXELS]>);

/// Write `flare` as the cache `out` (grids `density` and Kelvin `temperature`, mapped as
/// `plume render`'s defaults map them), with a proxy of `proxy_resolution` (default when
/// `None`). `progress(bytes_written, slabs_done, slabs)` is called after every slab.
///
/// # Errors
/// Write errors.
pub fn write_flare(
    flare: &Flare,
    out: &Path,
    proxy_resolution: Option<u32>,
    progress: &dyn Fn(u64, i32, i32),
) -> Result<Converted> {
    let start = Instant::now();
    let emission = unit_emission_model(&EmissionSettings::default(), EmissionKind::Blackbody)?;
    let dims = flare.brick_dims();
    let mut writer =
        CacheWriter::create(out, flare.world_from_index(), glam::IVec3::ZERO, dims, "density")?;
    for bz in 0..dims.z {
        let bricks: Vec<GeneratedBrick> = flare
            .bricks_in_slab(bz)
            .into_par_iter()
            .filter_map(|b| {
                let (mut d, mut t) =
                    (Box::new([0.0f32; LEAF_VOXELS]), Box::new([0.0f32; LEAF_VOXELS]));
                flare.fill_brick(b, &mut d, &mut t).then_some((b, d, t))
            })
            .collect();
        for (b, density, temperature) in &bricks {
            writer.put(*b, Channel::Density, &density[..], |v| v)?;
            writer.put(*b, Channel::Source, &temperature[..], |t| emission.map_source(t))?;
        }
        progress(writer.bytes_written(), bz + 1, dims.z);
    }
    let info = CacheInfo {
        density_grid: "density".into(),
        source_grid: Some("temperature".into()),
        albedo_grid: None,
        source_key: emission.source_key(),
        emission_kind: kind_name(EmissionKind::Blackbody).into(),
        input: None,
        backgrounds: [Some(0.0), Some(emission.map_source(0.0)), None],
    };
    let power = light_power(&emission);
    let proxy =
        ProxySpec { resolution: proxy_resolution, power_key: emission.light_key(), power: &power };
    let path = writer.finish(&info, Some(proxy))?;
    let bytes = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
    Ok(Converted { path, bytes, seconds: start.elapsed().as_secs_f64() })
}
