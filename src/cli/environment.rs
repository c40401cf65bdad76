//! What the binary reads from its environment for the library, which reads none: the
//! working directory, the user's cache directory and the benchmarks' scratch directory.

use std::path::PathBuf;

/// The working directory, against which scene descriptions written out are made
/// absolute (empty, so relative paths stay relative, when it cannot be found).
#[must_use]
pub fn working_dir() -> PathBuf {
    std::env::current_dir().unwrap_or_default()
}

/// Where automatic brick caches go when the input's directory cannot be written
/// (`render.user_cache_dir`): `$XDG_CACHE_HOME/plume`, else `~/.cache/plume`, else
/// `plume` in the temporary directory.
#[must_use]
pub fn user_cache_dir() -> PathBuf {
    std::env::var_os("XDG_CACHE_HOME")
        .filter(|d| !d.is_empty())
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))
        .unwrap_or_else(std::env::temp_dir)
        .join("plume")
}

/// Where benchmarks write generated scenes by default: `plume-bench` in the temporary
/// directory.
#[must_use]
pub fn bench_work_dir() -> PathBuf {
    std::env::temp_dir().join("plume-bench")
}
