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
use std::time::{Duration, Instant};

use glam::IVec3;

use crate::load::bind::{emission_kind, grid_requests, reader, unit_emission_model, FileReader};
use crate::vdb::{FileStamp, GridSelector, LeafData, ReadIsolation, ReadLimits, StreamedGrid};
use plume_core::error::{Error, Result};
use plume_engine::integrator::{light_power, LightSampling};
use plume_engine::medium::EmissionKind;
use plume_engine::stats::GIB;
use plume_scene::NeeTable;
use plume_scene::{
    EmissionSettings, EmissionSource, JobSettings, ReadSettings, SceneDescription, VolumeInput,
};
use plume_volume::brick::{brick_of, check_same_transform, table_dims, Channel, Slot};
use plume_volume::out_of_core::format::InputFingerprint;
use plume_volume::out_of_core::lock::{Acquired, CacheLock};
use plume_volume::out_of_core::reader::Cache;
use plume_volume::out_of_core::writer::{CacheInfo, CacheWriter, ProxySpec};
use plume_volume::Volume;

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
fn probe(
    isolation: &ReadIsolation,
    file: &Path,
    selector: &GridSelector,
    limits: &ReadLimits,
) -> Result<Option<StreamedGrid>> {
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

/// The automatic cache's file name: the input's name and a hash of the grid bindings and
/// source mapping, so renders with different grids or mappings keep separate caches.
fn auto_cache_name(scene: &SceneDescription, input: &Path) -> String {
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
    format!(
        "{}.{tag}.{}",
        input.file_name().map_or_else(|| "input".into(), |n| n.to_string_lossy()),
        super::EXTENSION
    )
}

/// A directory an automatic cache may live in, and how the user knows it.
struct Place {
    dir: PathBuf,
    what: &'static str,
}

/// Where the automatic cache of `input` may live, in order: only `render.cache_dir` when
/// it is given; otherwise beside the input, then `render.user_cache_dir` when the
/// application gave one (the binary: `$XDG_CACHE_HOME/plume`, or `~/.cache/plume`, or
/// `plume` in the temporary directory without a home).
fn cache_places(input: &Path, settings: &JobSettings) -> Vec<Place> {
    if let Some(dir) = &settings.render.cache_dir {
        return vec![Place { dir: dir.clone(), what: "render.cache_dir" }];
    }
    let mut places =
        vec![Place { dir: plume_core::fs::parent_dir(input), what: "beside the input" }];
    if let Some(user) = &settings.render.user_cache_dir {
        places.push(Place { dir: user.clone(), what: "$XDG_CACHE_HOME/plume" });
    }
    places
}

/// The automatic cache at `path` if it may be rendered (complete and current; it is
/// deleted if its background check fails later); `None` when there is none; `Err` saying
/// why the file there may not be used.
fn open_auto(path: &Path) -> Result<Option<Cache>> {
    if !path.exists() {
        return Ok(None);
    }
    let mut cache = Cache::open(path).and_then(|c| check_not_stale(&c).map(|()| c))?;
    cache.check.remove_on_failure();
    Ok(Some(cache))
}

/// Whether a cache can be made at `path`: its directory exists or can be created, and
/// takes a new file (a probe named like the writer's temporary, so that one left by a
/// killed process is cleaned up).
fn writable(dir: &Path, path: &Path) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let probe = plume_core::fs::temporary_path(path);
    std::fs::File::create(&probe)?;
    std::fs::remove_file(&probe)
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

/// `bytes` for messages: GiB from 1 GiB on, MiB below.
fn size(bytes: u64) -> String {
    if bytes as f64 >= GIB {
        format!("{:.2} GiB", bytes as f64 / GIB)
    } else {
        format!("{:.1} MiB", bytes as f64 / (1u64 << 20) as f64)
    }
}

/// How long a render waits for another process making the same automatic cache before it
/// gives up: `render.cache_lock_timeout`, or by default 10 minutes plus 1 s per 10 MB of
/// the `.vdb`, so that a conversion ten times slower than on a small 2-core machine still
/// finishes within it (docs/out-of-core.md, "Farm nodes sharing a cache directory").
#[must_use]
pub fn lock_timeout(settings: &JobSettings, input_bytes: u64) -> Duration {
    match settings.render.cache_lock_timeout {
        Some(seconds) => Duration::try_from_secs_f64(seconds).unwrap_or(Duration::MAX),
        None => DEFAULT_LOCK_WAIT + Duration::from_secs(input_bytes / LOCK_WAIT_BYTES_PER_SECOND),
    }
}

/// The fixed part of the default [`lock_timeout`].
const DEFAULT_LOCK_WAIT: Duration = Duration::from_secs(600);
/// The rate of conversion the default [`lock_timeout`] allows for (bytes of `.vdb` per second).
const LOCK_WAIT_BYTES_PER_SECOND: u64 = 10_000_000;

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

/// After waiting `waited` in vain for the `lock` of the automatic cache `path`: `Ok` (with
/// a warning) when `input` read into memory fits the memory `budget`, so the frame is
/// rendered without the cache; the error otherwise.
fn locked_out(
    scene: &SceneDescription,
    input: &Path,
    settings: &JobSettings,
    path: &Path,
    lock: &Path,
    waited: Duration,
    budget: u64,
) -> Result<()> {
    let held = format!(
        "another process has held this lock for {:.1} s (render.cache_lock_timeout) while making the automatic brick cache {}",
        waited.as_secs_f64(),
        path.display()
    );
    let needed = in_core_bytes(scene, input, settings)?;
    if needed <= budget {
        log::warn!(
            "{}: {held}; reading {} into memory instead (about {}, within the memory budget of {})",
            lock.display(),
            input.display(),
            size(needed),
            size(budget)
        );
        return Ok(());
    }
    Err(Error::CacheLocked {
        lock: lock.to_path_buf(),
        what: format!(
            "{held}, and reading {} into memory instead would need about {}, more than the memory budget of {} (render.memory_budget); \
             run the command again once that process has finished (or end it, if it hangs)",
            input.display(),
            size(needed),
            size(budget)
        ),
    })
}

/// Peak memory of reading `input` in core, estimated from its grids' headers (topology
/// only): the values of every leaf of the grids the description selects, twice (the
/// grids as read, and the volume built from them while they are still held).
///
/// # Errors
/// As reading the headers.
fn in_core_bytes(scene: &SceneDescription, input: &Path, settings: &JobSettings) -> Result<u64> {
    let FileReader { limits, isolation } = reader(&settings.reading)?;
    let mut leaves = 0u64;
    for request in grid_requests(&scene.volume, scene.emission.source)? {
        for sel in &request.alternatives {
            if let Some(h) = probe(&isolation, input, sel, &limits)? {
                leaves += h.leaf_count;
                break;
            }
        }
    }
    Ok(leaves.saturating_mul(2 * plume_volume::grid::LEAF_VOXELS as u64 * 4))
}
