#!/usr/bin/env bash
# Majorant pyramid (the default, adaptive walk) against one global majorant, on small and large
# grids, measured in one run with the runs interleaved (docs/BENCHMARKS.md, "Adaptive walk").
#   tools/bench_pyramid.sh [--repeat R] [--spp-scale F] [BIN ...]
# BINs default to target/release/velour; give a second binary (e.g. one built from an older
# commit) to compare builds in the same run. Prints per scene, majorant and binary the render
# times of every repeat, their median and the density lookups; then median ratios.
set -euo pipefail
cd "$(dirname "$0")/.."
repeat=3
scale=1
bins=()
while [ $# -gt 0 ]; do
  case "$1" in
    --repeat) repeat=$2; shift 2 ;;
    --spp-scale) scale=$2; shift 2 ;;
    *) bins+=("$1"); shift ;;
  esac
done
if [ ${#bins[@]} -eq 0 ]; then
  cargo build --release -q
  bins=(target/release/velour)
fi
if [ ! -f target/bench/sparse.vdb ]; then
  mkdir -p target/bench
  /usr/bin/python3 tools/vdb/make_sparse.py target/bench/sparse.vdb
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# name  scene  spp  (interior files made absolute so the copies render from $tmp)
scenes=(
  "grid_furnace tools/peers/scenes/grid_furnace.toml 256"
  "grid_cloud tools/peers/scenes/grid_cloud.toml 256"
  "cloud scenes/cloud.toml 8"
  "fbm_creature scenes/fbm_creature.toml 4"
  "sparse_puffs tools/bench/sparse_puffs.toml 16"
)
for entry in "${scenes[@]}"; do
  read -r name file spp <<<"$entry"
  dir=$(cd "$(dirname "$file")" && pwd)
  sed -E "s#file = \"([^/][^\"]*)\"#file = \"$dir/\\1\"#" "$file" > "$tmp/$name.pyramid.toml"
  # The global majorant: a tracking table in the interior (added before the closing brace).
  python3 - "$tmp/$name.pyramid.toml" "$tmp/$name.global.toml" <<'PY'
import re, sys
s = open(sys.argv[1]).read()
out = []
for line in s.splitlines():
    if line.startswith("interior = {") and "tracking" not in line:
        line = line[: line.rstrip().rfind("}")].rstrip() + ', tracking = { majorant = "global" } }'
    out.append(line)
open(sys.argv[2], "w").write("\n".join(out) + "\n")
PY
done
for r in $(seq "$repeat"); do
  for entry in "${scenes[@]}"; do
    read -r name file spp <<<"$entry"
    spp=$(python3 -c "print(max(1, round($spp * $scale)))")
    for m in pyramid global; do
      for b in "${bins[@]}"; do
        line=$(/usr/bin/time -f "cpu %U %S" -o "$tmp/cpu.txt" "$b" render "$tmp/$name.$m.toml" --spp "$spp" -q -o "$tmp/out.exr" 2>/dev/null | tail -1)
        t=$(grep -o 'time [0-9.]* s' <<<"$line" | awk '{print $2}')
        cpu=$(awk '/^cpu/ {print $2 + $3}' "$tmp/cpu.txt")
        ff=$(grep -o '[0-9]* free-flight lookups' <<<"$line" | awk '{print $1}')
        tl=$(grep -o '[0-9]* transmittance lookups' <<<"$line" | awk '{print $1}')
        echo "$name $m $b $spp $t $cpu ${ff:-0} ${tl:-0}"
      done
    done
  done
done > "$tmp/runs.txt"
python3 - "$tmp/runs.txt" <<'PY'
import sys, statistics
from collections import OrderedDict
runs = OrderedDict()
for line in open(sys.argv[1]):
    name, m, b, spp, t, cpu, ff, tl = line.split()
    runs.setdefault((name, m, b), []).append((float(t), float(cpu), int(ff), int(tl), int(spp)))
print(f"{'scene':<14} {'majorant':<8} {'binary':<24} {'spp':>4} {'render s':>9} {'(runs)':<20} {'CPU s':>7} {'(runs)':<20} {'free-flight lookups':>20} {'transm. lookups':>16}")
med, cpu = {}, {}
for (name, m, b), v in runs.items():
    ts = [x[0] for x in v]
    cs = [x[1] for x in v]
    med[(name, m, b)] = statistics.median(ts)
    cpu[(name, m, b)] = statistics.median(cs)
    print(f"{name:<14} {m:<8} {b:<24} {v[0][4]:>4} {med[(name, m, b)]:>9.2f} {' '.join(f'{x:.2f}' for x in ts):<20} {cpu[(name, m, b)]:>7.2f} {' '.join(f'{x:.2f}' for x in cs):<20} {v[0][2]:>20} {v[0][3]:>16}")
bins = list(OrderedDict.fromkeys(b for (_, _, b) in runs))
names = list(OrderedDict.fromkeys(n for (n, _, _) in runs))
print()
print("ratios of medians, render time (CPU time of the process incl. load); > 1: the first is slower")
for n in names:
    for b in bins:
        k1, k2 = (n, 'pyramid', b), (n, 'global', b)
        print(f"  {n:<14} {b:<24} pyramid / global = {med[k1] / med[k2]:.2f} ({cpu[k1] / cpu[k2]:.2f})")
    for b in bins[1:]:
        k1, k2 = (n, 'pyramid', bins[0]), (n, 'pyramid', b)
        print(f"  {n:<14} pyramid {bins[0]} / {b} = {med[k1] / med[k2]:.2f} ({cpu[k1] / cpu[k2]:.2f})")
PY
