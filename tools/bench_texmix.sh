#!/usr/bin/env bash
# The cost of textured mixture components and textured base media (docs/textures.md, "Mixtures
# read at the entry point") on a unit sphere (index-matched boundary, sky and sun, interior NEE)
# filled with (1) a constant mixture of a homogeneous medium and an fBm field, (2) the same with
# the homogeneous component's albedo from a one-value texture, (3) with the fBm component's
# density from a one-value texture, (4) an fBm interior with a constant base medium
# (`base_albedo`, `base_attenuation`: the combined tracker) and (5) the same with the base
# albedo from a one-value texture (tracked as a two-component mixture). One-value textures give
# the same image in expectation, so (2)-(3) against (1) is the machinery's cost: the texture
# reads per interior step (the walk's medium is rebuilt from the entry point each time), and
# (5) against (4) adds the change of tracker.
# Deterministic instruction counts (valgrind --tool=callgrind, 1 thread) at SPP and 3 x SPP:
# the fBm bake is the same in both, so the difference is the render's.
#
#   tools/bench_texmix.sh [VELOUR_BINARY] [WIDTH HEIGHT SPP]   # default: target/release/velour 32 24 4
set -euo pipefail
cd "$(dirname "$0")/.."
bin=$(realpath "${1:-target/release/velour}")
w=${2:-32}; h=${3:-24}; spp=${4:-4}
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
python3 tools/make_texture.py constant "$dir/one.png" 230 153 115 4
python3 tools/make_texture.py constant "$dir/grey.png" 128 128 128 4
head='[camera]
eye = [0, 0, 4]
look_at = [0, 0, 0]
fov = 36
[film]
width = 32
height = 24
spp = 4
max_depth = 256
[[light]]
type = "environment"
radiance = 1.0
[[light]]
type = "distant"
direction = [0.5, 0.6, 0.6]
irradiance = 2.0
[[object]]
name = "ball"
shape = "sphere"'
fbm='type = "fbm", noise = { frequency = 3.0, offset = 0.4, amplitude = 1.0 }, voxel_size = 0.04, phase = { g = 0.6 }'
water='type = "homogeneous", attenuation = [0.6, 0.8, 1.2]'
albedo='[0.901960784, 0.6, 0.450980392]'
declare -A interior
interior[constant]="{ type = \"mixture\", nee = \"interior\", media = [{ $water, albedo = $albedo }, { $fbm, attenuation = 0.25, density = 1.0 }] }"
interior[albedo_texture]="{ type = \"mixture\", nee = \"interior\", media = [{ $water, albedo = { texture = \"one.png\", colorspace = \"linear\" } }, { $fbm, attenuation = 0.25, density = 1.0 }] }"
interior[density_texture]="{ type = \"mixture\", nee = \"interior\", media = [{ $water, albedo = $albedo }, { $fbm, attenuation = 0.25, density = { texture = \"grey.png\", colorspace = \"linear\", scale = 1.9921875 } }] }"
interior[base_constant]="{ $fbm, nee = \"interior\", attenuation = 0.25, base_albedo = $albedo, base_attenuation = [0.6, 0.8, 1.2] }"
interior[base_texture]="{ $fbm, nee = \"interior\", attenuation = 0.25, base_albedo = { texture = \"one.png\", colorspace = \"linear\" }, base_attenuation = [0.6, 0.8, 1.2] }"
names="constant albedo_texture density_texture base_constant base_texture"
for name in $names; do
  printf '%s\ninterior = %s\n' "$head" "${interior[$name]}" >"$dir/$name.toml"
done
count() {
  valgrind --tool=callgrind --callgrind-out-file="$dir/cg.$1.$2" "$bin" render "$dir/$1.toml" \
    --width "$w" --height "$h" --spp "$2" --seed 7 --threads 1 -q --checkpoint 100000 -o "$dir/$1.exr" 2>&1 \
    | sed -n 's/.*Collected : //p'
}
echo "load average: $(cut -d' ' -f1-3 /proc/loadavg)"
printf '| interior | instructions, %s spp | %s spp | render, %s spp |\n|---|---|---|---|\n' "$spp" "$((3 * spp))" "$((2 * spp))"
for name in $names; do
  a=$(count "$name" "$spp")
  b=$(count "$name" "$((3 * spp))")
  printf '| %s | %s | %s | %s |\n' "$name" "$a" "$b" "$((b - a))"
done
