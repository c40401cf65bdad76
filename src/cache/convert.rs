//! `.vdb` → brick cache conversion (`plume prepare`, and the automatic cache `plume
//! render` makes for a .vdb too large for its memory budget), and the checks that decide
//! whether a cache may be rendered with a given set of flags.
//!
//! A cache is **stale** when its format version differs, when the .vdb it was converted
//! from has changed size or modification time since, or (for an automatic cache) when it
//! fails any check; stale automatic caches are rebuilt, an explicit `.plume` input is
//! refused with the command that fixes it. A cache is **incompatible** with the render's
//! flags when they select other grids or map the source differently (the stored source
//! is already mapped): refused, naming the flag.

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::IVec3;

use super::format::InputFingerprint;
use super::reader::Cache;
use super::writer::{CacheInfo, CacheWriter, ProxySpec};
use crate::error::{Error, Result};
use crate::integrator::{light_power, LightSampling};
use crate::medium::EmissionKind;
use crate::scene::bind::{emission_kind, grid_requests, memory_budget, reader, unit_emission_model};
use crate::scene::{EmissionSettings, EmissionSource, JobSettings, ReadSettings, SceneDescription, VolumeInput};
use crate::stats::GIB;
use crate::vdb::{FileStamp, GridSelector, LeafData, ReadIsolation, ReadLimits, StreamedGrid};
use crate::volume::brick::{brick_of, check_same_transform, table_dims, Channel, Slot};
use crate::volume::Volume;

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

/// Message of the error a header visitor returns to stop a stream after its header.
const HEADER_ONLY: &str = "plume: header probe";

/// The header of grid `selector` in `file` (its topology is read, no values), or `None`
/// when the file has no such grid.
fn probe(isolation: &ReadIsolation, file: &Path, selector: &GridSelector, limits: &ReadLimits) -> Result<Option<StreamedGrid>> {
    let mut header = None;
    let result = isolation.stream_float_grid(
        file,
        selector,
        limits,
        &mut |h| {
            header = Some(h.clone());
            Err(Error::Scene(HEADER_ONLY.into()))
        },
        &mut |_, _| Ok(()),
    );
    match result {
        Ok(h) => Ok(Some(h)),
        Err(Error::Scene(m)) if m == HEADER_ONLY => Ok(header),
        Err(Error::GridNotFound { .. }) => Ok(None),
        Err(e) => Err(e),
    }
}

/// Convert the grids of `file` that `volume` selects (its `file` is not used), with
/// sources mapped as `emission` says, into the cache file `out`, storing a proxy of
/// `proxy_resolution` (default for the volume's size when `None`).
///
/// Streams: each grid's header first (topology only, for the table's box and the
/// transform checks), then each grid leaf by leaf into the writer, so neither plume nor
/// the reader ever holds a grid's values (`vdb::stream`).
///
/// # Errors
/// Unreadable input or grids, incompatible transforms, write errors.
pub fn convert(
    file: &Path,
    volume: &VolumeInput,
    emission: &EmissionSettings,
    reading: &ReadSettings,
    proxy_resolution: Option<u32>,
    out: &Path,
) -> Result<Converted> {
    let before = FileStamp::of(file).ok();
    let result = convert_unchecked(file, volume, emission, reading, proxy_resolution, out);
    // A file that changed during the conversion explains a reader that crashed or read
    // garbage (OpenVDB reads the zeros past a new end), and a conversion that succeeded
    // may hold leaves of two versions: either way the file failed under plume (exit code
    // 4). Errors of the output (a full disk) stay what they are.
    let input_error = result.as_ref().err().is_none_or(|e| e.exit_code() == crate::error::exit::INPUT);
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

fn convert_unchecked(
    file: &Path,
    volume: &VolumeInput,
    emission: &EmissionSettings,
    reading: &ReadSettings,
    proxy_resolution: Option<u32>,
    out: &Path,
) -> Result<Converted> {
    let start = Instant::now();
    let input = fingerprint(file)?;
    let (limits, isolation) = reader(reading)?;
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
    let (_, density_sel, density) = chosen.next().flatten().expect("invariant: the density request is required");
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
    let (lo, dims) = if lo.x > hi.x { (IVec3::ZERO, IVec3::ZERO) } else { (lo, table_dims(lo, hi, &density.name)?) };
    let mut writer = CacheWriter::create(out, w, lo, dims, &density.name)?;
    let mut backgrounds = [None; 3];
    let mut names: [Option<String>; 3] = Default::default();
    for (i, (channel, grid)) in channels.into_iter().enumerate() {
        let Some((sel, header)) = grid else { continue };
        let map = |v: f32| if channel == Channel::Source { emission.map_source(v) } else { v };
        backgrounds[i] = Some(map(header.background));
        names[i] = Some(header.name.clone());
        isolation.stream_float_grid(file, &sel, &limits, &mut |_| Ok(()), &mut |origin, data| match data {
            LeafData::Values(values) => writer.put(brick_of(origin), channel, values, map),
            LeafData::Constant(v) => writer.put_constant(brick_of(origin), channel, map(v)),
        })?;
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
    let proxy = (kind != EmissionKind::None).then(|| ProxySpec { resolution: proxy_resolution, power_key: emission.light_key(), power: &power });
    let path = writer.finish(&info, proxy)?;
    let bytes = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
    Ok(Converted { path, bytes, seconds: start.elapsed().as_secs_f64() })
}

/// The emission kind a render from `cache` uses, after checking that the description
/// does not ask for other grids or another kind.
///
/// # Errors
/// [`Error::InvalidArgument`] naming the key that disagrees with the cache.
pub fn check_description(cache: &Cache, grids: &VolumeInput, source: EmissionSource) -> Result<EmissionKind> {
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
            format!("{path} holds density grid {:?}, not {:?}; prepare it again with this density grid", meta.density_grid, grids.density_grid),
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
pub fn check_source_key(cache: &Cache, emission: &crate::medium::Emission) -> Result<()> {
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
        return Err(Error::Cache { path: cache.path.clone(), what: format!("stale: {} changed since it was prepared; run `plume prepare` again", input.path) });
    }
    Ok(())
}

/// Refuse light-sampling tables that would not fit `budget` bytes of anonymous memory.
///
/// # Errors
/// [`Error::InvalidArgument`] for `--memory-budget`, with the way out.
pub fn check_light_budget(volume: &Volume, light_sampling: LightSampling, budget: u64) -> Result<()> {
    if light_sampling != LightSampling::Nee {
        return Ok(());
    }
    // Classic NEE: an alias slot and index per emitting voxel, a record per brick, a table
    let emitting_voxels: u64 = volume
        .bricks
        .iter()
        .map(|b| match b.source.get() {
            Slot::Dense(_) => 512,
            Slot::Constant(s) if s != 0.0 => 512,
            Slot::Constant(_) => 0,
        })
        .sum();
    let needed = emitting_voxels * 24 + volume.table.len() as u64 * 4 + volume.bricks.len() as u64 * 16;
    if needed > budget {
        return Err(Error::invalid(
            "render.memory_budget",
            format!(
                "classic NEE would need about {:.2} GiB for its table of up to {emitting_voxels} emitting voxels, more than the budget of {:.2} GiB; \
                 use the line-fnee method (its proxy needs a few MiB) or raise the memory budget",
                needed as f64 / GIB,
                budget as f64 / GIB
            ),
        ));
    }
    Ok(())
}

/// Where the automatic cache of `input` lives: `render.cache_dir`, else beside the input,
/// else `$XDG_CACHE_HOME/plume` (or `~/.cache/plume`). The name carries a hash of the
/// grid bindings and source mapping, so renders with different grids or mappings keep
/// separate caches.
fn auto_cache_path(scene: &SceneDescription, input: &Path, settings: &JobSettings) -> PathBuf {
    use sha2::{Digest, Sha256};
    let (v, e) = (&scene.volume, &scene.emission);
    // The Debug texts are those of the flag enums before the scene description existed,
    // so caches made then are still found
    let key = format!(
        "{}|{:?}|{}|{:?}|{}|{}|{:?}|{:?}|{:?}",
        v.density_grid,
        e.source,
        v.temperature_grid,
        v.emission_grid,
        e.temperature_map,
        e.temperature_cutoff,
        e.convention,
        v.albedo_grid,
        scene.integrator.proxy_resolution
    );
    let hash = Sha256::digest(key.as_bytes());
    let tag: String = hash[..6].iter().map(|b| format!("{b:02x}")).collect();
    let name = format!("{}.{tag}.{}", input.file_name().map_or_else(|| "input".into(), |n| n.to_string_lossy()), super::EXTENSION);
    let writable = |d: &Path| {
        let probe = d.join(format!(".plume-probe-{}", std::process::id()));
        let ok = std::fs::File::create(&probe).is_ok();
        let _ = std::fs::remove_file(&probe);
        ok
    };
    if let Some(dir) = &settings.render.cache_dir {
        return dir.join(name);
    }
    let beside = crate::output::parent_dir(input);
    if writable(&beside) {
        return beside.join(name);
    }
    let base = std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))
        .unwrap_or_else(std::env::temp_dir);
    base.join("plume").join(name)
}

/// For a .vdb larger on disk than a quarter of the memory budget: its automatic cache,
/// converted now if missing, stale or damaged. `None` for smaller files (read in core).
///
/// # Errors
/// As [`convert`]; an unusable cache directory.
pub fn auto_cache(scene: &SceneDescription, input: &Path, settings: &JobSettings) -> Result<Option<Cache>> {
    let Ok(meta) = std::fs::metadata(input) else { return Ok(None) };
    let budget = memory_budget(settings);
    if meta.len().saturating_mul(4) <= budget {
        return Ok(None);
    }
    let path = auto_cache_path(scene, input, settings);
    if path.exists() {
        match Cache::open(&path).and_then(|c| check_not_stale(&c).map(|()| c)) {
            Ok(mut cache) => {
                cache.check.remove_on_failure();
                return Ok(Some(cache));
            }
            Err(e) => {
                eprintln!("plume: rebuilding the automatic cache ({e})");
                let _ = std::fs::remove_file(&path);
            }
        }
    }
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| Error::Write { path: dir.to_path_buf(), source: e })?;
    }
    eprintln!(
        "plume: {} is {:.2} GiB on disk, more than a quarter of the memory budget ({:.2} GiB, --memory-budget); \
         converting it once to the brick cache {}",
        input.display(),
        meta.len() as f64 / GIB,
        budget as f64 / GIB,
        path.display()
    );
    let c = convert(input, &scene.volume, &scene.emission, &settings.reading, scene.integrator.proxy_resolution, &path)?;
    eprintln!("plume: wrote {} ({:.2} GiB) in {:.1} s", c.path.display(), c.bytes as f64 / GIB, c.seconds);
    let mut cache = Cache::open(&c.path)?;
    cache.check.remove_on_failure();
    Ok(Some(cache))
}
