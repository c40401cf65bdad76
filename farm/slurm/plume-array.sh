#!/usr/bin/env bash
# Render a plume sequence on Slurm as a job array.
#
#   INPUT='shots/fx/explosion.####.vdb' OUTPUT='renders/fx/beauty.%04d.exr' \
#   FIRST=1001 LAST=1100 CHUNK=5 SPP=256 farm/slurm/plume-array.sh
#
# submits one array task per chunk of CHUNK frames (task i renders frames
# FIRST + i*CHUNK ...). With TILES=n (and SAMPLE_SPLITS=m) every frame is instead split
# into n tiles x m sample ranges, one array task each, and a second array job, one task
# per frame, waits for them (--dependency=afterok) and runs `plume merge`: the merged
# image is bit-identical to rendering the frame in one process.
#
# Settings (environment): PLUME (default plume), INPUT, OUTPUT (a frame token; printf
# style %04d when tiling, since this script fills it in for the merge), FIRST, LAST,
# CHUNK (1), SPP (64), WIDTH (640), HEIGHT (480), TILES (1), SAMPLE_SPLITS (1),
# EXTRA_ARGS (more `plume render` flags, split at spaces), SBATCH_ARGS (more sbatch
# flags, e.g. "--partition=render --time=02:00:00 --mem=8G --requeue"; they override the
# #SBATCH lines below). The output directory is created at submission. With memory
# confined by Slurm (task/cgroup, ConstrainRAMSpace=yes), plume sizes its memory budget
# from --mem and renders a brick cache larger than it tile by tile (docs/farm.md).
#
# plume writes atomically, skips complete outputs and continues interrupted ones, so
# requeued or resubmitted tasks finish only what is missing. Slurm sends SIGTERM at the
# time limit or on preemption and SIGKILL KillWait seconds later: plume finishes its
# current pass (about a second) and writes the image with its spp (exit 5). Exit codes
# (docs/farm.md, "Exit codes"): 0 ok, 2 bad arguments, 3 input, 4 render/output, 5
# interrupted, 6 --time-limit, 7 some frames of the chunk failed. Array size is bounded
# by Slurm's MaxArraySize (1001 by default): raise CHUNK for long sequences.
#SBATCH --job-name=plume
#SBATCH --cpus-per-task=8
#SBATCH --output=plume-%A_%a.log
set -euo pipefail

: "${PLUME:=plume}" "${CHUNK:=1}" "${SPP:=64}" "${WIDTH:=640}" "${HEIGHT:=480}"
: "${TILES:=1}" "${SAMPLE_SPLITS:=1}" "${EXTRA_ARGS:=}" "${SBATCH_ARGS:=}"
: "${INPUT:?set INPUT to the VDB pattern}" "${OUTPUT:?set OUTPUT to the EXR pattern}"
: "${FIRST:?set FIRST}" "${LAST:?set LAST}"

die() { echo "plume-array: $*" >&2; exit 2; }
(( LAST >= FIRST )) || die "LAST ($LAST) is before FIRST ($FIRST)"
(( CHUNK >= 1 && TILES >= 1 && SAMPLE_SPLITS >= 1 )) || die "CHUNK, TILES and SAMPLE_SPLITS must be at least 1"
(( SAMPLE_SPLITS <= SPP )) || die "SAMPLE_SPLITS ($SAMPLE_SPLITS) exceeds SPP ($SPP)"
frames=$(( LAST - FIRST + 1 ))
parts_per_frame=$(( TILES * SAMPLE_SPLITS ))
if (( parts_per_frame > 1 )); then
    [[ $OUTPUT =~ %0?[0-9]*d ]] || die "with TILES/SAMPLE_SPLITS, OUTPUT needs a printf frame token such as %04d"
fi
# shellcheck disable=SC2206  # split on purpose
extra=($EXTRA_ARGS)

# The part of tile t, sample split s: OUTPUT with .tile<t>.s<s> before .exr
part_pattern() { echo "${OUTPUT%.exr}.tile$1.s$2.exr"; }

case "${1:-submit}" in
submit)
    # shellcheck disable=SC2206
    sbatch_args=($SBATCH_ARGS)
    mkdir -p "$(dirname "$OUTPUT")"
    if (( parts_per_frame == 1 )); then
        tasks=$(( (frames + CHUNK - 1) / CHUNK ))
        sbatch --parsable --array=0-$(( tasks - 1 )) --export=ALL "${sbatch_args[@]}" "$0" render
    else
        render_id=$(sbatch --parsable --array=0-$(( frames * parts_per_frame - 1 )) --export=ALL "${sbatch_args[@]}" "$0" render)
        echo "$render_id"
        sbatch --parsable --dependency=afterok:"${render_id%%;*}" --array=0-$(( frames - 1 )) --export=ALL \
            --cpus-per-task=1 "${sbatch_args[@]}" "$0" merge
    fi
    ;;
render)
    i=${SLURM_ARRAY_TASK_ID:?render runs as a Slurm array task}
    threads=${SLURM_CPUS_PER_TASK:-0}
    if (( parts_per_frame == 1 )); then
        first=$(( FIRST + i * CHUNK ))
        last=$(( first + CHUNK - 1 < LAST ? first + CHUNK - 1 : LAST ))
        exec "$PLUME" render "$INPUT" -o "$OUTPUT" --frames "$first-$last" --spp "$SPP" \
            --width "$WIDTH" --height "$HEIGHT" --threads "$threads" \
            --stats "${OUTPUT%.exr}.stats.jsonl" "${extra[@]}"
    fi
    frame=$(( FIRST + i / parts_per_frame ))
    tile=$(( (i / SAMPLE_SPLITS) % TILES ))
    split=$(( i % SAMPLE_SPLITS ))
    a=$(( split * SPP / SAMPLE_SPLITS ))
    b=$(( (split + 1) * SPP / SAMPLE_SPLITS ))
    part=$(part_pattern "$tile" "$split")
    exec "$PLUME" render "$INPUT" -o "$part" --frames "$frame" \
        --tile "$tile/$TILES" --sample-range "$a..$b" --width "$WIDTH" --height "$HEIGHT" \
        --threads "$threads" --stats "${part%.exr}.stats.jsonl" "${extra[@]}"
    ;;
merge)
    frame=$(( FIRST + ${SLURM_ARRAY_TASK_ID:?merge runs as a Slurm array task} ))
    parts=()
    for (( t = 0; t < TILES; t++ )); do
        for (( s = 0; s < SAMPLE_SPLITS; s++ )); do
            # shellcheck disable=SC2059  # the pattern is the format on purpose
            parts+=("$(printf "$(part_pattern "$t" "$s")" "$frame")")
        done
    done
    # shellcheck disable=SC2059
    exec "$PLUME" merge "${parts[@]}" -o "$(printf "$OUTPUT" "$frame")"
    ;;
*)
    die "usage: $0 [submit|render|merge]"
    ;;
esac
