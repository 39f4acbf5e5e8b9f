#!/usr/bin/env bash
# The cost of projection = "surface" on a voxel interior (docs/textures.md, "Density fields
# projected to the surface"; docs/BENCHMARKS.md, "Textured skin") on scenes/vdb_character.toml:
# its voxel skin interior with (1) a constant albedo [235, 128, 89] / 255, (2) that albedo from
# a one-value texture read at the entry point, (3) the same texture projected to the surface
# (the same look as (1) and (2): the differences are the machinery's cost), and (4, 5) the
# creature's veins albedo map (scenes/textures/creature_albedo.png) read at the entry point and
# projected to the surface (two looks). Deterministic instruction counts (valgrind
# --tool=callgrind, 1 thread) at two sample counts, so that loading (the VDB, its pyramid and
# the closest-point BVH) can be told from rendering, then interleaved wall-clock seconds (noisy
# on a shared machine; the load average is printed).
#
#   tools/bench_projfield.sh [VELOUR_BINARY] [WIDTH HEIGHT SPP_LOW SPP_HIGH RUNS]
#   # defaults: target/release/velour 64 48 2 8 3
set -euo pipefail
cd "$(dirname "$0")/.."
bin=$(realpath "${1:-target/release/velour}")
w=${2:-64}; h=${3:-48}; lo=${4:-2}; hi=${5:-8}; runs=${6:-3}
dir=$(mktemp -d)
trap 'rm -rf "$dir" scenes/.bench_pf_*.toml' EXIT
python3 tools/make_texture.py constant "$dir/one.png" 235 128 89 4
orig='albedo = [0.92, 0.5, 0.35]'
grep -qF -- "$orig" scenes/vdb_character.toml
names="constant one_entry one_surface veins_entry veins_surface"
for name in $names; do
  case $name in
    constant) new='albedo = [0.921568627, 0.501960784, 0.349019608]' ;;
    one_entry) new="albedo = { texture = \"$dir/one.png\", colorspace = \"linear\" }, projection = \"entry\"" ;;
    one_surface) new="albedo = { texture = \"$dir/one.png\", colorspace = \"linear\" }, projection = \"surface\"" ;;
    veins_entry) new='albedo = { texture = "textures/creature_albedo.png" }, projection = "entry"' ;;
    veins_surface) new='albedo = { texture = "textures/creature_albedo.png" }, projection = "surface"' ;;
  esac
  awk -v o="$orig" -v n="$new" '{ i = index($0, o); if (i) $0 = substr($0, 1, i - 1) n substr($0, i + length(o)); print }' \
    scenes/vdb_character.toml >"scenes/.bench_pf_$name.toml"
  grep -qF -- "$new" "scenes/.bench_pf_$name.toml"
done
echo "load average: $(cut -d' ' -f1-3 /proc/loadavg)"
printf '| interior | instructions, %s spp | %s spp | render, %s spp more |\n|---|---|---|---|\n' "$lo" "$hi" "$((hi - lo))"
count() {
  valgrind --tool=callgrind --callgrind-out-file="$dir/cg.$1.$2" "$bin" render "scenes/.bench_pf_$1.toml" \
    --width "$w" --height "$h" --spp "$2" --seed 7 --threads 1 -q --checkpoint 100000 -o "$dir/$1.exr" 2>&1 \
    | sed -n 's/.*Collected : //p'
}
for name in $names; do
  a=$(count "$name" "$lo")
  b=$(count "$name" "$hi")
  printf '| %s | %s | %s | %s |\n' "$name" "$a" "$b" "$((b - a))"
done
echo "load average: $(cut -d' ' -f1-3 /proc/loadavg)"
printf '\n| interior | seconds per render (%sx%s, %s spp, 2 threads), %s interleaved runs |\n|---|---|\n' \
  "$((w * 4))" "$((h * 4))" "$hi" "$runs"
declare -A t
for run in $(seq "$runs"); do
  for name in $names; do
    s=$(date +%s.%N)
    "$bin" render "scenes/.bench_pf_$name.toml" --width "$((w * 4))" --height "$((h * 4))" --spp "$hi" \
      --threads 2 -q --checkpoint 100000 -o "$dir/$name.exr" >/dev/null 2>&1
    e=$(date +%s.%N)
    t[$name]="${t[$name]:-} $(echo "$e - $s" | bc -l | cut -c1-5)"
  done
done
for name in $names; do printf '| %s |%s |\n' "$name" "${t[$name]}"; done
echo "load average: $(cut -d' ' -f1-3 /proc/loadavg)"
