#!/usr/bin/env bash
# tracking.behind = "survive" against "transmittance" (docs/choosing-estimators.md, "What lies
# behind a medium"): for each scene, two renders at seeds 11 and 12, the rel. MSE between them
# (`velour diff --json`; twice each render's), the CPU time (user + sys) per render, and the
# efficiency 1/(rel. MSE x CPU s).
#
#   tools/bench_behind.sh [VELOUR_BINARY]    # default: target/release/velour
#
# Scenes: a thin fBm puff (σ_t <= 2, HG 0.5, in an index-matched sphere, 32x32, 256 spp) against
# a bright sky (1.0, 1.1, 1.3) under a sun, at single-scattering albedos 0.2, 0.4, 0.6 and 0.9;
# and the thin peer cloud tools/peers/bench/cloud_thin.toml at 96x96, 64 spp (its grid from
# tools/peers/generate.sh; the row is skipped without it).
set -euo pipefail
cd "$(dirname "$0")/.."
bin=$(realpath "${1:-target/release/velour}")
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
puff() {
  cat <<TOML
[camera]
eye = [0, 0, 4]
look_at = [0, 0, 0]
fov = 24
[film]
width = 32
height = 32
spp = 256
max_depth = 64
[[light]]
type = "environment"
radiance = [1.0, 1.1, 1.3]
[[light]]
type = "distant"
direction = [0.5, 0.8, 0.3]
irradiance = [3.0, 2.8, 2.5]
[[object]]
name = "puff"
shape = "sphere"
radius = 0.8
interior = { type = "fbm", voxel_size = 0.05, noise = { frequency = 1.5, octaves = 3, seed = 4 }, albedo = $1, albedo_mode = "single", attenuation = 0.5, phase = { g = 0.5 }, nee = "interior", tracking = { behind = "$2" } }
TOML
}
measure() { # name scene.toml extra-args...
  local name=$1 scene=$2
  shift 2
  local cpu=0
  for seed in 11 12; do
    /usr/bin/time -o "$out/time" -f "%U %S" "$bin" render "$scene" -o "$out/$seed.exr" --seed "$seed" "$@" >/dev/null 2>&1
    cpu=$(python3 -c "print($cpu + sum(map(float, open('$out/time').read().split()[-2:])))")
  done
  local rel
  rel=$("$bin" diff --json "$out/11.exr" "$out/12.exr" | python3 -c 'import json,sys; print(json.load(sys.stdin)["rel_mse"])')
  python3 -c "c=$cpu/2; r=$rel; print(f'| $name | {c:.2f} | {r:.3e} | {1/(r*c):.1f} |')"
}
echo "| scene, behind | CPU s per render | rel. MSE between two renders | efficiency |"
echo "|---|---|---|---|"
for albedo in 0.2 0.4 0.6 0.9; do
  for mode in survive transmittance; do
    puff "$albedo" "$mode" >"$out/puff.toml"
    measure "puff, albedo $albedo, $mode" "$out/puff.toml"
  done
done
if [ -f tools/peers/generated/fbm_cloud_128.vdb ]; then
  for mode in survive transmittance; do
    sed "s#nee = \"interior\" }#nee = \"interior\", tracking = { behind = \"$mode\" } }#; s#\.\./generated#$PWD/tools/peers/generated#" \
      tools/peers/bench/cloud_thin.toml >"$out/thin.toml"
    measure "peer thin cloud, $mode" "$out/thin.toml" --width 96 --height 96 --spp 64
  done
else
  echo "notice: tools/peers/generated/fbm_cloud_128.vdb missing (tools/peers/generate.sh): peer row skipped" >&2
fi
