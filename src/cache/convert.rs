//! `.vdb` → brick cache conversion (`plume prepare`, and the automatic cache `plume
//! render` makes for a .vdb too large for its memory budget).
//!
//! A cache is **stale** when its format version differs, when the .vdb it was converted
//! from has changed size or modification time since, or (for an automatic cache) when it
//! fails any check; stale automatic caches are rebuilt, an explicit `.plume` input is
//! refused with the command that fixes it. A cache is **incompatible** with the render's
//! flags when they select other grids or map the source differently (the stored source
//! is already mapped): refused, naming the flag.
//!
//! This file owns the conversion itself ([`convert`]) and the automatic cache's entry
//! point ([`auto_cache`]: find, or convert under a lock); the checks that decide whether
//! a cache may be rendered are in `cache::checks`, where automatic caches live and how a
//! render waits for one in `cache::auto`, the grid headers read without values in
//! `cache::headers`. Their public items are re-exported here.

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::IVec3;

use super::auto::{auto_cache_name, cache_places, locked_out, open_auto, size, writable, Place};
use super::headers::{in_core_bytes, probe};
use crate::load::bind::{emission_kind, grid_requests, reader, unit_emission_model, FileReader};
use crate::vdb::{FileStamp, GridSelector, LeafData, StreamedGrid};
use plume_core::error::{Error, Result};
use plume_engine::integrator::light_power;
use plume_engine::medium::EmissionKind;
use plume_engine::stats::GIB;
use plume_scene::{
    EmissionSettings, EmissionSource, JobSettings, ReadSettings, SceneDescription, VolumeInput,
};
use plume_volume::brick::{brick_of, check_same_transform, table_dims, Channel};
use plume_volume::out_of_core::lock::{Acquired, CacheLock};
use plume_volume::out_of_core::reader::Cache;
use plume_volume::out_of_core::writer::{CacheInfo, CacheWriter, ProxySpec};

pub use super::auto::lock_timeout;
pub use super::checks::{
    check_description, check_light_budget, check_not_stale, check_source_key, fingerprint,
};

/// What a conversion wrote.
#[derive(Clone, Debug)]
pub struct Converted {
    /// The cache file.
    pub path: PathBuf,
    /// Its size in bytes.
    pub bytes: u64,
    /// Seconds taken.
    pub seconds: f64,
}

/// Name of an emission kind as stored in cache metadata.
#[must_use]
pub fn kind_name(kind: EmissionKind) -> &'static str {
    match kind {
        EmissionKind::None => "none",
        EmissionKind::Blackbody => "blackbody",
        EmissionKind::Grid => "grid",
    }
}

/// What a conversion stores: the grids a description binds, how their sources map, how
/// the file is read, and the proxy resolution (default for the volume's size when
/// `None`).
#[derive(Clone, Copy, Debug)]
pub struct Conversion<'a> {
    /// The grids (the `file` field is not used: the file is given apart).
    pub volume: &'a VolumeInput,
    /// How sources map (scale and tint are not stored).
    pub emission: &'a EmissionSettings,
    /// Reader limits and isolation.
    pub reading: &'a ReadSettings,
    /// FNEE proxy resolution to store.
    pub proxy_resolution: Option<u32>,
}

/// Convert the grids of `file` that `what` selects, with sources mapped as it says, into
/// the cache file `out`, storing its proxy.
///
/// Streams: each grid's header first (topology only, for the table's box and the
/// transform checks), then each grid leaf by leaf into the writer, so neither plume nor
/// the reader ever holds a grid's values (`vdb::stream`).
///
/// # Errors
/// Unreadable input or grids, incompatible transforms, write errors.
pub fn convert(file: &Path, what: &Conversion<'_>, out: &Path) -> Result<Converted> {
    let before = FileStamp::of(file).ok();
    let result = convert_unchecked(file, what, out);
    // A file that changed during the conversion explains a reader that crashed or read
    // garbage (OpenVDB reads the zeros past a new end), and a conversion that succeeded
    // may hold leaves of two versions: either way the file failed under plume (exit code
    // 4). Errors of the output (a full disk) stay what they are.
    let input_error =
        result.as_ref().err().is_none_or(|e| e.exit_code() == plume_core::error::exit::INPUT);
    match before.and_then(|b| b.change(file)) {
        Some(change) if input_error => {
            if let Ok(c) = &result {
                let _ = std::fs::remove_file(&c.path);
            }
            Err(FileStamp::failed(file, &change))
        }
        _ => result,
    }
}

fn convert_unchecked(file: &Path, what: &Conversion<'_>, out: &Path) -> Result<Converted> {
    let Conversion { volume, emission, reading, proxy_resolution } = *what;
    let start = Instant::now();
    let input = fingerprint(file)?;
    let FileReader { limits, isolation } = reader(reading)?;
    let source_kind = emission.source;
    // Resolve every request to one grid, by its header
    let mut chosen: Vec<Option<(usize, GridSelector, StreamedGrid)>> = Vec::new();
    for request in grid_requests(volume, source_kind)? {
        let mut found = None;
        for (k, sel) in request.alternatives.iter().enumerate() {
            if let Some(h) = probe(&isolation, file, sel, &limits)? {
                found = Some((k, sel.clone(), h));
                break;
            }
        }
        if found.is_none() && request.required {
            // The reader's own "no grid …; available: …" error
            let sel = &request.alternatives[0];
            isolation.stream_float_grid(file, sel, &limits, &mut |_| Ok(()), &mut |_, _| Ok(()))?;
        }
        chosen.push(found);
    }
    let mut chosen = chosen.into_iter();
    let (_, density_sel, density) =
        chosen.next().flatten().expect("invariant: the density request is required");
    let source = if source_kind == EmissionSource::None { None } else { chosen.next().flatten() };
    let albedo = chosen.next().flatten();
    let kind = emission_kind(source_kind, source.as_ref().map(|f| f.0));
    let emission = unit_emission_model(emission, kind)?;
    let w = density.world_from_index;
    if !w.inverse().is_finite() || w.matrix3.determinant() == 0.0 {
        return Err(Error::Scene(format!("grid {:?} has a singular transform", density.name)));
    }
    let channels = [
        (Channel::Density, Some((density_sel, density.clone()))),
        (Channel::Source, source.map(|(_, sel, h)| (sel, h))),
        (Channel::Albedo, albedo.map(|(_, sel, h)| (sel, h))),
    ];
    let (mut lo, mut hi) = (IVec3::MAX, IVec3::MIN);
    for (_, (_, h)) in channels.iter().filter_map(|(c, g)| Some((c, g.as_ref()?))) {
        check_same_transform((&density.name, w), (&h.name, h.world_from_index))?;
        if let Some((a, b)) = h.index_bbox {
            lo = lo.min(brick_of(a));
            hi = hi.max(brick_of(b));
        }
    }
    let (lo, dims) = if lo.x > hi.x {
        (IVec3::ZERO, IVec3::ZERO)
    } else {
        (lo, table_dims(lo, hi, &density.name)?)
    };
    let mut writer = CacheWriter::create(out, w, lo, dims, &density.name)?;
    let mut backgrounds = [None; 3];
    let mut names: [Option<String>; 3] = Default::default();
    for (i, (channel, grid)) in channels.into_iter().enumerate() {
        let Some((sel, header)) = grid else { continue };
        let map = |v: f32| if channel == Channel::Source { emission.map_source(v) } else { v };
        backgrounds[i] = Some(map(header.background));
        names[i] = Some(header.name.clone());
        isolation.stream_float_grid(
            file,
            &sel,
            &limits,
            &mut |_| Ok(()),
            &mut |origin, data| match data {
                LeafData::Values(values) => writer.put(brick_of(origin), channel, values, map),
                LeafData::Constant(v) => writer.put_constant(brick_of(origin), channel, map(v)),
            },
        )?;
    }
    let [density_grid, source_grid, albedo_grid] = names;
    let info = CacheInfo {
        density_grid: density_grid.unwrap_or_default(),
        source_grid,
        albedo_grid,
        source_key: emission.source_key(),
        emission_kind: kind_name(kind).into(),
        input: Some(input),
        backgrounds: [backgrounds[0], Some(backgrounds[1].unwrap_or(0.0)), backgrounds[2]],
    };
    let power = light_power(&emission);
    let proxy = (kind != EmissionKind::None).then(|| ProxySpec {
        resolution: proxy_resolution,
        power_key: emission.light_key(),
        power: &power,
    });
    let path = writer.finish(&info, proxy)?;
    let bytes = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
    Ok(Converted { path, bytes, seconds: start.elapsed().as_secs_f64() })
}

/// For a .vdb larger on disk than a quarter of the memory `budget` (bytes): its automatic cache,
/// converted now if missing, stale or damaged. `None` for smaller files (read in core),
/// and for files read in core because no cache can be made (below).
///
/// - A current cache in any of the places (`cache_places`) is used as it is, even in a
///   read-only directory (a cache directory prepared once and shared read-only).
/// - Otherwise the cache is made in the first writable place, under a lock
///   ([`CacheLock`]): a process that waited uses the cache the other one made. A stale or
///   damaged file stays where it is until the new cache is renamed over it, so a failed
///   conversion (a full disk) leaves the directory as it was. A process that waited
///   longer than [`lock_timeout`] (the holder hangs) reads the file into memory if that
///   fits the memory budget, and fails otherwise.
/// - An explicit `render.cache_dir` that cannot be written is an error; without one, when
///   neither the input's directory nor the user cache directory can be written, the file
///   is read into memory if that fits the memory budget, and refused otherwise.
///
/// # Errors
/// As [`convert`]; [`Error::Write`] for a cache directory that cannot be written (exit
/// code 4); [`Error::Interrupted`] for a signal while waiting for another converter;
/// [`Error::CacheLocked`] (exit code 4) when it waited in vain and the file does not fit
/// the memory budget.
pub fn auto_cache(
    scene: &SceneDescription,
    input: &Path,
    settings: &JobSettings,
    budget: u64,
) -> Result<Option<Cache>> {
    let Ok(meta) = std::fs::metadata(input) else { return Ok(None) };
    if meta.len().saturating_mul(4) <= budget {
        return Ok(None);
    }
    let name = auto_cache_name(scene, input);
    let places = cache_places(input, settings);
    for place in &places {
        match open_auto(&place.dir.join(&name)) {
            Ok(Some(cache)) => return Ok(Some(cache)),
            Ok(None) => {}
            Err(e) => log::info!("rebuilding the automatic cache ({e})"),
        }
    }
    let mut refused = Vec::new();
    for place in &places {
        let path = place.dir.join(&name);
        match writable(&place.dir, &path) {
            Ok(()) => return make_auto_cache(scene, input, settings, &path, meta.len(), budget),
            Err(e) => refused.push((place, e)),
        }
    }
    let why = |(place, e): &(&Place, std::io::Error)| {
        format!("{} ({}): {e}", place.dir.display(), place.what)
    };
    if settings.render.cache_dir.is_some() {
        let (place, e) = &refused[0];
        let message = format!(
            "{e}; render.cache_dir must name a writable directory: the automatic brick cache of {} is made there, \
             as the file is larger than a quarter of the memory budget",
            input.display()
        );
        return Err(Error::Write {
            path: place.dir.clone(),
            source: std::io::Error::new(e.kind(), message),
        });
    }
    let nowhere = refused.iter().map(why).collect::<Vec<_>>().join("; ");
    let needed = in_core_bytes(scene, input, settings)?;
    if needed <= budget {
        log::warn!(
            "nowhere to write the automatic brick cache of {} ({nowhere}); reading it into memory instead \
             (about {} while reading, within the memory budget of {})",
            input.display(),
            size(needed),
            size(budget)
        );
        return Ok(None);
    }
    let (place, e) = &refused[0];
    let others = refused[1..].iter().map(why).collect::<Vec<_>>().join("; ");
    let nor = if others.is_empty() { others } else { format!("; nor {others}") };
    let message = format!(
        "{e} ({}){nor}; so the automatic brick cache of {} cannot be made, and reading it into memory would need about {}, \
         more than the memory budget of {} (render.memory_budget); give a writable render.cache_dir",
        place.what,
        input.display(),
        size(needed),
        size(budget)
    );
    Err(Error::Write { path: place.dir.clone(), source: std::io::Error::new(e.kind(), message) })
}

/// Convert `input` to the automatic cache `path` (whose directory is writable), unless
/// another process made it while this one waited for the lock. `None` when the lock
/// stayed taken past [`lock_timeout`] and the file is read into memory instead.
fn make_auto_cache(
    scene: &SceneDescription,
    input: &Path,
    settings: &JobSettings,
    path: &Path,
    input_bytes: u64,
    budget: u64,
) -> Result<Option<Cache>> {
    let timeout = lock_timeout(settings, input_bytes);
    let at_most = (timeout.as_secs_f64() * 10.0).round() / 10.0;
    let waiting = format!("waiting for another process that is making the automatic cache {} (at most {at_most} s, render.cache_lock_timeout)", path.display());
    let _lock = match CacheLock::acquire(path, timeout, Some(&waiting))? {
        Acquired::Locked(lock) => lock,
        Acquired::TimedOut { lock, waited } => {
            // A whole new file may be there even so (readers see the old file or the new one)
            if let Ok(Some(cache)) = open_auto(path) {
                return Ok(Some(cache));
            }
            return locked_out(scene, input, settings, path, &lock, waited, budget).map(|()| None);
        }
    };
    if let Ok(Some(cache)) = open_auto(path) {
        log::info!(
            "using the automatic cache {}, which another process made meanwhile",
            path.display()
        );
        return Ok(Some(cache));
    }
    log::info!(
        "{} is {:.2} GiB on disk, more than a quarter of the memory budget ({:.2} GiB, render.memory_budget); \
         converting it once to the brick cache {}",
        input.display(),
        input_bytes as f64 / GIB,
        budget as f64 / GIB,
        path.display()
    );
    let what = Conversion {
        volume: &scene.volume,
        emission: &scene.emission,
        reading: &settings.reading,
        proxy_resolution: scene.integrator.proxy_resolution,
    };
    let c = convert(input, &what, path)?;
    log::info!(
        "wrote {} ({:.2} GiB) in {:.1} s",
        c.path.display(),
        c.bytes as f64 / GIB,
        c.seconds
    );
    let mut cache = Cache::open(&c.path)?;
    cache.check.remove_on_failure();
    Ok(Some(cache))
}
