//! The checks that decide whether a brick cache may be rendered: the input's identity
//! and staleness ([`fingerprint`], [`check_not_stale`]), the description's grids and
//! emission kind ([`check_description`]), the source mapping ([`check_source_key`]), and
//! whether classic NEE's light tables fit the memory budget ([`check_light_budget`]).

use std::path::Path;

use plume_core::error::{Error, Result};
use plume_engine::integrator::LightSampling;
use plume_engine::medium::EmissionKind;
use plume_engine::stats::GIB;
use plume_scene::{EmissionSource, NeeTable, VolumeInput};
use plume_volume::brick::Slot;
use plume_volume::out_of_core::format::InputFingerprint;
use plume_volume::out_of_core::reader::Cache;
use plume_volume::Volume;

/// The input's identity for staleness checks.
///
/// # Errors
/// The file cannot be examined.
pub fn fingerprint(path: &Path) -> Result<InputFingerprint> {
    let open = |e| Error::Open { path: path.to_path_buf(), source: e };
    let meta = std::fs::metadata(path).map_err(open)?;
    let mtime = meta.modified().map_err(open)?;
    let mtime_ns = match mtime.duration_since(std::time::UNIX_EPOCH) {
        Ok(d) => d.as_nanos() as i128,
        Err(e) => -(e.duration().as_nanos() as i128),
    };
    let abs = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
    Ok(InputFingerprint { path: abs.to_string_lossy().into_owned(), size: meta.len(), mtime_ns })
}

/// The emission kind a render from `cache` uses, after checking that the description
/// does not ask for other grids or another kind.
///
/// # Errors
/// [`Error::InvalidArgument`] naming the key that disagrees with the cache.
pub fn check_description(
    cache: &Cache,
    grids: &VolumeInput,
    source: EmissionSource,
) -> Result<EmissionKind> {
    let meta = &cache.meta;
    let stored = match meta.emission_kind.as_str() {
        "blackbody" => EmissionKind::Blackbody,
        "grid" => EmissionKind::Grid,
        _ => EmissionKind::None,
    };
    let path = cache.path.display();
    let asked = match source {
        EmissionSource::Auto => stored,
        EmissionSource::None => EmissionKind::None,
        EmissionSource::Blackbody => EmissionKind::Blackbody,
        EmissionSource::Grid => EmissionKind::Grid,
    };
    if asked != stored && asked != EmissionKind::None {
        return Err(Error::invalid(
            "emission.source",
            format!("{path} was prepared with {} emission; prepare it again with the emission source you render with", meta.emission_kind),
        ));
    }
    if grids.density_grid != "density" && grids.density_grid != meta.density_grid {
        return Err(Error::invalid(
            "volume.density_grid",
            format!(
                "{path} holds density grid {:?}, not {:?}; prepare it again with this density grid",
                meta.density_grid, grids.density_grid
            ),
        ));
    }
    if let Some(a) = &grids.albedo_grid {
        if meta.albedo_grid.as_deref() != Some(a.as_str()) {
            return Err(Error::invalid(
                "volume.albedo_grid",
                format!("{path} holds albedo grid {:?}, not {a:?}; prepare it again with this albedo grid", meta.albedo_grid),
            ));
        }
    }
    Ok(asked)
}

/// Check that the render maps sources as the cache stored them.
///
/// # Errors
/// [`Error::InvalidArgument`] naming the mapping flags.
pub fn check_source_key(cache: &Cache, emission: &plume_engine::medium::Emission) -> Result<()> {
    if emission.kind == EmissionKind::None || emission.source_key() == cache.meta.source_key {
        return Ok(());
    }
    Err(Error::invalid(
        "emission.temperature_map/emission.temperature_cutoff/emission.convention",
        format!(
            "{} stores sources mapped as \"{}\", the render maps them as \"{}\"; prepare it again with the mapping you render with",
            cache.path.display(),
            cache.meta.source_key,
            emission.source_key()
        ),
    ))
}

/// Refuse a cache whose source file has changed since it was prepared (a source that no
/// longer exists is fine: a cache stands on its own).
///
/// # Errors
/// [`Error::Cache`] saying what changed.
pub fn check_not_stale(cache: &Cache) -> Result<()> {
    let Some(input) = &cache.meta.input else { return Ok(()) };
    let Ok(now) = fingerprint(Path::new(&input.path)) else { return Ok(()) };
    if now.size != input.size || now.mtime_ns != input.mtime_ns {
        return Err(Error::Cache {
            path: cache.path.clone(),
            what: format!(
                "stale: {} changed since it was prepared; run `plume prepare` again",
                input.path
            ),
        });
    }
    Ok(())
}

/// Refuse light-sampling tables that would not fit `budget` bytes of anonymous memory.
///
/// # Errors
/// [`Error::InvalidArgument`] for `render.memory_budget`, with the way out.
pub fn check_light_budget(
    volume: &Volume,
    light_sampling: LightSampling,
    table: NeeTable,
    budget: u64,
) -> Result<()> {
    if light_sampling != LightSampling::Nee {
        return Ok(());
    }
    let emitting_bricks: u64 = volume
        .bricks
        .iter()
        .map(|b| u64::from(!matches!(b.source.get(), Slot::Constant(s) if s == 0.0)))
        .sum();
    // A brick table: an alias slot, a cell and a power per emitting brick (light::nee_bricks)
    let brick_table = emitting_bricks * 32;
    // A voxel table: an alias slot and index per emitting voxel, a record per brick, a table
    let emitting_voxels = emitting_bricks * 512;
    let needed = match table {
        NeeTable::Voxel => {
            emitting_voxels * 24 + volume.table.len() as u64 * 4 + volume.bricks.len() as u64 * 16
        }
        NeeTable::Brick => brick_table,
    };
    if needed > budget {
        let way_out = match table {
            NeeTable::Voxel => format!(
                "use integrator.nee_table brick (about {:.1} MiB: the voxel drawn from its brick's values) or the line-fnee method (its proxy needs a few MiB), or raise the memory budget",
                brick_table as f64 / (1024.0 * 1024.0)
            ),
            NeeTable::Brick => "use the line-fnee method (its proxy needs a few MiB) or raise the memory budget".into(),
        };
        return Err(Error::invalid(
            "render.memory_budget",
            format!(
                "classic NEE would need about {:.2} GiB for its {table} table of up to {emitting_voxels} emitting voxels in {emitting_bricks} bricks, more than the budget of {:.2} GiB; {way_out}",
                needed as f64 / GIB,
                budget as f64 / GIB
            ),
        ));
    }
    Ok(())
}
