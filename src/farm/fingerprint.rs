//! What identifies a frame's pixels: the SHA-256 of the input file and a hash of the
//! settings. Parts of a frame merge only if both agree; an existing output is skipped or
//! continued only if its settings hash matches.

use std::io::Read;
use std::path::Path;

use sha2::{Digest, Sha256};

use crate::cli::RenderArgs;
use crate::error::{Error, Result};

/// Hex SHA-256 of a file's bytes and its size.
///
/// # Errors
/// [`Error::Open`] naming the file.
///
/// A brick cache file (`.plume`) is identified by its header page instead: the header
/// holds the hash of the chunk checksums, which cover every other byte, so hashing 4 KiB
/// identifies a file of tens of GB (its size is still the file's).
pub fn file_sha256(path: &Path) -> Result<(String, u64)> {
    let open = |source| Error::Open { path: path.to_path_buf(), source };
    let mut file = std::fs::File::open(path).map_err(open)?;
    let mut hasher = Sha256::new();
    if crate::cache::is_cache_path(path) {
        let size = file.metadata().map_err(open)?.len();
        let mut page = vec![0u8; crate::cache::format::PAGE as usize];
        let n = file.read(&mut page).map_err(open)?;
        hasher.update(&page[..n]);
        return Ok((hex(&hasher.finalize()), size));
    }
    let mut buf = vec![0u8; 1 << 20];
    let mut bytes = 0u64;
    loop {
        let n = file.read(&mut buf).map_err(open)?;
        if n == 0 {
            break;
        }
        hasher.update(&buf[..n]);
        bytes += n as u64;
    }
    Ok((hex(&hasher.finalize()), bytes))
}

/// Hash (32 hex digits) of the plume version, the seed and every render flag that can
/// change pixels.
///
/// Fail-safe by construction: it hashes the `Debug` text of all of [`RenderArgs`] after
/// blanking the fields known not to change pixels values (paths, threads, sample budget
/// and range, crop, progress, logging, limits), so a flag added later counts until it is
/// listed here.
#[must_use]
pub fn settings_hash(args: &RenderArgs, seed: u64) -> String {
    let mut a = args.clone();
    a.file = Default::default();
    a.output = Default::default();
    a.spp = None;
    a.time = None;
    a.seed = None;
    a.threads = 0;
    a.debug_pixel = None;
    a.preview = None;
    a.exposure = None;
    a.stats = None;
    a.grids.max_input_memory = None;
    a.memory_budget = None;
    a.cache_dir = None;
    a.grids.read_timeout = 0.0;
    a.grids.no_isolation = false;
    a.quiet = false;
    a.frames = None;
    a.overwrite = false;
    a.time_limit = None;
    a.crop = None;
    a.tile = None;
    a.sample_range = None;
    a.sums = false;
    a.progress = crate::cli::ProgressArg::None;
    let text = format!("plume {}\nseed {seed}\nfixed point {}\n{a:?}", env!("CARGO_PKG_VERSION"), crate::film::FIXED_POINT_BITS);
    hex(&Sha256::digest(text.as_bytes())[..16])
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    fn args(extra: &[&str]) -> RenderArgs {
        let mut v = vec!["plume", "render", "in.vdb", "-o", "out.exr"];
        v.extend_from_slice(extra);
        match crate::cli::Cli::parse_from(v).command {
            crate::cli::Command::Render(a) => *a,
            _ => unreachable!(),
        }
    }

    #[test]
    fn settings_hash_ignores_what_does_not_change_pixels() {
        let base = settings_hash(&args(&[]), 1);
        assert_eq!(base.len(), 32);
        assert_eq!(settings_hash(&args(&["--threads", "3", "--spp", "9", "--tile", "1/4", "-q"]), 1), base);
        assert_eq!(settings_hash(&args(&["--sample-range", "0..4", "--stats", "s.json", "--progress", "openjd"]), 1), base);
        assert_ne!(settings_hash(&args(&["--density-scale", "2"]), 1), base);
        assert_ne!(settings_hash(&args(&["--width", "20"]), 1), base);
        assert_ne!(settings_hash(&args(&[]), 2), base);
    }
}
