//! Out of core: volumes larger than memory.
//!
//! A `.vdb` is converted once (by the application's loading code) into a brick cache
//! file (`plume prepare`, or an automatic cache), which is memory-mapped: the bricks,
//! pyramid and FNEE proxy an in-core build would hold, produced by the same code, so a
//! render from the cache is bit-identical to the in-core render of the same data. The OS
//! pages bricks in on demand while the resident anonymous memory stays within the budget.
//!
//! - [`mod@format`]: the file layout (sections, checksums, metadata).
//! - [`writer`]: [`CacheWriter`], streaming bricks in and writing the derived sections.
//! - [`reader`]: [`Cache::open`], its checks, and a mapped [`crate::Volume`].
//! - [`verify`]: the background checksum pass over the large sections.
//! - [`storage`]: [`storage::Buffer`], a read-only array on the heap or in a mapped file.
//! - [`mapfault`]: the only way plume maps a file; a page that fails under plume (the
//!   file truncated or its storage failing) ends the process with one line and exit
//!   code 4 instead of a death by SIGBUS.
//! - [`memory`]: the memory this process may use (RAM, `MemAvailable`, cgroup v1 and v2
//!   limits at every level), which sets the default budget and the sample order.
//! - [`prefetch`]: read-ahead of the bricks that the next tiles' rays cross, in
//!   tile-major order.
//!
//! The engine's side of out of core is the tile-major pass (`plume_engine::render`),
//! scattered paths deferred into rounds that read the file in order
//! (`plume_engine::integrator::deferred`), and classic NEE's per-brick table
//! (`plume_engine::light::nee_bricks`), which needs no memory per voxel.
//!
//! **Invariant:** a cache is never rendered from unless every check passed; a cache that
//! fails one is an error naming the file, never a wrong image.

pub mod format;
pub mod lock;
pub mod mapfault;
pub mod memory;
pub mod prefetch;
pub mod reader;
pub mod storage;
pub mod verify;
pub mod writer;

pub use format::{InputFingerprint, Meta};
pub use reader::{Cache, CacheCheck};
pub use writer::{write_volume, CacheInfo, CacheWriter, ProxySpec};

/// File extension of cache files.
pub const EXTENSION: &str = "plume";

/// True when `path` names a cache file (by extension).
#[must_use]
pub fn is_cache_path(path: &std::path::Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case(EXTENSION))
}
