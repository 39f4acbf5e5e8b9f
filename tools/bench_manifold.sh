#!/usr/bin/env bash
# nee = "exit" (unidirectional: behind a smooth boundary only phase sampling that refracts into
# the light reaches it) against nee = "manifold" (manifold NEE, docs/choosing-estimators.md) on
# a smooth dielectric sphere (IOR 1.4, r = 1) with a scattering interior, lit by a small sphere
# light (r = 0.1 at distance 3.5).
#
#   tools/bench_manifold.sh [VELOUR_BINARY]    # default: target/release/velour
#
# 1. Efficiency: for each estimator, two 64x64 renders at seeds 11 and 12, the rel. MSE between
#    them (`velour diff --json`), the CPU time (user + sys) per render, and the efficiency
#    1/(rel. MSE x CPU s); then the ratio manifold / exit.
# 2. Bias: the image means of long 16x16 renders of both estimators under a larger light
#    (r = 0.3, so that the unidirectional estimator converges), their relative difference and
#    the z-score of the difference per channel (`velour diff`'s bias z), and the manifold
#    walk's failure rates from the render summary.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=$(realpath "${1:-target/release/velour}")
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
scene() { # nee light_radius radiance
  cat <<TOML
[camera]
eye = [0.0, 0.0, 4.0]
look_at = [0.0, 0.0, 0.0]
fov = 30
[film]
width = 64
height = 64
spp = 16
max_depth = 1000
[[light]]
type = "sphere"
center = [-2.0, 2.5, 1.5]
radius = $2
radiance = $3
[[object]]
name = "ball"
shape = "sphere"
radius = 1.0
surface = { type = "dielectric", ior = 1.4 }
interior = { type = "homogeneous", albedo = [0.95, 0.85, 0.7], albedo_mode = "single", density = 2.0, attenuation = [1.0, 0.8, 0.6], phase = { g = 0.3 }, nee = "$1" }
TOML
}
for nee in exit manifold; do
  scene $nee 0.1 500.0 >"$out/small_$nee.toml"
  scene $nee 0.3 60.0 >"$out/large_$nee.toml"
done
echo "load average before: $(cat /proc/loadavg)"
declare -A eff
for s in "exit 512" "manifold 32"; do
  set -- $s
  cpu=()
  for seed in 11 12; do
    t=$( { /usr/bin/time -f "%U %S" "$bin" render "$out/small_$1.toml" -q --spp "$2" --seed $seed \
      --checkpoint 100000 -o "$out/$seed.exr" >/dev/null; } 2>&1 | tail -1)
    cpu+=("$(echo "$t" | awk '{print $1 + $2}')")
  done
  rel=$("$bin" diff --json "$out/11.exr" "$out/12.exr" | grep -m1 '"rel_mse"' | sed 's/.*: *//; s/,//')
  e=$(awk -v a="${cpu[0]}" -v b="${cpu[1]}" -v r="$rel" 'BEGIN { print 1 / (r * (a + b) / 2) }')
  eff[$1]=$e
  awk -v n="$1" -v spp="$2" -v a="${cpu[0]}" -v b="${cpu[1]}" -v r="$rel" -v e="$e" \
    'BEGIN { printf "%-9s %4d spp  cpu %.2f s  rel_mse %.4g  efficiency %.4g\n", n, spp, (a + b) / 2, r, e }'
done
awk -v m="${eff[manifold]}" -v e="${eff[exit]}" 'BEGIN { printf "efficiency ratio manifold / exit: %.1f\n", m / e }'
"$bin" render "$out/large_exit.toml" -q --width 16 --height 16 --spp 16384 --seed 21 \
  --checkpoint 100000 -o "$out/ref.exr" >/dev/null
"$bin" render "$out/large_manifold.toml" -q --width 16 --height 16 --spp 2048 --seed 22 \
  --checkpoint 100000 -o "$out/m.exr" | grep -o 'manifold NEE: .*'
"$bin" diff --json "$out/m.exr" "$out/ref.exr" | awk '
  /"mean_reference"/ && !ref { gsub(/[ ,]/, ""); split($0, a, ":"); ref = a[2] }
  /"mean_bias"/ && !bias { gsub(/[ ,]/, ""); split($0, a, ":"); bias = a[2] }
  /"bias_z"/ { inz = 1; next }
  inz && /\]/ { inz = 0 }
  inz { gsub(/[ ,]/, ""); z = z " " sprintf("%.2f", $0) }
  END { printf "bias (16x16, exit 16384 spp vs manifold 2048 spp, light r = 0.3): manifold - exit = %.3g (%.2f %% of the mean %.4g); z per channel:%s\n", bias, 100 * bias / ref, ref, z }'
echo "load average after: $(cat /proc/loadavg)"
