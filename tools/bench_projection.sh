#!/usr/bin/env bash
# The cost of projection = "surface" against "entry" and a constant interior on the textured
# creature (docs/BENCHMARKS.md, "Textured skin"): scenes/creature_textured.toml (entry),
# scenes/creature_veins.toml (the same textures projected to the closest boundary point), and
# the same scene with the skin's interior replaced by the default creature's constant one.
# Deterministic instruction counts (valgrind --tool=callgrind, 1 thread) at a small size, then
# wall-clock seconds interleaved (noisy on a shared machine; the load average is printed).
#
#   tools/bench_projection.sh [VELOUR_BINARY]     # default: target/release/velour
set -euo pipefail
cd "$(dirname "$0")/.."
bin=$(realpath "${1:-target/release/velour}")
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
constant=$(grep '^interior = ' scenes/creature.toml | head -1)
awk -v l="$constant" '/^interior = \{ type = "blend"/{print l; next} {print}' \
  scenes/creature_textured.toml >scenes/.bench_constant.toml
trap 'rm -rf "$dir" scenes/.bench_constant.toml' EXIT
names="constant entry surface"
file() {
  case $1 in
    constant) echo scenes/.bench_constant.toml ;;
    entry) echo scenes/creature_textured.toml ;;
    surface) echo scenes/creature_veins.toml ;;
  esac
}
echo "load average: $(cut -d' ' -f1-3 /proc/loadavg)"
printf '| interior | instructions (64x48, 8 spp, 1 thread) |\n|---|---|\n'
for name in $names; do
  n=$(valgrind --tool=callgrind --callgrind-out-file="$dir/cg.$name" "$bin" render "$(file $name)" \
      --width 64 --height 48 --spp 8 --seed 7 --threads 1 -q --checkpoint 100000 -o "$dir/$name.exr" 2>&1 \
      | sed -n 's/.*Collected : //p')
  printf '| %s | %s |\n' "$name" "$n"
done
printf '\n| interior | seconds per render (240x180, 16 spp, 2 threads), 3 interleaved runs |\n|---|---|\n'
declare -A t
for run in 1 2 3; do
  for name in $names; do
    s=$(date +%s.%N)
    "$bin" render "$(file $name)" --width 240 --height 180 --spp 16 --threads 2 -q --checkpoint 100000 \
      -o "$dir/$name.exr" >/dev/null 2>&1
    e=$(date +%s.%N)
    t[$name]="${t[$name]:-} $(echo "$e - $s" | bc -l | cut -c1-5)"
  done
done
for name in $names; do printf '| %s |%s |\n' "$name" "${t[$name]}"; done
echo "load average: $(cut -d' ' -f1-3 /proc/loadavg)"
