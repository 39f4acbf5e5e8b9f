#!/usr/bin/env bash
# The cost of textured voxel/fbm interiors (docs/textures.md, "Density fields read at the entry
# point") on scenes/fbm_creature.toml: its fBm interior with (1) a constant albedo
# [230, 153, 115] / 255, (2) that albedo from a one-value texture read at the entry point (the
# same walks: the difference is the machinery's cost), (3) a 256x256 'veins' albedo texture and
# (4) a mask texture as density (x 2) (both change the look, so their walks differ too).
# Deterministic instruction counts (valgrind --tool=callgrind, 1 thread) at a small size.
#
#   tools/bench_texfields.sh [VELOUR_BINARY] [WIDTH HEIGHT SPP]   # default: target/release/velour 32 24 4
set -euo pipefail
cd "$(dirname "$0")/.."
bin=$(realpath "${1:-target/release/velour}")
w=${2:-32}; h=${3:-24}; spp=${4:-4}
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
cp -r scenes/meshes "$dir/"
python3 tools/make_texture.py veins "$dir/veins.png" 256
python3 tools/make_texture.py mask "$dir/mask.png" 64
python3 tools/make_texture.py constant "$dir/one.png" 230 153 115 4
rest='attenuation = [0.3, 0.12, 0.08], phase = { g = 0.3 }, nee = "exit", noise = { frequency = 6.0, octaves = 4, offset = 0.45, amplitude = 0.9, min = 0.05, max = 1.0 }, voxel_size = 0.008'
constant="interior = { type = \"fbm\", albedo = [0.901960784, 0.6, 0.450980392], $rest }"
one="interior = { type = \"fbm\", albedo = { texture = \"one.png\", colorspace = \"linear\" }, $rest }"
veins="interior = { type = \"fbm\", albedo = { texture = \"veins.png\" }, $rest }"
density="interior = { type = \"fbm\", albedo = [0.901960784, 0.6, 0.450980392], density = { texture = \"mask.png\", scale = 2.0 }, $rest }"
names="constant one_value veins density"
for name in $names; do
  case $name in
    constant) line=$constant ;;
    one_value) line=$one ;;
    veins) line=$veins ;;
    density) line=$density ;;
  esac
  awk -v l="$line" '/^interior = \{ type = "fbm"/{print l; next} {print}' \
    scenes/fbm_creature.toml >"$dir/$name.toml"
  grep -qF -- "$line" "$dir/$name.toml"
done
echo "load average: $(cut -d' ' -f1-3 /proc/loadavg)"
printf '| interior | instructions (%sx%s, %s spp, 1 thread) |\n|---|---|\n' "$w" "$h" "$spp"
for name in $names; do
  n=$(valgrind --tool=callgrind --callgrind-out-file="$dir/cg.$name" "$bin" render "$dir/$name.toml" \
      --width "$w" --height "$h" --spp "$spp" --seed 7 --threads 1 -q --checkpoint 100000 -o "$dir/$name.exr" 2>&1 \
      | sed -n 's/.*Collected : //p')
  printf '| %s | %s |\n' "$name" "$n"
done
