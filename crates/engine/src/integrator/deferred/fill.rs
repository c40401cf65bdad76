//! The fill of deferred paths: every lookup the rounds recorded, answered in the order
//! of the cache file (module docs of `integrator::deferred`).

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use rayon::prelude::*;

use super::{Answer, PendingSample};
use crate::integrator::scene::Scene;
use crate::integrator::tracker::Points;
use plume_scene::PointLookup;
use plume_volume::field::Field;

/// Lookups answered per piece of work of the fill.
const FILL_CHUNK: usize = 4096;

/// The fill orders lookups by the file's value blocks in buckets of `2^BUCKET_SHIFT`
/// blocks (512 KiB): pages in a bucket are read together, in any order.
const BUCKET_SHIFT: u32 = 8;

/// Buckets of the file asked for ahead of the one being answered (64 MiB).
const FILL_AHEAD_BUCKETS: usize = 128;

/// The fill's work lists, kept from round to round (fresh pages cost the kernel their
/// zeroing).
#[derive(Default)]
pub(super) struct FillBuffers {
    /// The lookups in file order.
    order: Vec<Entry>,
    /// Their keys and values.
    out: Vec<Answer>,
}

/// One lookup of the fill: whose it is.
#[derive(Clone, Copy, Debug, Default)]
struct Entry {
    sample: u32,
    path: u32,
    request: u32,
}

/// Answer every missing request, bucket by bucket of the cache file in order, and add
/// the values to their paths' [`Answers`]. Returns how many were answered.
pub(super) fn fill<F: Field>(
    scene: &Scene<F>,
    pool: &rayon::ThreadPool,
    lookup: PointLookup,
    pending: &mut [PendingSample],
    buffers: &mut FillBuffers,
) -> u64 {
    let volume = scene.field.voxels();
    // Each request's value blocks, by channel; its bucket is its first dense block's
    let blocks: Vec<Vec<[u32; 3]>> = pool.install(|| {
        pending
            .par_iter_mut()
            .map(|s| {
                let wait = !s.direct && s.paths[s.next..].iter().any(|p| !p.missing.is_empty());
                s.stale |= wait;
                let requests = s.paths[s.next..].iter().flat_map(|p| &p.missing);
                requests.map(|r| volume.map_or([u32::MAX; 3], |v| v.value_blocks_at(r.p))).collect()
            })
            .collect()
    });
    // Bucket 0: lookups that read no block
    let bucket = |b: &[u32; 3]| {
        b.iter().find(|&&b| b != u32::MAX).map_or(0, |&b| (b >> BUCKET_SHIFT) as usize + 1)
    };
    let n_buckets = blocks.iter().flatten().map(bucket).max().map_or(0, |b| b + 1);
    // Per bucket and channel, the range of blocks its lookups read (their bricks')
    let mut ranges = vec![[(u32::MAX, 0u32); 3]; n_buckets];
    let mut starts = vec![0usize; n_buckets + 1];
    for b in blocks.iter().flatten() {
        let k = bucket(b);
        starts[k + 1] += 1;
        for (range, &block) in ranges[k].iter_mut().zip(b).filter(|(_, &block)| block != u32::MAX) {
            *range = (range.0.min(block), range.1.max(block));
        }
    }
    for k in 0..n_buckets {
        starts[k + 1] += starts[k];
    }
    buffers.order.clear();
    buffers.order.resize(starts[n_buckets], Entry::default());
    let order = &mut buffers.order;
    let mut at = starts.clone();
    for (i, (s, b)) in pending.iter().zip(&blocks).enumerate() {
        let mut b = b.iter();
        for (k, path) in s.paths.iter().enumerate().skip(s.next) {
            for j in 0..path.missing.len() {
                let slot = &mut at[bucket(b.next().expect("invariant: blocks per request"))];
                order[*slot] = Entry { sample: i as u32, path: k as u32, request: j as u32 };
                *slot += 1;
            }
        }
    }
    drop(blocks);
    // The bucket of each piece of work's last lookup
    let bucket_at = |i: usize| starts.partition_point(|&s| s <= i).saturating_sub(1);
    // Answer in order, the file's pages asked for a few buckets ahead
    let order = &buffers.order;
    buffers.out.clear();
    buffers.out.resize(order.len(), (0, [0.0; 3]));
    let work: Vec<Mutex<&mut [Answer]>> =
        buffers.out.chunks_mut(FILL_CHUNK).map(Mutex::new).collect();
    let next = AtomicUsize::new(0);
    let asked = AtomicUsize::new(0);
    let shared: &[PendingSample] = pending;
    let request =
        |e: &Entry| shared[e.sample as usize].paths[e.path as usize].missing[e.request as usize];
    let mapped = volume.filter(|v| v.is_mapped());
    pool.broadcast(|_| {
        let points = Points::new(&scene.field, &scene.medium, None, lookup);
        loop {
            let c = next.fetch_add(1, Ordering::Relaxed);
            let Some(slots) = work.get(c) else { return };
            let entries = &order[c * FILL_CHUNK..(c * FILL_CHUNK + FILL_CHUNK).min(order.len())];
            if let Some(v) = mapped.filter(|_| !entries.is_empty()) {
                let here = bucket_at(c * FILL_CHUNK + entries.len() - 1);
                let upto = (here + FILL_AHEAD_BUCKETS).min(n_buckets);
                let from = asked.fetch_max(upto, Ordering::Relaxed);
                for range in ranges
                    .get(from..upto)
                    .unwrap_or_default()
                    .iter()
                    .flatten()
                    .filter(|r| r.0 <= r.1)
                {
                    v.read_ahead_blocks(range.0 as usize..range.1 as usize + 1);
                }
            }
            let mut slots = slots.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
            for (slot, e) in slots.iter_mut().zip(entries) {
                let r = request(e);
                *slot = (r.key(), r.answer(&points));
            }
        }
    });
    drop(work);
    pool.install(|| {
        pending.par_iter_mut().filter(|s| s.stale).for_each(|s| {
            for path in &mut s.paths[s.next..] {
                path.answers.entries.reserve_exact(path.missing.len());
            }
        });
    });
    for (e, &answer) in order.iter().zip(&buffers.out) {
        pending[e.sample as usize].paths[e.path as usize].answers.entries.push(answer);
    }
    pool.install(|| {
        pending.par_iter_mut().filter(|s| s.stale && !s.direct).for_each(|s| {
            for path in &mut s.paths {
                path.missing = Vec::new();
                path.answers.sort();
            }
        });
    });
    buffers.order.len() as u64
}
