#!/usr/bin/env bash
# The cost of textured yarn colours on a fabric shell (docs/textures.md, "Fabric yarn colours")
# on scenes/draped_cloth.toml: its warp colour (1) as the constant [184, 26, 23] / 255, (2) from
# a one-value texture of that colour read at the entry point (the same walks up to the last bits
# of the colour: the difference is the machinery's cost: a per-walk medium, three texture reads
# per free flight and shadow segment, the colour's inversion at each scattering vertex), and
# (3) a 64x64 printed check (another look, so other walks). Deterministic instruction counts
# (valgrind --tool=callgrind, 1 thread) at a small size: the whole run (load included) and
# the render alone (velour::integrator::trace_path and below).
#
#   tools/bench_texfabric.sh [VELOUR_BINARY] [WIDTH HEIGHT SPP]   # default: target/release/velour 64 48 8
set -euo pipefail
cd "$(dirname "$0")/.."
bin=$(realpath "${1:-target/release/velour}")
w=${2:-64}; h=${3:-48}; spp=${4:-8}
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
cp -r scenes/meshes "$dir/"
python3 tools/make_texture.py check "$dir/check.png" 64
python3 tools/make_texture.py constant "$dir/one.png" 184 26 23 4
names="constant one_value check"
for name in $names; do
  case $name in
    constant) warp='[0.721568627, 0.101960784, 0.090196078]' ;;
    one_value) warp='{ texture = "one.png", colorspace = "linear" }' ;;
    check) warp='{ texture = "check.png" }' ;;
  esac
  sed "s|warp_albedo = \[0.72, 0.1, 0.09\]|warp_albedo = $warp|" scenes/draped_cloth.toml >"$dir/$name.toml"
  grep -qF -- "warp_albedo = $warp" "$dir/$name.toml"
done
echo "load average: $(cut -d' ' -f1-3 /proc/loadavg)"
printf '| warp colour | instructions, whole run | instructions in trace_path | (%sx%s, %s spp, 1 thread) |\n|---|---|---|---|\n' "$w" "$h" "$spp"
for name in $names; do
  out=$(valgrind --tool=callgrind --callgrind-out-file="$dir/cg.$name" "$bin" render "$dir/$name.toml" \
      --width "$w" --height "$h" --spp "$spp" --seed 7 --threads 1 -q --checkpoint 100000 -o "$dir/$name.exr" 2>&1)
  total=$(echo "$out" | sed -n 's/.*Collected : //p')
  callgrind_annotate --inclusive=yes "$dir/cg.$name" >"$dir/annotate.$name" 2>/dev/null
  inner=$(awk '/velour::integrator::trace_path/ {print $1; exit}' "$dir/annotate.$name")
  printf '| %s | %s | %s | |\n' "$name" "$total" "$inner"
done
