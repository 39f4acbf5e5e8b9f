#!/usr/bin/env bash
# Bit-exact fingerprints of every shipped scene at a fixed seed, for checking that a change
# which should not alter images does not (docs/checksums.md records the table).
#
#   tools/checksums.sh [VELOUR_BINARY]      # default: target/release/velour
#
# Each scene renders at 96x72, 8 spp, seed 7, 2 threads (images are identical across thread
# counts), and the table prints `velour checksum` of the EXR: the SHA-256 of its pixels (beauty,
# variance, albedo, normal, depth, sample count), not of its header, which holds the render
# time and the command line.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-target/release/velour}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
printf '| scene | SHA-256 of the pixels (first 16 hex digits) |\n|---|---|\n'
for scene in default scenes/*.toml tools/peers/scenes/*.toml; do
  name=$(basename "$scene" .toml)
  args=()
  [ "$scene" != default ] && args=("$scene")
  "$bin" render "${args[@]}" --width 96 --height 72 --spp 8 --seed 7 --threads 2 -q \
    --checkpoint 100000 -o "$out/$name.exr" >"$out/$name.log" 2>&1 || { echo "| $name | render failed: $(tail -1 "$out/$name.log") |"; continue; }
  sum=$("$bin" checksum "$out/$name.exr" | cut -c1-64)
  echo "| $name | ${sum:0:16} |"
done
