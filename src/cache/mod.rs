//! Brick cache conversion: a `.vdb` turned into a `.plume` cache (`plume prepare`, and
//! the automatic cache of `plume render` for inputs too large for the memory budget),
//! with staleness and description checks ([`convert`]), the advisory lock of an automatic
//! conversion (`plume_volume::out_of_core::lock`) and generators written straight to a cache ([`generate`]). The
//! cache format, reader and writer are `plume_volume::out_of_core`.

pub mod convert;
pub mod generate;

pub use plume_volume::out_of_core::{
    is_cache_path, Cache, CacheCheck, CacheInfo, CacheWriter, InputFingerprint, Meta, ProxySpec,
    EXTENSION,
};
