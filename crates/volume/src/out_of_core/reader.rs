//! [`Cache::open`]: map a brick cache file and hand out a [`Volume`] whose arrays are views
//! of the mapping, after checking everything that decides how the file is read.
//!
//! At open: the header (magic, version, byte order, checksum), the section table (every
//! section present once, page-aligned, inside the file, not overlapping), the CHUNKS
//! section's hash, and the chunk checksums of the metadata and of every section up to
//! [`EAGER_BYTES`]; then the metadata's sizes against the section lengths. Larger
//! sections (the values, and the table and pyramid of huge volumes) are checked by a
//! background thread while rendering starts ([`Verification`]); a render waits for it
//! before writing any output, so nothing computed from a damaged file is ever saved.
//! Until then, every index read from the file is bounds-checked with a harmless
//! fallback (`volume::brick`), so a damaged file cannot crash plume.
//!
//! A file that fails while mapped is not damaged but changed under plume: a page lost to
//! a truncation or an I/O error ends plume with one line and exit code 4 (`mapfault`);
//! a chunk the check cannot read, and a file at the path that is no longer the one
//! opened (device, inode, size, header page: truncated, rewritten, replaced, removed),
//! refuse the output with [`Error::InputFailed`], also exit code 4.

use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{DAffine3, DMat3, DVec3, IVec3};
use rayon::prelude::*;

use super::format::{
    Header, Meta, SectionEntry, SectionKind, BYTE_ORDER, CHUNK, MAGIC, PAGE, VERSION,
};
use super::lock::{Acquired, CacheLock};
use super::verify::{section_sums, Failure, Verification};
use crate::brick::Brick;
use crate::grid::LEAF_VOXELS;
use crate::out_of_core::mapfault::Mapping;
use crate::out_of_core::storage::Buffer;
use crate::proxy::CellPower;
use crate::pyramid::{level_dims, Level, NodeBounds, Pyramid};
use crate::Volume;
use plume_core::error::{Error, Result};

/// Sections up to this size are verified before [`Cache::open`] returns.
pub const EAGER_BYTES: u64 = 64 << 20;

/// How long [`CacheCheck::verified`] waits for the conversion lock before it leaves a
/// damaged automatic cache to the process holding it.
const REMOVE_LOCK_WAIT: std::time::Duration = std::time::Duration::from_secs(2);

/// An opened brick cache. See the module docs.
#[derive(Debug)]
pub struct Cache {
    /// The file.
    pub path: PathBuf,
    /// Its metadata.
    pub meta: Meta,
    /// The volume, mapped.
    pub volume: Volume,
    /// The stored FNEE proxy power, if any.
    pub proxy_power: Option<CellPower>,
    /// File size in bytes.
    pub file_bytes: u64,
    /// The background check; outlives the volume's use (see [`CacheCheck::verified`]).
    pub check: CacheCheck,
}

/// What a fault in a cache's mapping, or a failure of it while in use, calls the file.
const KIND: &str = "brick cache";

/// The background check of a cache's large sections, kept by whoever renders from it.
#[derive(Debug)]
pub struct CacheCheck {
    path: PathBuf,
    verification: Verification,
    remove_on_failure: bool,
    opened: Identity,
}

/// The file as it was opened: which file, its size and its header page (whose checksum
/// covers the chunk checksums, so equal pages mean equal contents).
#[derive(Debug)]
struct Identity {
    dev: u64,
    ino: u64,
    bytes: u64,
    header: Vec<u8>,
}

impl Identity {
    fn of(meta: &std::fs::Metadata, header: Vec<u8>) -> Identity {
        use std::os::unix::fs::MetadataExt;
        Identity { dev: meta.dev(), ino: meta.ino(), bytes: meta.len(), header }
    }

    /// How the file now at `path` differs from this one, if it does (`None` also for a
    /// replacement by a file of the same contents, e.g. an automatic cache rebuilt by
    /// another process).
    fn changed(&self, path: &Path) -> Option<String> {
        let now = match File::open(path).and_then(|mut f| {
            let meta = f.metadata()?;
            let mut header = vec![0u8; self.header.len()];
            f.read_exact(&mut header)
                .map(|()| header)
                .or_else(|_| Ok(Vec::new()))
                .map(|h| Identity::of(&meta, h))
        }) {
            Ok(now) => now,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Some("it was removed while in use".into())
            }
            Err(e) => return Some(format!("it cannot be opened again ({e})")),
        };
        let sizes = format!("{} bytes, {} when opened", now.bytes, self.bytes);
        if (now.dev, now.ino) != (self.dev, self.ino) {
            (now.bytes != self.bytes || now.header != self.header)
                .then(|| format!("it was replaced by another file while in use (now {sizes})"))
        } else if now.bytes < self.bytes {
            Some(format!("it was truncated while in use (now {sizes})"))
        } else if now.bytes != self.bytes || now.header != self.header {
            Some(format!("it was rewritten while in use (now {sizes})"))
        } else {
            None
        }
    }
}

impl CacheCheck {
    /// Wait for the background check of the large sections, then check that the file at
    /// the path is still the one opened (its device, inode, size and header page).
    ///
    /// # Errors
    /// [`Error::InputFailed`] (exit code 4) when the file was truncated, rewritten,
    /// replaced or removed while in use, or could not be read (an I/O error);
    /// [`Error::Cache`] naming the first chunk that failed its checksum (an automatic
    /// cache is then deleted, so the next run rebuilds it, unless another process has
    /// replaced it meanwhile: see `remove_damaged`).
    pub fn verified(&self) -> Result<()> {
        let outcome = self.verification.wait();
        let failed = |what: String| {
            Error::InputFailed {
            kind: KIND,
            path: self.path.clone(),
            what: format!("{what}; nothing computed from it was written (run the command again once the file is as it should be)"),
        }
        };
        // A file changed under the render explains any checksum failure, and is not
        // deleted: it may be another process's new file
        if let Some(what) = self.opened.changed(&self.path) {
            return Err(failed(what));
        }
        match outcome {
            Ok(()) => Ok(()),
            Err(Failure::Unreadable(what)) => Err(failed(what)),
            Err(Failure::Damaged(what)) if self.remove_on_failure => {
                Err(corrupt(&self.path, format!("{what}; {}", self.remove_damaged())))
            }
            Err(Failure::Damaged(what)) => Err(corrupt(&self.path, what)),
        }
    }

    /// Remove the damaged automatic cache, if the file at the path is still the one this
    /// check read; say what was done. Under the conversion lock ([`CacheLock`]), which every
    /// converter holds while it renames a new cache into place, so no new file can arrive
    /// between the comparison and the unlink: the identity compared (device and inode of
    /// the file opened against a fresh `stat` of the path) is the file's, not its bytes',
    /// as a rebuilt cache has the same size and header as the damaged one it replaces.
    /// A lock still held after [`REMOVE_LOCK_WAIT`] means another process is converting
    /// (its new cache will replace this one): the file is left to it. Where locks are not
    /// available, the comparison is made without one (converters cannot take one either).
    fn remove_damaged(&self) -> String {
        use std::os::unix::fs::MetadataExt;
        let _lock = match CacheLock::acquire(&self.path, REMOVE_LOCK_WAIT, None) {
            Ok(Acquired::Locked(lock)) => lock,
            Ok(Acquired::TimedOut { lock, .. }) => {
                return format!(
                    "left in place: another process holds its lock {} and is making a new one",
                    lock.display()
                );
            }
            Err(e) => return format!("left in place ({e})"),
        };
        match std::fs::metadata(&self.path) {
            Ok(now) if (now.dev(), now.ino()) != (self.opened.dev, self.opened.ino) => {
                "not removed: another process has already replaced this automatic cache with a new file; run the command again".into()
            }
            Ok(_) => match std::fs::remove_file(&self.path) {
                Ok(()) => "removed this automatic cache, the next run rebuilds it".into(),
                Err(e) => format!("cannot remove this automatic cache ({e})"),
            },
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => "another process has already removed it".into(),
            Err(e) => format!("left in place ({e})"),
        }
    }

    /// Delete the file if the check fails (for automatic caches, which plume owns).
    pub fn remove_on_failure(&mut self) {
        self.remove_on_failure = true;
    }
}

fn corrupt(path: &Path, what: impl std::fmt::Display) -> Error {
    Error::Cache {
        path: path.to_path_buf(),
        what: format!(
            "{what}; the file is damaged or not a plume cache (run `plume prepare` again)"
        ),
    }
}

/// Check the chunk sums of `entry` over `map`, chunks in parallel (at open).
fn check_section(
    map: &[u8],
    entry: &SectionEntry,
    sums: &[u64],
) -> std::result::Result<(), String> {
    let (kind, expected) = section_sums(entry, sums)?;
    let check = |i: usize| -> std::result::Result<(), String> {
        let start = entry.offset + i as u64 * CHUNK;
        let end = (start + CHUNK).min(entry.offset + entry.len);
        let bytes = &map[start as usize..end as usize];
        if xxhash_rust::xxh3::xxh3_64(bytes) == expected[i] {
            Ok(())
        } else {
            Err(format!("the {kind} section fails its checksum at bytes {start}..{end}"))
        }
    };
    (0..expected.len()).into_par_iter().try_for_each(check)
}

impl Cache {
    /// Open and check `path`. See the module docs.
    ///
    /// # Errors
    /// [`Error::Open`] when it cannot be opened; [`Error::Cache`] when it is not a cache,
    /// has another version, or fails a check.
    pub fn open(path: &Path) -> Result<Cache> {
        let mut file =
            File::open(path).map_err(|e| Error::Open { path: path.to_path_buf(), source: e })?;
        let file_meta =
            file.metadata().map_err(|e| Error::Open { path: path.to_path_buf(), source: e })?;
        let file_bytes = file_meta.len();
        let mut page = vec![0u8; PAGE as usize];
        let header_len = std::mem::size_of::<Header>();
        if file_bytes < PAGE || file.read_exact(&mut page).is_err() {
            return Err(corrupt(
                path,
                format!("{file_bytes} bytes is too short for a cache header"),
            ));
        }
        let header: Header = bytemuck::pod_read_unaligned(&page[..header_len]);
        if header.magic != MAGIC {
            return Err(corrupt(path, "no plume cache magic at the start"));
        }
        if header.byte_order != BYTE_ORDER {
            return Err(corrupt(path, "written with another byte order"));
        }
        if header.version != VERSION {
            return Err(Error::Cache {
                path: path.to_path_buf(),
                what: format!("format version {} is stale (this plume reads version {VERSION}); run `plume prepare` again", header.version),
            });
        }
        if header.compute_checksum() != header.checksum {
            return Err(corrupt(path, "the header fails its checksum"));
        }
        let mut entries = Vec::new();
        for kind in SectionKind::ALL {
            let e = *header
                .section(kind)
                .ok_or_else(|| corrupt(path, format!("no {} section", kind.name())))?;
            let end = e.offset.checked_add(e.len);
            if e.offset % PAGE != 0 || e.offset < PAGE || end.is_none_or(|end| end > file_bytes) {
                return Err(corrupt(
                    path,
                    format!(
                        "the {} section lies outside the file ({} bytes)",
                        kind.name(),
                        file_bytes
                    ),
                ));
            }
            entries.push(e);
        }
        let mut sorted = entries.clone();
        sorted.sort_by_key(|e| e.offset);
        if sorted.windows(2).any(|w| w[0].offset + w[0].len > w[1].offset) {
            return Err(corrupt(path, "sections overlap"));
        }
        let section = |k: SectionKind| {
            entries[SectionKind::ALL.iter().position(|x| *x == k).expect("invariant: all kinds")]
        };
        // Watched: if another process truncates the file while it is mapped, or its
        // storage fails, touching a lost page ends plume with a line naming the file
        // (`mapfault`), here or during the render
        let map = Arc::new(
            Mapping::map(&file, path, KIND)
                .map_err(|e| Error::Open { path: path.to_path_buf(), source: e })?,
        );
        let chunks = section(SectionKind::Chunks);
        let chunk_bytes = &map[chunks.offset as usize..(chunks.offset + chunks.len) as usize];
        if xxhash_rust::xxh3::xxh3_64(chunk_bytes) != chunks.checksum || chunks.len % 8 != 0 {
            return Err(corrupt(path, "the chunk checksum section fails its checksum"));
        }
        let sums: Arc<Vec<u64>> = Arc::new(bytemuck::pod_collect_to_vec(chunk_bytes));
        // Metadata and small sections now; large ones in the background
        let mut deferred = Vec::new();
        for e in entries.iter().filter(|e| e.kind != SectionKind::Chunks as u32) {
            if e.len <= EAGER_BYTES || e.kind == SectionKind::Meta as u32 {
                check_section(&map, e, &sums).map_err(|what| corrupt(path, what))?;
            } else {
                deferred.push(*e);
            }
        }
        let meta_entry = section(SectionKind::Meta);
        let meta: Meta = serde_json::from_slice(
            &map[meta_entry.offset as usize..(meta_entry.offset + meta_entry.len) as usize],
        )
        .map_err(|e| corrupt(path, format!("unreadable metadata ({e})")))?;
        let (volume, proxy_power) = Self::assemble(path, &map, &meta, &section)?;
        let verification = if deferred.is_empty() {
            Verification::done()
        } else {
            Verification::start(file, Arc::clone(&map), &deferred, &sums)
                .map_err(|e| Error::Open { path: path.to_path_buf(), source: e })?
        };
        let opened = Identity::of(&file_meta, page);
        let check =
            CacheCheck { path: path.to_path_buf(), verification, remove_on_failure: false, opened };
        Ok(Cache { path: path.to_path_buf(), meta, volume, proxy_power, file_bytes, check })
    }

    /// Build the mapped volume after checking the metadata against the section sizes.
    fn assemble(
        path: &Path,
        map: &Arc<Mapping>,
        meta: &Meta,
        section: &dyn Fn(SectionKind) -> SectionEntry,
    ) -> Result<(Volume, Option<CellPower>)> {
        let w = meta.world_from_index;
        let world_from_index = DAffine3::from_mat3_translation(
            DMat3::from_cols_array(&[w[0], w[1], w[2], w[3], w[4], w[5], w[6], w[7], w[8]]),
            DVec3::new(w[9], w[10], w[11]),
        );
        if !world_from_index.is_finite() || world_from_index.matrix3.determinant() == 0.0 {
            return Err(corrupt(path, "its transform is singular or not finite"));
        }
        let dims = IVec3::from_array(meta.dims);
        let brick_lo = IVec3::from_array(meta.brick_lo);
        if dims.cmplt(IVec3::ZERO).any()
            || (brick_lo.as_i64vec3() + dims.as_i64vec3()).max_element() > i64::from(i32::MAX / 8)
        {
            return Err(corrupt(path, format!("its brick table {dims} at {brick_lo} is invalid")));
        }
        let cells = dims.x as u64 * dims.y as u64 * dims.z as u64;
        let nodes: u64 =
            level_dims(dims).iter().map(|d| d.x as u64 * d.y as u64 * d.z as u64).sum();
        let expect = [
            (SectionKind::Table, cells * 4),
            (SectionKind::Bricks, meta.brick_count * std::mem::size_of::<Brick>() as u64),
            (SectionKind::Values, meta.value_blocks * LEAF_VOXELS as u64 * 4),
            (SectionKind::Pyramid, nodes * std::mem::size_of::<NodeBounds>() as u64),
        ];
        for (kind, bytes) in expect {
            if section(kind).len != bytes {
                return Err(corrupt(
                    path,
                    format!(
                        "the {} section holds {} bytes, its metadata says {bytes}",
                        kind.name(),
                        section(kind).len
                    ),
                ));
            }
        }
        let view = |kind: SectionKind| (section(kind).offset as usize, section(kind).len as usize);
        let bad =
            |kind: SectionKind| corrupt(path, format!("the {} section is misaligned", kind.name()));
        let (o, n) = view(SectionKind::Table);
        let table = Buffer::<u32>::mapped(map, o, n).ok_or_else(|| bad(SectionKind::Table))?;
        let (o, n) = view(SectionKind::Bricks);
        let bricks = Buffer::<Brick>::mapped(map, o, n).ok_or_else(|| bad(SectionKind::Bricks))?;
        let (o, n) = view(SectionKind::Values);
        let values = Buffer::<f32>::mapped(map, o, n).ok_or_else(|| bad(SectionKind::Values))?;
        let (mut o, _) = view(SectionKind::Pyramid);
        let mut levels = Vec::new();
        for d in level_dims(dims) {
            let n = d.x as usize * d.y as usize * d.z as usize * std::mem::size_of::<NodeBounds>();
            let nodes =
                Buffer::<NodeBounds>::mapped(map, o, n).ok_or_else(|| bad(SectionKind::Pyramid))?;
            levels.push(Level { dims: d, nodes });
            o += n;
        }
        let (o, n) = view(SectionKind::Proxy);
        let proxy_power = match &meta.proxy {
            Some(p) if n % 8 == 0 => Some(CellPower {
                resolution: p.resolution,
                sums: bytemuck::pod_collect_to_vec(&map[o..o + n]),
            }),
            Some(_) => return Err(corrupt(path, "the proxy section is not whole f64s")),
            None => None,
        };
        let volume = Volume::from_parts(
            world_from_index,
            brick_lo,
            dims,
            table,
            bricks,
            values,
            Pyramid { levels },
            meta.report,
        );
        Ok((volume, proxy_power))
    }
}
