#!/usr/bin/env bash
# draped_cloth efficiency of one build against another, measured in one run (docs/BENCHMARKS.md):
#   BASE=path/to/old/velour [NEW=path/to/new/velour] tools/bench_draped_race.sh S1 S2 [S3 S4 ...]
# For each pair of seeds, both binaries render scenes/draped_cloth.toml at 160x120, 16 spp, one
# thread, at the same time (start order alternated between the two seeds). Each binary's
# relative MSE is taken between its two seeds' images (`velour diff --json`), its CPU time is
# the mean user time of the two renders, and efficiency is 1/(relative MSE x CPU seconds).
# Prints, per pair, both sides' figures, the CPU ratio and the efficiency ratio new / base.
# Images and times stay in ${VELOUR_BENCH_OUT:-out/bench_draped_race}.
set -euo pipefail
cd "$(dirname "$0")/.."
: "${BASE:?set BASE to the velour binary to compare against}"
NEW=${NEW:-target/release/velour}
[ $# -ge 2 ] && [ $(($# % 2)) -eq 0 ] || { echo "usage: BASE=bin $0 S1 S2 [S3 S4 ...]" >&2; exit 2; }
out=${VELOUR_BENCH_OUT:-out/bench_draped_race}
mkdir -p "$out"
run() { # binary tag seed
  /usr/bin/time -f %U -o "$out/$2-$3.t" "$1" render scenes/draped_cloth.toml --width 160 \
    --height 120 --spp 16 --threads 1 --seed "$3" -q -o "$out/$2-$3.exr" >/dev/null 2>"$out/$2-$3.log"
}
rel_mse() { # image image
  "$NEW" diff --json "$1" "$2" | python3 -c 'import json, sys; print(json.load(sys.stdin)["rel_mse"])'
}
while [ $# -ge 2 ]; do
  a=$1 b=$2
  shift 2
  run "$BASE" base "$a" & run "$NEW" new "$a" & wait
  run "$NEW" new "$b" & run "$BASE" base "$b" & wait
  python3 - "$(rel_mse "$out/base-$a.exr" "$out/base-$b.exr")" \
    "$(rel_mse "$out/new-$a.exr" "$out/new-$b.exr")" \
    "$(cat "$out/base-$a.t")" "$(cat "$out/base-$b.t")" \
    "$(cat "$out/new-$a.t")" "$(cat "$out/new-$b.t")" "$a" "$b" <<'PY'
import sys
bm, nm, ba, bb, na, nb = map(float, sys.argv[1:7])
bc, nc = (ba + bb) / 2, (na + nb) / 2
print(f"seeds {sys.argv[7]},{sys.argv[8]}: base relMSE {bm:.4f} cpu {bc:.2f}  "
      f"new relMSE {nm:.4f} cpu {nc:.2f}  cpu ratio {bc / nc:.3f}  eff ratio {(bm * bc) / (nm * nc):.3f}")
PY
done
