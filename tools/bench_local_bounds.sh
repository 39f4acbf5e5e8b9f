#!/usr/bin/env bash
# Local bounds (tracking = { local_bounds = true }) on the dense peer cloud at 128^3 and 256^3
# voxels, against the plain estimators and against another build, in one interleaved run
# (docs/BENCHMARKS.md, "Local bounds").
#
#   tools/bench_local_bounds.sh REFERENCE.exr [--repeat R] [--spp N] [--res W] [BASE_BIN]
#
# REFERENCE.exr: a reference of tools/peers/bench/cloud_dense.toml at W x W, e.g.
#   velour reference tools/peers/bench/cloud_dense.toml -o ref.exr --width 128 --height 128 --time 600
# (the 256^3 scene has the same expected image). BASE_BIN (e.g. a build of main) renders the
# scenes as they are; target/release/velour renders them as they are, with local bounds, and
# with decomposition tracking and local bounds. Every render: W x W, N spp, 1 thread, seed 1.
# Prints per configuration the median CPU seconds (user + sys of the whole process, load
# included), the render's own wall time, lookups per real collision, transmittance lookups,
# relative MSE against the reference (velour diff) and efficiency = 1 / (rel. MSE x CPU s).
# Needs the generated grids (tools/peers/generate.sh --no-512).
set -euo pipefail
cd "$(dirname "$0")/.."
ref=$1
shift
repeat=3
spp=32
res=128
base=""
while [ $# -gt 0 ]; do
  case "$1" in
    --repeat) repeat=$2; shift 2 ;;
    --spp) spp=$2; shift 2 ;;
    --res) res=$2; shift 2 ;;
    *) base=$1; shift ;;
  esac
done
new=target/release/velour
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
gen=$(pwd)/tools/peers/generated
configs=()
for grid in "" _256; do
  src=tools/peers/bench/cloud_dense$grid.toml
  sed "s#\"../generated/#\"$gen/#" "$src" > "$tmp/plain$grid.toml"
  sed 's#nee = "interior" }#nee = "interior", tracking = { local_bounds = true } }#' "$tmp/plain$grid.toml" > "$tmp/local$grid.toml"
  sed 's#nee = "interior" }#nee = "interior", tracking = { local_bounds = true, free_flight = "decomposition" } }#' "$tmp/plain$grid.toml" > "$tmp/decomp$grid.toml"
  [ -n "$base" ] && configs+=("base$grid|$base|$tmp/plain$grid.toml")
  configs+=("plain$grid|$new|$tmp/plain$grid.toml" "local$grid|$new|$tmp/local$grid.toml" "decomp$grid|$new|$tmp/decomp$grid.toml")
done
for r in $(seq "$repeat"); do
  for c in "${configs[@]}"; do
    IFS='|' read -r name bin scene <<<"$c"
    out="$tmp/$name.$r.exr"
    line=$(/usr/bin/time -f "cpu %U %S" -o "$tmp/cpu.txt" "$bin" render "$scene" --spp "$spp" --width "$res" --height "$res" --threads 1 -q -o "$out" 2>/dev/null | tail -1)
    cpu=$(awk '/^cpu/ {print $2 + $3}' "$tmp/cpu.txt")
    t=$(grep -o 'time [0-9.]* s' <<<"$line" | awk '{print $2}')
    lpc=$(grep -o '[0-9.]* lookups per real collision' <<<"$line" | awk '{print $1}')
    tl=$(grep -o '[0-9]* transmittance lookups' <<<"$line" | awk '{print $1}')
    rel=$("$new" diff "$out" "$ref" --json | python3 -c 'import json,sys; d=json.load(sys.stdin); print(d.get("rel_mse", d.get("relative_mse")))')
    echo "$name $cpu $t $lpc $tl $rel"
  done
done > "$tmp/runs.txt"
python3 - "$tmp/runs.txt" "$(cat /proc/loadavg)" <<'PY'
import sys, statistics
from collections import OrderedDict
runs = OrderedDict()
for line in open(sys.argv[1]):
    name, cpu, t, lpc, tl, rel = line.split()
    runs.setdefault(name, []).append((float(cpu), float(t), float(lpc), int(tl), float(rel)))
print(f"load average at the end: {sys.argv[2]}")
print(f"{'configuration':<14} {'CPU s':>7} {'(runs)':<18} {'render s':>8} {'lookups/real':>12} {'transm. lookups':>15} {'rel. MSE':>10} {'efficiency':>10}")
for name, v in runs.items():
    cpu = statistics.median(x[0] for x in v)
    t = statistics.median(x[1] for x in v)
    rel = statistics.mean(x[4] for x in v)
    runs_s = ",".join(f"{x[0]:.2f}" for x in v)
    print(f"{name:<14} {cpu:7.2f} {runs_s:<18} {t:8.2f} {v[0][2]:12.2f} {v[0][3]:15d} {rel:10.3e} {1.0/(rel*cpu):10.1f}")
PY
