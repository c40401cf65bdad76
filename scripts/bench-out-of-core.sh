#!/usr/bin/env bash
# Out-of-core benchmark (README, "Out-of-core rendering"): a generated solar flare of
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
#   4. render throughput (samples/s, DDA voxel steps/s) against the in-core render of
#      a flare that fits in memory (1024³ .vdb read into RAM), same camera framing
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

# Run a command, sampling its peak RssAnon/RssFile (kB) into $WORK/peak.txt
sampled() {
    "$@" &
    local pid=$! anon=0 file=0 a f
    while kill -0 "$pid" 2>/dev/null; do
        if read -r a f < <(awk '/^RssAnon:/{a=$2} /^RssFile:/{f=$2} END{print a+0, f+0}' "/proc/$pid/status" 2>/dev/null); then
            [ "${a:-0}" -gt "$anon" ] && anon=$a
            [ "${f:-0}" -gt "$file" ] && file=$f
        fi
        sleep 0.02
    done
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

# 2. Generation straight to a cache (REUSE=1 keeps an existing one: 5 minutes saved)
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

# 3./4. Renders: same flags, stats per run. Camera rays only (emission and absorption):
# with scattering, FNEE sends every bounce towards a random emitter, so a volume larger
# than RAM is read at random and the page cache thrashes (see README).
FLAGS=(--width 160 --height 120 --spp 2 --threads 2 -q)
rm -f "$WORK"/*.jsonl
sync; echo 3 > /proc/sys/vm/drop_caches 2>/dev/null || true
sampled $PLUME render "$WORK/flare$BIG.plume" -o "$WORK/big.exr" "${FLAGS[@]}" --memory-budget 4GiB --stats "$WORK/big.jsonl" --overwrite
read -r big_anon big_file < "$WORK/peak.txt"
# Warm run of the same (page cache holds what fits)
$PLUME render "$WORK/flare$BIG.plume" -o "$WORK/big-warm.exr" "${FLAGS[@]}" --memory-budget 4GiB --stats "$WORK/big-warm.jsonl" --overwrite
[ -f "$WORK/flare1024.vdb" ] || $PLUME synth flare --resolution 1024 -o "$WORK/flare1024.vdb"
sampled $PLUME render "$WORK/flare1024.vdb" -o "$WORK/core.exr" "${FLAGS[@]}" --stats "$WORK/core.jsonl" --overwrite
read -r core_anon _ < "$WORK/peak.txt"
# Same data both ways: 2048³ in core (.vdb) and mapped (.plume)
$PLUME render "$WORK/flare2048.vdb" -o "$WORK/c2048.exr" "${FLAGS[@]}" --memory-budget 20GiB --stats "$WORK/c2048.jsonl" --overwrite
$PLUME render "$WORK/flare2048.plume" -o "$WORK/m2048.exr" "${FLAGS[@]}" --stats "$WORK/m2048.jsonl" --overwrite

sps() { json "$1" "['samples_per_second']"; }
steps() { python3 -c "import json,sys; r=json.loads(open(sys.argv[1]).read().splitlines()[-1]); print(r['counters']['voxel_steps']/r['render_seconds'])" "$1"; }
ttfs() { json "$1" "['time_to_first_sample_seconds']"; }
python3 - "$WORK" "$BIG" "$vdb_bytes" "$cache2048_bytes" "$conv_s" "$conv_anon" "$big_bytes" "$gen_s" "$gen_anon" "$big_anon" "$big_file" "$core_anon" \
    "$(ttfs "$WORK/big.jsonl")" "$(ttfs "$WORK/big-warm.jsonl")" "$(sps "$WORK/big.jsonl")" "$(sps "$WORK/big-warm.jsonl")" "$(sps "$WORK/core.jsonl")" \
    "$(steps "$WORK/big.jsonl")" "$(steps "$WORK/big-warm.jsonl")" "$(steps "$WORK/core.jsonl")" "$(sps "$WORK/c2048.jsonl")" "$(sps "$WORK/m2048.jsonl")" <<'EOF'
import sys
a = sys.argv[1:]
work, big = a[0], a[1]
vdb_b, c2048_b, conv_s, conv_anon, big_b, gen_s, gen_anon, big_anon, big_file, core_anon = map(float, a[2:12])
ttfs_cold, ttfs_warm, sps_cold, sps_warm, sps_core, st_cold, st_warm, st_core, sps_c2048, sps_m2048 = map(float, a[12:22])
G, M = 1e9, 1e6
print(f"| figure | value | target |")
print(f"|---|---|---|")
print(f"| dataset | {big}³ flare, {big_b/G:.1f} GB cache file | ≥ 30 GB |")
print(f"| conversion (`plume prepare`, 2048³ .vdb {vdb_b/G:.2f} GB → {c2048_b/G:.2f} GB cache) | {c2048_b/M/conv_s:.0f} MB/s written ({conv_s:.1f} s), peak RssAnon {conv_anon/1024:.0f} MiB | ≥ 200 MB/s |")
print(f"| generation straight to cache ({big}³) | {big_b/M/gen_s:.0f} MB/s ({gen_s:.0f} s), peak RssAnon {gen_anon/1024:.0f} MiB | |")
print(f"| peak anonymous RSS rendering it, `--memory-budget 4GiB` | {big_anon/1024:.0f} MiB (file pages mapped: up to {big_file/1024:.0f} MiB) | ≤ 4096 MiB |")
print(f"| time to first sample from the cache (cold page cache / warm) | {ttfs_cold:.3f} s / {ttfs_warm:.3f} s | < 2 s |")
print(f"| render throughput, samples/s: {big}³ cache cold / warm vs 1024³ in core | {sps_cold:.0f} / {sps_warm:.0f} vs {sps_core:.0f} ({sps_cold/sps_core:.2f}× / {sps_warm/sps_core:.2f}×) | ≥ 0.5× |")
print(f"| DDA voxel steps/s: {big}³ cache cold / warm vs 1024³ in core | {st_cold/M:.1f} M / {st_warm/M:.1f} M vs {st_core/M:.1f} M ({st_cold/st_core:.2f}× / {st_warm/st_core:.2f}×) | |")
print(f"| same 2048³ data, mapped cache vs in core (samples/s) | {sps_m2048:.0f} vs {sps_c2048:.0f} ({sps_m2048/sps_c2048:.2f}×) | |")
EOF
