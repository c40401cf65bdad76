#!/usr/bin/env python3
"""How many passes over a brick cache a chunked wavefront would need.

Reads the trace that `docs/bench/chunk-trace.patch` makes plume write
(`PLUME_CHUNK_TRACE=trace.bin plume render ...`): for every scattered path, in the order
of its lookups, which twelfth of the cache's value blocks each lookup fell in (u64
little-endian: path id << 4 | twelfth, consecutive repeats dropped).

The model: the file is cut into K chunks (Morton ranges of the value blocks); one chunk is
resident at a time; every path waiting for it is traced as far as it goes inside it and
queued for the next chunk it needs; the chunks are swept forward, then back, round after
round, and a chunk no path waits for is not read. A path's lookups are taken in the order
it made them, so its FNEE segments wait for the segments before them (an upper bound on
the rounds). A chunk load is priced as a sequential read of K-th of the file
(FILE_SECONDS, measured) or, when few paths wait for it, as their pages read at random
(PAGES_PER_VISIT per path at PAGE_SECONDS), whichever is cheaper.

    python3 scripts/wavefront_sim.py trace.bin
"""
import sys
from collections import defaultdict

import numpy as np

FILE_SECONDS = 2.31      # the 4.5 GiB flare read in file order in a 1.5 GiB cgroup
PAGE_SECONDS = 11.3e-6   # one 4 KiB page read at random in the same limit
PAGES_PER_PATH = 55      # pages a scattered path reads (the flare, docs/BENCHMARKS.md)


def paths(trace):
    raw = np.fromfile(trace, dtype="<u8")
    path, twelfth = raw >> 4, (raw & 15).astype(np.int64)
    order = np.argsort(path, kind="stable")
    path, twelfth = path[order], twelfth[order]
    cut = np.flatnonzero(np.diff(path)) + 1
    return [twelfth[s:e] for s, e in zip(np.r_[0, cut], np.r_[cut, len(path)])]


def simulate(runs, k, pingpong):
    seqs = []
    for r in runs:
        c = r * k // 12
        seqs.append(c[np.r_[True, c[1:] != c[:-1]]])
    mean_runs = np.mean([len(q) for q in seqs])
    pages_per_visit = PAGES_PER_PATH / mean_runs
    pos = [0] * len(seqs)
    need = defaultdict(set)
    for i, q in enumerate(seqs):
        need[q[0]].add(i)
    rounds = loads = 0
    seconds = 0.0
    while any(need.values()):
        backwards = pingpong and rounds % 2 == 1
        for chunk in (range(k - 1, -1, -1) if backwards else range(k)):
            waiting = need[chunk]
            if not waiting:
                continue
            loads += 1
            seconds += min(FILE_SECONDS / k, len(waiting) * pages_per_visit * PAGE_SECONDS)
            need[chunk] = set()
            for i in waiting:
                pos[i] += 1
                if pos[i] < len(seqs[i]):
                    need[seqs[i][pos[i]]].add(i)
        rounds += 1
    return rounds, loads, seconds, mean_runs


def main():
    runs = paths(sys.argv[1])
    print(f"{len(runs)} scattered paths")
    print("| chunks | sweep | rounds | chunk loads (passes) | I/O, priced | chunk runs per path |")
    print("|---|---|---|---|---|---|")
    for k in (3, 6, 12):
        for pingpong in (False, True):
            rounds, loads, seconds, mean_runs = simulate(runs, k, pingpong)
            sweep = "forward and back" if pingpong else "forward"
            print(f"| {k} | {sweep} | {rounds} | {loads} ({loads / k:.1f}) | {seconds:.1f} s | {mean_runs:.2f} |")


if __name__ == "__main__":
    main()
