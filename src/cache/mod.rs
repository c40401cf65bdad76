//! Brick cache conversion: a `.vdb` turned into a `.plume` cache (`plume prepare`, and
//! the automatic cache of `plume render` for inputs too large for the memory budget),
//! with staleness and description checks ([`convert`], [`checks`]), where automatic caches
//! live and the advisory lock of an automatic conversion (`auto`,
//! `plume_volume::out_of_core::lock`), grid headers read without values (`headers`), and
//! generators written straight to a cache ([`generate`]). The cache format, reader and
//! writer are `plume_volume::out_of_core`.

mod auto;
pub mod checks;
pub mod convert;
pub mod generate;
mod headers;

pub use plume_volume::out_of_core::{
    is_cache_path, Cache, CacheCheck, CacheInfo, CacheWriter, InputFingerprint, Meta, ProxySpec,
    EXTENSION,
};
