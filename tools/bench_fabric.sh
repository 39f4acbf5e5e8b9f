#!/usr/bin/env bash
# Fabric rendering figures, measured in one run (docs/BENCHMARKS.md):
#   tools/bench_fabric.sh [SPP] [REFERENCE_SPP]     (VELOUR_BENCH_REUSE_REF=1 keeps the last reference)
# The draped cloth (scenes/draped_cloth.toml) at 240x180: a level-0 reference, then each patch
# mip level (0, 1, 2, 3 and "auto") and isotropic extinction at SPP samples per pixel: render
# time, lookups per real collision, and RMSE / bias / z-test against the reference, and the
# efficiency 1/(relative MSE x CPU time). Images stay in ${VELOUR_BENCH_OUT:-out/bench_fabric}.
set -euo pipefail
cd "$(dirname "$0")/.."
spp=${1:-16}
ref_spp=${2:-256}
bin=target/release/velour
cargo build --release -q
tmp=${VELOUR_BENCH_OUT:-out/bench_fabric}
mkdir -p "$tmp"
# The scene at 240x180 in its own file (mip = "auto" chooses per ray, so --width/--height would do too).
sed -e 's|file = "meshes/|file = "'"$PWD"'/scenes/meshes/|' -e 's|^width = .*|width = 240|' \
    -e 's|^height = .*|height = 180|' scenes/draped_cloth.toml > "$tmp/base.toml"
variant() { # name, extra interior keys
  sed 's|nee = "interior" }|nee = "interior", '"$2"' }|' "$tmp/base.toml" > "$tmp/$1.toml"
}
for m in 0 1 2 3; do variant "mip$m" "mip = $m"; done
variant auto 'mip = "auto"'
variant isotropic 'extinction = "isotropic"'
if [ -n "${VELOUR_BENCH_REUSE_REF:-}" ] && [ -f "$tmp/ref.exr" ]; then
  echo "== reference: reusing $tmp/ref.exr"
else
  echo "== reference: mip 0, $ref_spp spp"
  $bin reference "$tmp/mip0.toml" --spp "$ref_spp" -q -o "$tmp/ref.exr" | tail -1
fi
for v in mip0 mip1 mip2 mip3 auto isotropic; do
  echo "-- $v, $spp spp"
  # CPU seconds (user + system, load and voxelisation included): steadier than wall time
  # on a shared machine.
  log=$(/usr/bin/time -f "cpu %U %S" $bin render "$tmp/$v.toml" --spp "$spp" --seed 77 -q -o "$tmp/$v.exr" 2>&1)
  echo "$log" | grep note || true
  secs=$(echo "$log" | awk '/^cpu / { print $2 + $3 }')
  lpc=$(echo "$log" | sed -n 's/.*, \([0-9.]*\) lookups per real collision.*/\1/p')
  $bin diff "$tmp/$v.exr" "$tmp/ref.exr" --json | SECS="$secs" LPC="$lpc" python3 -c '
import json, os, sys
d = json.load(sys.stdin)
z = d.get("z_test") or {}
t = float(os.environ["SECS"])
print("   cpu %.2f s  lookups/real collision %s  rmse %.5f  rel_mse %.5f  bias %+.5f  efficiency %.3f" % (
    t, os.environ["LPC"], d["rmse"], d["rel_mse"], d["mean_bias"], 1.0 / (d["rel_mse"] * t)))
if z:
    print("   z-test: beyond 3 sigma %.3f%% (expected %.3f%%), aggregate bias z %s, %s" % (
        100 * z["frac_above_3"], 100 * z["expected_above_3"],
        ", ".join("%+.2f" % b for b in z["bias_z"]) if isinstance(z["bias_z"], list) else z["bias_z"],
        "consistent" if z["consistent"] else "inconsistent"))'
done
