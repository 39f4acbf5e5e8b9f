#!/usr/bin/env bash
# The first image: how long the built-in default scene (scenes/creature.toml) takes to render and
# how noisy its creature is, against a high-sample reference (docs/BENCHMARKS.md, "The first
# image").
#
#   tools/first_image.sh [VELOUR_BINARY] [OUT_DIR]     # defaults: target/release/velour, out/first_image
#
# Environment: REF_SPP (default 4096) samples per pixel of the reference; REF (default
# OUT_DIR/reference.exr) reuses an existing reference of the same scene instead of rendering one
# (at 480x360 and 4096 spp that takes about half an hour on 2 cores).
#
# Steps:
#  1. `velour render` of the default scene exactly as an artist runs it (its film settings,
#     all cores); the summary's time, the process's user CPU time and the load average are kept.
#  2. A mask of the creature's pixels: the scene with and without the creature, both inside a
#     large black sphere so that every camera ray hits something (and paths end there), rendered
#     at 4 spp; the pixels whose depth differs (the creature covers some of their samples) are
#     white.
#  3. The reference (`velour reference`, independent seed), unless REF exists.
#  4. `velour diff --mask`: the relative RMSE over the creature's pixels, per pixel
#     (sqrt(mean(((a-b)/b)^2))) and as RMSE over the mean.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-target/release/velour}
out=${2:-out/first_image}
ref_spp=${REF_SPP:-4096}
ref=${REF:-$out/reference.exr}
mkdir -p "$out"
scene=scenes/creature.toml
meshes=$(cd scenes/meshes && pwd)

echo "== 1. default render ($(date -u '+%Y-%m-%d %H:%M UTC'); load before: $(cut -d' ' -f1-3 /proc/loadavg))"
TIMEFORMAT='process: %U s user CPU, %S s system, %R s wall'
time "$bin" render -q -o "$out/first.exr" | tee "$out/render.log"
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"

echo "== 2. creature mask"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
enclosure='
[[object]]
name = "mask enclosure"
shape = "sphere"
radius = 50
surface = { type = "lambertian", reflectance = 0.0 }
'
# The scene file with absolute mesh paths, plus the enclosure; and the same without its objects.
sed "s#file = \"meshes/#file = \"$meshes/#" "$scene" >"$tmp/with.toml"
printf '%s' "$enclosure" >>"$tmp/with.toml"
awk '/^\[\[object\]\]/ { exit } { print }' "$scene" >"$tmp/without.toml"
printf '%s' "$enclosure" >>"$tmp/without.toml"
"$bin" render "$tmp/with.toml" --spp 4 -q -o "$tmp/with.exr" >/dev/null
"$bin" render "$tmp/without.toml" --spp 4 -q -o "$tmp/without.exr" >/dev/null
"$bin" diff "$tmp/with.exr" "$tmp/without.exr" --layer depth --error-scale 1e-9 \
  --error-png "$out/mask.png" >/dev/null
echo "wrote $out/mask.png"

echo "== 3. reference ($ref)"
if [ -f "$ref" ]; then
  echo "reusing $ref"
else
  time "$bin" reference -q --spp "$ref_spp" -o "$ref" | tee "$out/reference.log"
fi

echo "== 4. creature pixels against the reference"
"$bin" diff "$out/first.exr" "$ref" --mask "$out/mask.png" | tee "$out/diff.txt"
