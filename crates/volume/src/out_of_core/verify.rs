//! The background check of a cache's large sections ([`Verification`]): every 1 MiB chunk
//! hashed with xxh3 against the CHUNKS section before a render may save anything.
//!
//! A render of a cache larger than memory reads the file from disk once at best, and a
//! check that read it all again would double the disk traffic and take CPU from the
//! render. So the check runs in two phases, at the lowest CPU priority (`nice` 19):
//!
//! 1. **While rendering**, in a sweep every second, it hashes what is in the page cache
//!    (`mincore`), straight from the mapping: no disk read, no copy, and nothing evicted.
//!    The render's own reads are what brings pages in. A chunk is hashed as a stream
//!    (xxh3's streaming state gives the one-shot sum), from its first unhashed page up
//!    to the next page not in memory, so a chunk whose pages the render reads at
//!    different times is still hashed in pieces. Out of core this matters: the render
//!    keeps only part of the file in memory at a time, so few 1 MiB chunks are ever
//!    wholly resident at once (docs/out-of-core.md, "Checks and faults").
//! 2. **When the render asks for the outcome** ([`Verification::wait`]), it reads what
//!    is still unhashed from the file (`pread`: of a chunk, only the pages after its
//!    hashed prefix) and lets the kernel drop those pages again (`POSIX_FADV_DONTNEED`),
//!    so it does not push the render's working set out.
//!
//! Every byte is checked either way; only the order and the I/O differ.

use std::fs::File;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::thread::JoinHandle;
use std::time::Duration;

use memmap2::Mmap;
use xxhash_rust::xxh3::{xxh3_64, Xxh3Default};

use crate::out_of_core::mapfault::Mapping;

use super::format::{SectionEntry, SectionKind, CHUNK};

/// Time between two sweeps of phase 1.
const SWEEP_INTERVAL: Duration = Duration::from_secs(1);
/// CPU niceness of the checking thread.
const NICENESS: libc::c_int = 19;

/// Why a check failed.
#[derive(Clone, Debug, PartialEq)]
pub enum Failure {
    /// Bytes that do not match their checksum: the file is damaged (or was rewritten
    /// while in use, which `CacheCheck` tells apart by the file's header and size).
    Damaged(String),
    /// Bytes that could not be read: the file shrank since it was opened, or its storage
    /// returned an I/O error.
    Unreadable(String),
}

/// The outcome of a check.
pub type Outcome = std::result::Result<(), Failure>;

/// The outcome of checking a cache's large sections in the background.
#[derive(Debug)]
pub struct Verification {
    thread: Mutex<Option<JoinHandle<Outcome>>>,
    /// Set by [`Verification::wait`]: check the rest now, reading the file.
    finish: Arc<AtomicBool>,
    outcome: OnceLock<Outcome>,
}

/// One chunk to check: its bytes in the file, the expected sum, and its section's name.
#[derive(Clone, Copy, Debug)]
struct Chunk {
    start: u64,
    end: u64,
    sum: u64,
    kind: &'static str,
}

impl Chunk {
    fn failed(&self) -> Failure {
        Failure::Damaged(format!(
            "the {} section fails its checksum at bytes {}..{}",
            self.kind, self.start, self.end
        ))
    }

    fn unreadable(&self, e: &std::io::Error) -> Failure {
        Failure::Unreadable(if e.kind() == std::io::ErrorKind::UnexpectedEof {
            format!(
                "the file ends before byte {} (the {} section): it was truncated while in use",
                self.end, self.kind
            )
        } else {
            format!("byte {} (the {} section) cannot be read: {e}", self.start, self.kind)
        })
    }
}

/// The name of `entry`'s section and its expected chunk sums.
pub(super) fn section_sums<'s>(
    entry: &SectionEntry,
    sums: &'s [u64],
) -> std::result::Result<(&'static str, &'s [u64]), String> {
    let kind =
        SectionKind::ALL.iter().find(|k| **k as u32 == entry.kind).map_or("unknown", |k| k.name());
    let first = entry.first_chunk as usize;
    match sums.get(first..first + entry.chunk_count() as usize) {
        Some(expected) => Ok((kind, expected)),
        None => Err(format!("the {kind} section's chunk checksums are missing")),
    }
}

impl Verification {
    /// Nothing to check.
    pub(super) fn done() -> Verification {
        Verification::finished(Ok(()))
    }

    fn finished(outcome: Outcome) -> Verification {
        Verification {
            thread: Mutex::new(None),
            finish: Arc::new(AtomicBool::new(true)),
            outcome: OnceLock::from(outcome),
        }
    }

    /// Start checking `sections` of the file behind `map` against `sums`.
    ///
    /// # Errors
    /// The thread cannot be started.
    pub(super) fn start(
        file: File,
        map: Arc<Mapping>,
        sections: &[SectionEntry],
        sums: &[u64],
    ) -> std::io::Result<Verification> {
        let mut chunks = Vec::new();
        for entry in sections {
            match section_sums(entry, sums) {
                Ok((kind, expected)) => {
                    chunks.extend(expected.iter().enumerate().map(|(i, &sum)| {
                        let start = entry.offset + i as u64 * CHUNK;
                        Chunk {
                            start,
                            end: (start + CHUNK).min(entry.offset + entry.len),
                            sum,
                            kind,
                        }
                    }))
                }
                Err(what) => return Ok(Verification::finished(Err(Failure::Damaged(what)))),
            }
        }
        let finish = Arc::new(AtomicBool::new(false));
        let flag = Arc::clone(&finish);
        let handle =
            std::thread::Builder::new().name("plume-cache-verify".into()).spawn(move || {
                // SAFETY: setpriority on this thread's own id only lowers its CPU priority.
                unsafe {
                    libc::setpriority(libc::PRIO_PROCESS, libc::gettid() as libc::id_t, NICENESS);
                }
                check(&file, &map, chunks, &flag)
            })?;
        Ok(Verification { thread: Mutex::new(Some(handle)), finish, outcome: OnceLock::new() })
    }

    /// Finish the check (reading what the render did not bring into memory) and return
    /// its outcome.
    ///
    /// # Errors
    /// The first chunk that failed, described.
    pub fn wait(&self) -> Outcome {
        self.outcome
            .get_or_init(|| {
                self.finish.store(true, Ordering::Relaxed);
                let handle = self.thread.lock().map(|mut t| t.take()).ok().flatten();
                match handle {
                    Some(h) => {
                        h.thread().unpark();
                        h.join().unwrap_or_else(|_| {
                            Err(Failure::Damaged("the verifier thread panicked".into()))
                        })
                    }
                    None => Ok(()),
                }
            })
            .clone()
    }
}

/// Page size the residency of a mapping is asked in.
const PAGE: usize = 4096;

/// A chunk being checked: its first `hashed` bytes are fed to `state` (`None` until a
/// part of it has been hashed; a chunk hashed whole at once never needs one).
struct Progress {
    chunk: Chunk,
    hashed: usize,
    state: Option<Box<Xxh3Default>>,
}

impl Progress {
    fn new(chunk: Chunk) -> Progress {
        Progress { chunk, hashed: 0, state: None }
    }

    fn len(&self) -> usize {
        (self.chunk.end - self.chunk.start) as usize
    }

    /// Hash the next `bytes` (following the prefix already hashed); `Some(outcome)` once
    /// the chunk is complete.
    fn feed(&mut self, bytes: &[u8]) -> Option<Outcome> {
        let len = self.len();
        let sum = if self.hashed == 0 && bytes.len() == len {
            xxh3_64(bytes)
        } else {
            let state = self.state.get_or_insert_with(|| Box::new(Xxh3Default::new()));
            state.update(bytes);
            self.hashed += bytes.len();
            if self.hashed < len {
                return None;
            }
            state.digest()
        };
        Some(if sum == self.chunk.sum { Ok(()) } else { Err(self.chunk.failed()) })
    }

    /// Phase 1: hash the pages after the prefix that are in memory now, up to the first
    /// that is not; `Some(outcome)` once the chunk is complete.
    fn advance(&mut self, map: &Mmap, scratch: &mut Vec<u8>) -> Option<Outcome> {
        let from = self.chunk.start as usize + self.hashed;
        let resident = resident_prefix(map, from, self.len() - self.hashed, scratch);
        if resident == 0 {
            return None;
        }
        let whole = self.hashed == 0 && resident == self.len();
        let outcome = self.feed(&map[from..from + resident]);
        if !whole {
            // A chunk in memory only in part: the file does not fit, and reading the pages
            // marked them as used. Age them again (`MADV_COLD`), or the check would keep
            // pages in memory that the render is done with, and a render out of core would
            // read more of the file again (measured in docs/BENCHMARKS.md, "Out of core with
            // scattering")
            // SAFETY: the range lies inside the mapping and starts on a page boundary; the
            // advice only moves clean file pages on the kernel's reclaim lists.
            unsafe {
                libc::madvise(
                    map.as_ptr().add(from) as *mut libc::c_void,
                    resident,
                    libc::MADV_COLD,
                );
            }
        }
        outcome
    }

    /// Phase 2: read the rest of the chunk from the file and finish its sum, then let the
    /// kernel drop those pages (it does so only for pages nobody has mapped), so the check
    /// does not evict the render's pages.
    fn finish_by_reading(&mut self, file: &File, buf: &mut [u8]) -> Outcome {
        use std::os::fd::AsRawFd;
        use std::os::unix::fs::FileExt;
        let from = self.chunk.start + self.hashed as u64;
        let bytes = &mut buf[..self.len() - self.hashed];
        file.read_exact_at(bytes, from).map_err(|e| self.chunk.unreadable(&e))?;
        let outcome = self.feed(bytes).expect("invariant: the rest of the chunk completes it");
        // SAFETY: posix_fadvise only advises the kernel about this open descriptor's pages.
        unsafe {
            libc::posix_fadvise(
                file.as_raw_fd(),
                from as libc::off_t,
                bytes.len() as libc::off_t,
                libc::POSIX_FADV_DONTNEED,
            );
        }
        outcome
    }
}

/// The checking thread: what is in memory from the mapping until `finish`, then the rest
/// from the file. See the module docs.
fn check(file: &File, map: &Mmap, chunks: Vec<Chunk>, finish: &AtomicBool) -> Outcome {
    let mut pending: Vec<Progress> = chunks.into_iter().map(Progress::new).collect();
    let mut residency = Vec::new();
    while !pending.is_empty() && !finish.load(Ordering::Relaxed) {
        let mut failed = None;
        pending.retain_mut(|p| {
            if failed.is_some() {
                return true;
            }
            match p.advance(map, &mut residency) {
                None => true,
                Some(outcome) => {
                    failed = outcome.err();
                    false
                }
            }
        });
        if let Some(what) = failed {
            return Err(what);
        }
        std::thread::park_timeout(SWEEP_INTERVAL);
    }
    let mut buf = vec![0u8; CHUNK as usize];
    pending.iter_mut().try_for_each(|p| p.finish_by_reading(file, &mut buf))
}

/// Bytes from `start` (page-aligned, inside `map`) on, at most `len`, whose pages are all
/// in memory (`mincore`; 0 if it cannot tell). The first page is asked alone first: a
/// chunk whose next page the render has not read is turned away with one page lookup.
fn resident_prefix(map: &Mmap, start: usize, len: usize, scratch: &mut Vec<u8>) -> usize {
    if len == 0 {
        return 0;
    }
    scratch.clear();
    scratch.resize(len.div_ceil(PAGE), 0);
    // SAFETY: the ranges lie inside the mapping (section bounds were checked at open) and
    // start on page boundaries (sections are page-aligned, chunks a multiple of pages);
    // mincore writes one byte per page into `scratch`, which has room for all of them.
    let asked = unsafe {
        let at = map.as_ptr().add(start) as *mut libc::c_void;
        libc::mincore(at, len.min(PAGE), scratch.as_mut_ptr()) == 0
            && scratch[0] & 1 == 1
            && libc::mincore(at, len, scratch.as_mut_ptr()) == 0
    };
    if !asked {
        return 0;
    }
    let pages = scratch.iter().take_while(|&&b| b & 1 == 1).count();
    (pages * PAGE).min(len)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    /// A file of `n` chunks of distinct bytes and their chunk records.
    fn chunked_file(name: &str, n: u64) -> (std::path::PathBuf, Vec<Chunk>) {
        let path = std::env::temp_dir().join(format!("plume-verify-{name}-{}", std::process::id()));
        let mut f = File::create(&path).unwrap();
        let mut chunks = Vec::new();
        for i in 0..n {
            let bytes: Vec<u8> =
                (0..CHUNK).map(|b| (b as u8).wrapping_mul(31).wrapping_add(i as u8)).collect();
            f.write_all(&bytes).unwrap();
            let start = i * CHUNK;
            chunks.push(Chunk {
                start,
                end: start + CHUNK,
                sum: xxhash_rust::xxh3::xxh3_64(&bytes),
                kind: "values",
            });
        }
        f.sync_all().unwrap();
        (path, chunks)
    }

    /// Both phases check every chunk and report a bad one: phase 1 from the mapping (the
    /// freshly written file is in the page cache), phase 2 by reading (asked to finish
    /// at once).
    #[test]
    fn both_phases_check_every_chunk() {
        let (path, mut chunks) = chunked_file("phases", 6);
        let file = File::open(&path).unwrap();
        let map = Mapping::map(&file, &path, "test file").unwrap();
        assert!(
            chunks.iter().all(|c| resident_prefix(
                &map,
                c.start as usize,
                CHUNK as usize,
                &mut Vec::new()
            ) == CHUNK as usize),
            "a file just written is resident"
        );
        for finish_at_once in [false, true] {
            let flag = AtomicBool::new(finish_at_once);
            assert_eq!(check(&file, &map, chunks.clone(), &flag), Ok(()));
            let mut bad = chunks.clone();
            bad[4].sum ^= 1;
            let err = damaged(check(&file, &map, bad, &AtomicBool::new(finish_at_once)));
            assert!(err.contains(&format!("{}..{}", 4 * CHUNK, 5 * CHUNK)), "{err}");
        }
        // Through the thread: a damaged sum is reported by wait()
        chunks[2].sum ^= 1;
        let entry_sums: Vec<u64> = chunks.iter().map(|c| c.sum).collect();
        let entry = SectionEntry {
            kind: SectionKind::Values as u32,
            offset: 0,
            len: 6 * CHUNK,
            first_chunk: 0,
            checksum: 0,
        };
        let v =
            Verification::start(File::open(&path).unwrap(), Arc::new(map), &[entry], &entry_sums)
                .unwrap();
        let err = damaged(v.wait());
        assert!(err.contains(&format!("{}..{}", 2 * CHUNK, 3 * CHUNK)), "{err}");
        assert_eq!(damaged(v.wait()), err, "the outcome is kept");
        let _ = std::fs::remove_file(&path);
    }

    /// A chunk hashed in pieces, as phase 1 hashes what the render has brought into
    /// memory, gets the one-shot sum: complete only with its last byte, and a wrong sum
    /// or a changed byte is reported whatever the pieces.
    #[test]
    fn a_chunk_hashed_in_pieces_gets_the_one_shot_sum() {
        let bytes: Vec<u8> =
            (0..CHUNK).map(|b| (b as u8).wrapping_mul(29) ^ (b >> 12) as u8).collect();
        let chunk = Chunk { start: 0, end: CHUNK, sum: xxh3_64(&bytes), kind: "values" };
        for pieces in [vec![256], vec![1, 255], vec![3, 100, 153], vec![255, 1]] {
            let mut p = Progress::new(chunk);
            let mut at = 0;
            for (i, &pages) in pieces.iter().enumerate() {
                let outcome = p.feed(&bytes[at..at + pages * PAGE]);
                at += pages * PAGE;
                let last = i + 1 == pieces.len();
                assert_eq!(outcome, last.then_some(Ok(())), "pieces {pieces:?}, after {i}");
            }
            let mut changed = bytes.clone();
            changed[at - 7] ^= 1;
            let mut q = Progress::new(chunk);
            let mut at = 0;
            let mut last = None;
            for &pages in &pieces {
                last = q.feed(&changed[at..at + pages * PAGE]);
                at += pages * PAGE;
            }
            assert!(matches!(last, Some(Err(Failure::Damaged(_)))), "{last:?}");
        }
    }

    /// Phase 2 reads only what phase 1 left of a chunk: a prefix hashed from memory and
    /// the rest read from the file make the chunk's sum, and damage in the rest is found.
    #[test]
    fn phase_two_reads_the_rest_of_a_partly_hashed_chunk() {
        let (path, chunks) = chunked_file("rest", 2);
        let original = std::fs::read(&path).unwrap();
        let file = File::open(&path).unwrap();
        let map = Mapping::map(&file, &path, "test file").unwrap();
        assert_eq!(
            resident_prefix(&map, 0, CHUNK as usize, &mut Vec::new()),
            CHUNK as usize,
            "a file just written is resident"
        );
        let mut buf = vec![0u8; CHUNK as usize];
        let mut p = Progress::new(chunks[1]);
        let from = chunks[1].start as usize;
        assert_eq!(p.feed(&original[from..from + 100 * PAGE]), None);
        assert_eq!(p.finish_by_reading(&file, &mut buf), Ok(()));
        // A byte in the unhashed rest changes on disk
        let mut p = Progress::new(chunks[1]);
        assert_eq!(p.feed(&original[from..from + 100 * PAGE]), None);
        let at = chunks[1].start + 200 * PAGE as u64;
        std::os::unix::fs::FileExt::write_all_at(
            &File::options().write(true).open(&path).unwrap(),
            &[!original[at as usize]],
            at,
        )
        .unwrap();
        let err = damaged(p.finish_by_reading(&file, &mut buf));
        assert!(err.contains(&format!("{}..{}", CHUNK, 2 * CHUNK)), "{err}");
        let _ = std::fs::remove_file(&path);
    }

    fn damaged(outcome: Outcome) -> String {
        match outcome {
            Err(Failure::Damaged(what)) => what,
            other => panic!("expected a checksum failure, got {other:?}"),
        }
    }

    /// A file that shrank since it was opened is unreadable, not damaged (phase 2 only:
    /// this test process has no SIGBUS handler for the mapping's lost pages).
    #[test]
    fn a_truncated_file_is_unreadable_not_damaged() {
        let (path, chunks) = chunked_file("truncated", 4);
        let file = File::open(&path).unwrap();
        let map = Mapping::map(&file, &path, "test file").unwrap();
        File::options().write(true).open(&path).unwrap().set_len(2 * CHUNK + 100).unwrap();
        match check(&file, &map, chunks, &AtomicBool::new(true)) {
            Err(Failure::Unreadable(what)) => assert!(
                what.contains(&format!("ends before byte {}", 3 * CHUNK))
                    && what.contains("truncated"),
                "{what}"
            ),
            other => panic!("{other:?}"),
        }
        let _ = std::fs::remove_file(&path);
    }
}
