#!/usr/bin/env bash
# Render a scene on a Slurm cluster as a job array, and merge the parts in a dependent job.
#
#   tools/farm/submit.sh --mode tiles  --count N [options] SCENE -o OUT.exr [-- render args]
#   tools/farm/submit.sh --mode passes --count N --spp S [options] SCENE -o OUT.exr [-- ...]
#   tools/farm/submit.sh --mode frames --frames A..B [options] SCENE -o 'OUT.{frame:04}.exr'
#
# tiles:  task k renders band k of N (`velour render --tile k/N`) into OUT.tilek-N.exr;
# passes: task k renders samples [k*S/N, (k+1)*S/N) into OUT.samplesA-B.exr;
#   then one merge job (`--dependency=afterok:<array> --kill-on-invalid-dep=yes`, so a failed
#   task cancels it instead of leaving it pending forever) writes OUT.exr, bit-identical to a
#   one-process render.
# frames: task f renders frame f (B excluded); no merge.
#
# Every task runs `velour render ... --resume`, is submitted with --requeue, and `exec`s the
# renderer so that it receives Slurm's SIGTERM itself: a pre-empted, requeued or timed-out
# task writes its checkpoint (OUT.partial.exr) and the next run continues from it.
#
# Options: --velour BIN (default: velour on PATH, else target/release/velour), --threads T
# (cpus per task, default 1), --max-parallel M (array %M), --partition P, --time LIMIT,
# --logs DIR (default: beside OUT). Prints "array <id>" and "merge <id>".
set -euo pipefail
mode= count= spp= frames= scene= out= threads=1 parallel= partition= time_limit= logs=
velour_bin=$(command -v velour || true)
[ -n "$velour_bin" ] || velour_bin=$(cd "$(dirname "$0")/../.." && pwd)/target/release/velour
extra=()
while [ $# -gt 0 ]; do
  case "$1" in
    --mode) mode=$2; shift 2 ;;
    --count) count=$2; shift 2 ;;
    --spp) spp=$2; shift 2 ;;
    --frames) frames=$2; shift 2 ;;
    --velour) velour_bin=$2; shift 2 ;;
    --threads) threads=$2; shift 2 ;;
    --max-parallel) parallel=$2; shift 2 ;;
    --partition) partition=$2; shift 2 ;;
    --time) time_limit=$2; shift 2 ;;
    --logs) logs=$2; shift 2 ;;
    -o) out=$2; shift 2 ;;
    --) shift; extra=("$@"); break ;;
    -*) echo "submit.sh: unknown option $1" >&2; exit 2 ;;
    *) scene=$1; shift ;;
  esac
done
die() { echo "submit.sh: $*" >&2; exit 2; }
[ -n "$scene" ] && [ -f "$scene" ] || die "give an existing SCENE file"
[ -n "$out" ] || die "give the output with -o"
[ -x "$velour_bin" ] || die "no velour binary at $velour_bin (build it or pass --velour)"
scene=$(cd "$(dirname "$scene")" && pwd)/$(basename "$scene")
case "$out" in /*) ;; *) out=$PWD/$out ;; esac
logs=${logs:-$(dirname "$out")/slurm-logs}
mkdir -p "$logs" "$(dirname "$out")"
stem=${out%.exr}

common=(--parsable --requeue --cpus-per-task="$threads" --signal=B:TERM@60
        --output="$logs/%x-%A_%a.out" --open-mode=append)
[ -n "$partition" ] && common+=(--partition="$partition")
[ -n "$time_limit" ] && common+=(--time="$time_limit")
render=("$velour_bin" render "$scene" -q --threads "$threads" --resume)

case "$mode" in
  tiles|passes)
    [[ "$count" =~ ^[1-9][0-9]*$ ]] || die "--count N (a positive number) is required"
    array="0-$((count - 1))${parallel:+%$parallel}"
    if [ "$mode" = tiles ]; then
      task='t=$SLURM_ARRAY_TASK_ID; exec "$@" --tile "$t/'"$count"'" -o "'"$stem"'.tile$t-'"$count"'.exr"'
      parts=(); for ((k = 0; k < count; k++)); do parts+=("$stem.tile$k-$count.exr"); done
      [ -n "$spp" ] && render+=(--spp "$spp")
    else
      [[ "$spp" =~ ^[1-9][0-9]*$ ]] || die "--mode passes needs --spp S"
      [ "$count" -le "$spp" ] || die "--count $count exceeds --spp $spp"
      render+=(--spp "$spp")
      task='k=$SLURM_ARRAY_TASK_ID; a=$((k * '"$spp"' / '"$count"')); b=$(((k + 1) * '"$spp"' / '"$count"'));
exec "$@" --samples "$a..$b" -o "'"$stem"'.samples$a-$b.exr"'
      parts=(); for ((k = 0; k < count; k++)); do
        parts+=("$stem.samples$((k * spp / count))-$(((k + 1) * spp / count)).exr"); done
    fi
    array_id=$(sbatch "${common[@]}" --job-name=velour-$mode --array="$array" \
      --wrap="$(printf 'set -e; set -- %q' "${render[0]}"; printf ' %q' "${render[@]:1}" "${extra[@]}"; printf '; %s' "$task")")
    merge_id=$(sbatch --parsable --job-name=velour-merge --dependency=afterok:"$array_id" \
      --kill-on-invalid-dep=yes --output="$logs/%x-%j.out" \
      ${partition:+--partition="$partition"} \
      --wrap="$(printf 'exec %q merge -o %q' "$velour_bin" "$out"; printf ' %q' "${parts[@]}")")
    echo "array $array_id"
    echo "merge $merge_id"
    ;;
  frames)
    [[ "$frames" =~ ^([0-9]+)\.\.(=?)([0-9]+)$ ]] || die "--frames A..B or A..=B is required"
    a=${BASH_REMATCH[1]}; last=${BASH_REMATCH[3]}
    [ -n "${BASH_REMATCH[2]}" ] || last=$((last - 1))
    [ "$a" -le "$last" ] || die "empty frame range $frames"
    [[ "$out" == *"{frame"* ]] || die "-o must contain {frame} or {frame:04} with --mode frames"
    [ -n "$spp" ] && render+=(--spp "$spp")
    task='f=$SLURM_ARRAY_TASK_ID; exec "$@" --frames "$f..=$f" -o '"$(printf %q "$out")"
    array_id=$(sbatch "${common[@]}" --job-name=velour-frames --array="$a-$last${parallel:+%$parallel}" \
      --wrap="$(printf 'set -e; set -- %q' "${render[0]}"; printf ' %q' "${render[@]:1}" "${extra[@]}"; printf '; %s' "$task")")
    echo "array $array_id"
    ;;
  *) die "--mode tiles, passes or frames" ;;
esac
