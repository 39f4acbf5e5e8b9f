#!/usr/bin/env bash
# The cost of textured interiors against a constant one on scenes/skin_sphere.toml (docs/textures.md):
# the same scene with its interior (1) constant (albedo [230, 153, 115] / 255), (2) entry-projected
# with a texture of that one value (the same walks: the difference is the cost of the texture
# machinery), (3) entry-projected with a 256x256 'veins' albedo texture, (4) a blend of two
# homogeneous looks by a mask texture ((3) and (4) change the look, so their walks differ too). Deterministic instruction counts
# (valgrind --tool=callgrind, 1 thread) at a small size, then wall-clock seconds per render at the
# scene's own size, interleaved (noisy on a shared machine; the load average is printed).
#
#   tools/bench_textures.sh [VELOUR_BINARY]     # default: target/release/velour
set -euo pipefail
cd "$(dirname "$0")/.."
bin=$(realpath "${1:-target/release/velour}")
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
cp -r scenes/meshes "$dir/"
python3 tools/make_texture.py veins "$dir/veins.png" 256
python3 tools/make_texture.py mask "$dir/mask.png" 64
python3 tools/make_texture.py constant "$dir/one.png" 230 153 115 4
skin='interior = { type = "homogeneous", albedo = [0.901960784, 0.6, 0.450980392], attenuation = [0.35, 0.15, 0.08], phase = { g = 0.3 }, nee = "exit" }'
one='interior = { type = "homogeneous", albedo = { texture = "one.png", colorspace = "linear" }, attenuation = [0.35, 0.15, 0.08], phase = { g = 0.3 }, nee = "exit", projection = "entry" }'
entry='interior = { type = "homogeneous", albedo = { texture = "veins.png" }, attenuation = [0.35, 0.15, 0.08], phase = { g = 0.3 }, nee = "exit", projection = "entry" }'
blend='interior = { type = "blend", mask = { texture = "mask.png" }, nee = "exit", a = { type = "homogeneous", albedo = [0.9, 0.6, 0.45], attenuation = [0.35, 0.15, 0.08], phase = { g = 0.3 } }, b = { type = "homogeneous", albedo = [0.8, 0.4, 0.4], attenuation = [0.2, 0.08, 0.05], phase = { g = 0.3 } } }'
names="constant one_value entry blend"
for name in $names; do
  case $name in
    constant) line=$skin ;;
    one_value) line=$one ;;
    entry) line=$entry ;;
    blend) line=$blend ;;
  esac
  awk -v l="$line" '/^interior = \{ type = "homogeneous", albedo = \[0.9, 0.6, 0.45\]/{print l; next} {print}' \
    scenes/skin_sphere.toml >"$dir/$name.toml"
done
echo "load average: $(cut -d' ' -f1-3 /proc/loadavg)"
printf '| interior | instructions (64x48, 8 spp, 1 thread) |\n|---|---|\n'
for name in $names; do
  n=$(valgrind --tool=callgrind --callgrind-out-file="$dir/cg.$name" "$bin" render "$dir/$name.toml" \
      --width 64 --height 48 --spp 8 --seed 7 --threads 1 -q --checkpoint 100000 -o "$dir/$name.exr" 2>&1 \
      | sed -n 's/.*Collected : //p')
  printf '| %s | %s |\n' "$name" "$n"
done
printf '\n| interior | seconds per render (320x240, 32 spp, 2 threads), 3 interleaved runs |\n|---|---|\n'
declare -A t
for run in 1 2 3; do
  for name in $names; do
    s=$(date +%s.%N)
    "$bin" render "$dir/$name.toml" --threads 2 -q --checkpoint 100000 -o "$dir/$name.exr" >/dev/null 2>&1
    e=$(date +%s.%N)
    t[$name]="${t[$name]:-} $(echo "$e - $s" | bc -l | cut -c1-5)"
  done
done
for name in $names; do printf '| %s |%s |\n' "$name" "${t[$name]}"; done
echo "load average: $(cut -d' ' -f1-3 /proc/loadavg)"
