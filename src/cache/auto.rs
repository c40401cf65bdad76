//! Where automatic brick caches live and how a render waits for one: the cache's file
//! name ([`auto_cache_name`]), the places it may be kept ([`cache_places`]), whether a file
//! there may be used ([`open_auto`]) or made ([`writable`]), how long a render waits for
//! another process making it ([`lock_timeout`]), and what it does when it waited in vain
//! ([`locked_out`]). The conversion that uses them is `cache::convert::auto_cache`.

use std::path::{Path, PathBuf};
use std::time::Duration;

use super::checks::check_not_stale;
use super::headers::in_core_bytes;
use plume_core::error::{Error, Result};
use plume_engine::stats::GIB;
use plume_scene::{JobSettings, SceneDescription};
use plume_volume::out_of_core::reader::Cache;
use plume_volume::out_of_core::EXTENSION;

/// The automatic cache's file name: the input's name and a hash of the grid bindings and
/// source mapping, so renders with different grids or mappings keep separate caches.
pub(super) fn auto_cache_name(scene: &SceneDescription, input: &Path) -> String {
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
        EXTENSION
    )
}

/// A directory an automatic cache may live in, and how the user knows it.
pub(super) struct Place {
    /// The directory.
    pub(super) dir: PathBuf,
    /// How the user knows it.
    pub(super) what: &'static str,
}

/// Where the automatic cache of `input` may live, in order: only `render.cache_dir` when
/// it is given; otherwise beside the input, then `render.user_cache_dir` when the
/// application gave one (the binary: `$XDG_CACHE_HOME/plume`, or `~/.cache/plume`, or
/// `plume` in the temporary directory without a home).
pub(super) fn cache_places(input: &Path, settings: &JobSettings) -> Vec<Place> {
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
pub(super) fn open_auto(path: &Path) -> Result<Option<Cache>> {
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
pub(super) fn writable(dir: &Path, path: &Path) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let probe = plume_core::fs::temporary_path(path);
    std::fs::File::create(&probe)?;
    std::fs::remove_file(&probe)
}

/// `bytes` for messages: GiB from 1 GiB on, MiB below.
pub(super) fn size(bytes: u64) -> String {
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

/// After waiting `waited` in vain for the `lock` of the automatic cache `path`: `Ok` (with
/// a warning) when `input` read into memory fits the memory `budget`, so the frame is
/// rendered without the cache; the error otherwise.
pub(super) fn locked_out(
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
