#!/usr/bin/env bash
# Speed/accuracy figures of the tracking estimators, measured in one run (docs/BENCHMARKS.md).
#   tools/bench_tracking.sh [SPP]        (VELOUR=path/to/velour to measure another build)
# 1. the VDB cloud with the majorant pyramid vs one global majorant (equal spp): time, density
#    lookups per real collision, and agreement (velour diff);
# 2. the fBm creature baked vs evaluated exactly (estimated bounds): time and error vs the baked image.
set -euo pipefail
cd "$(dirname "$0")/.."
spp=${1:-16}
if [ -n "${VELOUR:-}" ]; then
  bin=$VELOUR
else
  bin=target/release/velour
  cargo build --release -q
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
sed 's|file = "../volumes/|file = "'"$PWD"'/volumes/|' scenes/cloud.toml > "$tmp/pyramid.toml"
sed 's|nee = "interior" }|nee = "interior", tracking = { majorant = "global" } }|' "$tmp/pyramid.toml" > "$tmp/global.toml"
echo "== cloud, $spp spp, 200x150"
for v in pyramid global; do
  echo "-- $v"
  $bin render "$tmp/$v.toml" --spp "$spp" --width 200 --height 150 -q -o "$tmp/cloud_$v.exr" | tail -1
done
$bin diff "$tmp/cloud_pyramid.exr" "$tmp/cloud_global.exr" | head -12
sed 's|file = "meshes/|file = "'"$PWD"'/scenes/meshes/|' scenes/fbm_creature.toml > "$tmp/baked.toml"
sed 's|voxel_size = 0.008 }|voxel_size = 0.008, evaluation = "exact", bound = "estimated", trial_samples = 16, safety = 1.25 }|' "$tmp/baked.toml" > "$tmp/exact.toml"
sed 's|voxel_size = 0.008 }|voxel_size = 0.008, evaluation = "lazy", bound = "estimated", trial_samples = 16, safety = 1.25 }|' "$tmp/baked.toml" > "$tmp/lazy.toml"
echo "== fbm creature, 4 spp, 160x120"
for v in baked lazy exact; do
  echo "-- $v"
  /usr/bin/time -f "wall %e s (including load/bake)" $bin render "$tmp/$v.toml" --spp 4 --width 160 --height 120 -q -o "$tmp/fbm_$v.exr" | tail -1
done
$bin diff "$tmp/fbm_exact.exr" "$tmp/fbm_baked.exr" | head -12
$bin diff "$tmp/fbm_lazy.exr" "$tmp/fbm_baked.exr" | head -12
