//! Brick cache files (`plume prepare`): a volume converted once into a memory-mappable
//! file, so volumes larger than memory render with resident anonymous memory bounded by
//! `--memory-budget` while the OS pages bricks in on demand.
//!
//! - [`mod@format`]: the layout (sections, checksums, metadata).
//! - [`writer`]: [`CacheWriter`], streaming bricks in and writing the derived sections.
//! - [`reader`]: [`Cache::open`], checks and a mapped [`crate::volume::Volume`].
//! - [`verify`]: the background checksum pass over the large sections.
//! - [`convert`]: `.vdb` → cache (`plume prepare`, and the automatic cache of `plume
//!   render` for inputs too large for `--memory-budget`), staleness and flag checks.
//! - [`lock`]: the advisory lock of an automatic cache's conversion, with a bounded wait.
//!
//! A cache stores what an in-core build would hold, produced by the same code (the brick
//! table builder, the pyramid from per-brick bounds, the proxy's per-cell power sum), so
//! a render from it is bit-identical to the in-core render of the same data.

pub mod convert;
pub mod format;
pub mod generate;
pub mod lock;
pub mod reader;
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
