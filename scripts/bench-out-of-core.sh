#!/usr/bin/env bash
# Out-of-core benchmark (docs/out-of-core.md): a generated solar flare of
# about 30 GB rendered from a brick cache under --memory-budget 4GiB.
#
#   scripts/bench-out-of-core.sh [WORKDIR]      (default: target/ooc-bench; needs ≈40 GB free)
#   REUSE=1 BIG=4096 scripts/bench-out-of-core.sh   (keep a generated flare4096.plume)
#
# Measures, with the release binary:
#   1. conversion throughput: `plume prepare` of a 2048³ flare .vdb (streamed leaf by leaf)
#   2. generation straight to a cache of the largest flare that fits the disk (4096³ ≈ 30 GB)
#   3. time to first sample from that cache, and peak anonymous RSS (sampled from /proc
#      every 20 ms) while rendering it with --memory-budget 4GiB
#   4. render throughput (DDA voxel steps/s, samples/s) against in-core renders of
#      flares that fit in memory (1024³ and 2048³ .vdb read into RAM), same flags
# and prints a Markdown table. Every figure comes from --stats JSON or /proc, not guesses.
set -euo pipefail
cd "$(dirname "$0")/.."
WORK=${1:-target/ooc-bench}
mkdir -p "$WORK"
cargo build --release --quiet
PLUME=target/release/plume

free_gb=$(df -BG --output=avail "$WORK" | tail -1 | tr -dc 0-9)
if [ -n "${BIG:-}" ]; then :; elif [ "$free_gb" -ge 40 ]; then BIG=4096; elif [ "$free_gb" -ge 20 ]; then BIG=3264; else BIG=2048; fi
echo "free disk: ${free_gb} GB -> big flare ${BIG}³" >&2

# Run a command, sampling its peak RssAnon/RssFile (kB) every 20 ms into $WORK/peak.txt.
# Bash builtins only (no awk or sleep processes), so sampling takes no CPU from the
# 2-core render it measures.
sampled() {
    "$@" &
    local pid=$! anon=0 file=0 key value _ tick
    exec {tick}<> <(:)
    while kill -0 "$pid" 2>/dev/null; do
        while read -r key value _; do
            case $key in
                RssAnon:) [ "$value" -gt "$anon" ] && anon=$value ;;
                RssFile:) [ "$value" -gt "$file" ] && file=$value ;;
            esac
        done < "/proc/$pid/status" 2>/dev/null || true
        read -r -t 0.02 -u "$tick" _ || true
    done
    exec {tick}>&-
    wait "$pid"
    echo "$anon $file" > "$WORK/peak.txt"
}
json() { python3 -c "import json,sys; r=json.loads(open(sys.argv[1]).read().splitlines()[-1]); print(r$2)" "$1"; }
now() { date +%s.%N; }

# 1. Conversion: .vdb (built in memory by the generator) -> cache, streamed
[ -f "$WORK/flare2048.vdb" ] || $PLUME synth flare --resolution 2048 -o "$WORK/flare2048.vdb"
rm -f "$WORK/flare2048.plume"
sync; echo 3 > /proc/sys/vm/drop_caches 2>/dev/null || true
t0=$(now)
sampled $PLUME prepare "$WORK/flare2048.vdb" -o "$WORK/flare2048.plume" -q
t1=$(now)
read -r conv_anon _ < "$WORK/peak.txt"
vdb_bytes=$(stat -c %s "$WORK/flare2048.vdb")
cache2048_bytes=$(stat -c %s "$WORK/flare2048.plume")
conv_s=$(python3 -c "print($t1-$t0)")

# 2. Generation straight to a cache (REUSE=1 keeps an existing one and skips this step)
if [ "${REUSE:-0}" = 1 ] && [ -f "$WORK/flare$BIG.plume" ]; then
    gen_s=nan; gen_anon=0
else
    rm -f "$WORK/flare$BIG.plume"
    t0=$(now)
    sampled $PLUME synth flare --resolution "$BIG" -o "$WORK/flare$BIG.plume"
    t1=$(now)
    read -r gen_anon _ < "$WORK/peak.txt"
    gen_s=$(python3 -c "print($t1-$t0)")
fi
big_bytes=$(stat -c %s "$WORK/flare$BIG.plume")

# 3./4. Renders: same flags for every run, stats per run, page cache dropped before each
# (where allowed). Emission and absorption (camera rays): with scattering, FNEE sends
# bounces towards emitters anywhere in the volume, which tile-major read-ahead does not
# cover (docs/out-of-core.md, "Scattering out of core"). SPP=64: a production-like sample
# count; SPP_IO=16 shows the I/O-bound end, where the render reads the whole file for a
# quarter of the work.
FLAGS=(--width 320 --height 240 -q --overwrite)   # default threads: all cores (+1 tile by tile)
SPP=${SPP:-64}; SPP_IO=${SPP_IO:-16}
cold() { sync; echo 3 > /proc/sys/vm/drop_caches 2>/dev/null || true; }
disk_read() { cat /sys/block/*/stat 2>/dev/null | awk '{s+=$3} END{printf "%.0f\n", s*512}'; }
rm -f "$WORK"/*.jsonl
cold; r0=$(disk_read)
sampled $PLUME render "$WORK/flare$BIG.plume" -o "$WORK/big.exr" "${FLAGS[@]}" --spp "$SPP" --memory-budget 4GiB --stats "$WORK/big.jsonl"
r1=$(disk_read)
read -r big_anon big_file < "$WORK/peak.txt"
cold
$PLUME render "$WORK/flare$BIG.plume" -o "$WORK/big-io.exr" "${FLAGS[@]}" --spp "$SPP_IO" --memory-budget 4GiB --stats "$WORK/big-io.jsonl"
[ -f "$WORK/flare1024.vdb" ] || $PLUME synth flare --resolution 1024 -o "$WORK/flare1024.vdb"
$PLUME render "$WORK/flare1024.vdb" -o "$WORK/core.exr" "${FLAGS[@]}" --spp "$SPP" --stats "$WORK/core.jsonl"
$PLUME render "$WORK/flare1024.vdb" -o "$WORK/core-io.exr" "${FLAGS[@]}" --spp "$SPP_IO" --stats "$WORK/core-io.jsonl"
# The largest flare that fits, in core
$PLUME render "$WORK/flare2048.vdb" -o "$WORK/c2048.exr" "${FLAGS[@]}" --spp "$SPP" --memory-budget 20GiB --stats "$WORK/c2048.jsonl"

sps() { json "$1" "['samples_per_second']"; }
steps() { python3 -c "import json,sys; r=json.loads(open(sys.argv[1]).read().splitlines()[-1]); print(r['counters']['voxel_steps']/r['render_seconds'])" "$1"; }
ttfs() { json "$1" "['time_to_first_sample_seconds']"; }
wall() { json "$1" "['wall_seconds']"; }
python3 - "$WORK" "$BIG" "$vdb_bytes" "$cache2048_bytes" "$conv_s" "$conv_anon" "$big_bytes" "$gen_s" "$gen_anon" "$big_anon" "$big_file" \
    "$(ttfs "$WORK/big.jsonl")" "$(wall "$WORK/big.jsonl")" "$(sps "$WORK/big.jsonl")" "$(steps "$WORK/big.jsonl")" \
    "$(wall "$WORK/big-io.jsonl")" "$(steps "$WORK/big-io.jsonl")" "$(sps "$WORK/core.jsonl")" "$(steps "$WORK/core.jsonl")" \
    "$(steps "$WORK/core-io.jsonl")" "$(steps "$WORK/c2048.jsonl")" "$((r1 - r0))" "$SPP" "$SPP_IO" <<'EOF'
import sys
a = sys.argv[1:]
work, big = a[0], a[1]
vdb_b, c2048_b, conv_s, conv_anon, big_b, gen_s, gen_anon, big_anon, big_file = map(float, a[2:11])
ttfs, wall, sps_big, st_big, wall_io, st_io, sps_core, st_core, st_core_io, st_2048, read_b = map(float, a[11:22])
spp, spp_io = a[22], a[23]
G, M = 1e9, 1e6
print("| figure | value | target |")
print("|---|---|---|")
print(f"| dataset | {big}³ flare, {big_b/G:.1f} GB cache file | ≥ 30 GB |")
print(f"| conversion, `plume prepare` of a 2048³ .vdb ({vdb_b/G:.2f} GB → {c2048_b/G:.2f} GB cache, cold page cache) | **{c2048_b/M/conv_s:.0f} MB/s** of cache written ({vdb_b/M/conv_s:.0f} MB/s of .vdb read; {conv_s:.1f} s), peak RssAnon {conv_anon/1024:.0f} MiB | ≥ 200 MB/s |")
if gen_s == gen_s:
    print(f"| generation straight to a cache ({big}³) | {big_b/M/gen_s:.0f} MB/s ({gen_s:.0f} s), peak RssAnon {gen_anon/1024:.0f} MiB | |")
print(f"| peak anonymous RSS rendering it with `--memory-budget 4GiB` | **{big_anon/1024:.0f} MiB** (mapped file pages: up to {big_file/1024:.0f} MiB) | ≤ 4096 MiB |")
print(f"| time to first sample from the cache (cold page cache) | **{ttfs:.3f} s** | < 2 s |")
print(f"| render throughput, voxel steps/s at {spp} spp: {big}³ from the cache (cold) vs 1024³ in core | {st_big/M:.1f} M vs {st_core/M:.1f} M (**{st_big/st_core:.2f}×**); {wall:.1f} s, {read_b/G:.1f} GB read from disk | ≥ 0.5× |")
print(f"| the same against the largest flare that fits (2048³ in core) | {st_big/M:.1f} M vs {st_2048/M:.1f} M ({st_big/st_2048:.2f}×) | |")
print(f"| samples/s at {spp} spp ({big}³ samples take more steps) | {sps_big:.0f} vs {sps_core:.0f} | |")
print(f"| I/O-bound end, {spp_io} spp: voxel steps/s | {st_io/M:.1f} M vs {st_core_io/M:.1f} M ({st_io/st_core_io:.2f}×); {wall_io:.1f} s | |")
EOF
