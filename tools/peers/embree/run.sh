#!/usr/bin/env bash
# Embree peer of `cargo bench --bench ray_casting`: the same mesh and rays, closest-hit and
# occlusion rays per second with rtcIntersect1 / rtcOccluded1 in a loop, one thread, run
# concurrently with velour's bench (ratios in one run). Skips with a notice when neither
# Embree 4 nor Embree 3 headers and library are found. See README.md.
#
# Environment: EMBREE_INCLUDE / EMBREE_LIB (directories; an Embree 4 install, e.g. headers from
# the embree repository with the library of the `embreex` wheel), EMBREE_CONFIG (rtcNewDevice
# config, default "threads=1"; "threads=1,max_isa=avx2" for velour's ISA), PAIRS (default 2),
# RAY_CASTING_RAYS / RAY_CASTING_SUBDIV (passed to both benches), EMBREE_ROBUST=1 (Embree's
# robust mode), RECORDED=path (time the queries of a ray log recorded from a render, see
# README.md, instead of the synthetic sets; the start order alternates between pairs).
set -euo pipefail
cd "$(dirname "$0")/../../.."
out=${OUT:-/tmp/velour_embree}
mkdir -p "$out"
src=tools/peers/embree/embree_rays.cpp
cxx=${CXX:-g++}
if ! command -v "$cxx" >/dev/null; then
  echo "embree peer: no C++ compiler ($cxx); skipped"
  exit 0
fi
inc=${EMBREE_INCLUDE:-/usr/include}
lib=${EMBREE_LIB:-}
flags=(-O3 -march=native -o "$out/embree_rays" "$src")
if [ -f "$inc/embree4/rtcore.h" ]; then
  flags+=(-DEMBREE4=1 -I"$inc" ${lib:+-L"$lib" -Wl,-rpath,"$lib"} -lembree4)
elif [ -f "$inc/embree3/rtcore.h" ]; then
  flags+=(-I"$inc" ${lib:+-L"$lib" -Wl,-rpath,"$lib"} -lembree3)
else
  echo "embree peer: no Embree 4 or 3 headers under $inc (apt-get install libembree-dev, or set EMBREE_INCLUDE/EMBREE_LIB); skipped"
  exit 0
fi
if ! "$cxx" "${flags[@]}" 2>"$out/build.log"; then
  echo "embree peer: the C++ bench does not build against Embree (see $out/build.log); skipped"
  exit 0
fi
bench=$(cargo bench --bench ray_casting --no-run --message-format=json 2>/dev/null |
  sed -n 's/.*"executable":"\([^"]*ray_casting[^"]*\)".*/\1/p' | tail -1)
cp "$bench" "$out/velour_bench"
if [ -n "${RECORDED:-}" ]; then
  for i in $(seq "${PAIRS:-2}"); do
    echo "== pair $i ($([ $((i % 2)) = 1 ] && echo velour || echo embree) started first)"
    if [ $((i % 2)) = 1 ]; then
      RAY_CASTING_RECORDED="$RECORDED" "$out/velour_bench" >"$out/velour_$i.txt" &
      "$out/embree_rays" "$RECORDED" "${EMBREE_CONFIG:-threads=1}" >"$out/embree_$i.txt"
    else
      "$out/embree_rays" "$RECORDED" "${EMBREE_CONFIG:-threads=1}" >"$out/embree_$i.txt" &
      RAY_CASTING_RECORDED="$RECORDED" "$out/velour_bench" >"$out/velour_$i.txt"
    fi
    wait
    cat "$out/velour_$i.txt" "$out/embree_$i.txt"
  done
  exit 0
fi
# The rays, written once by velour's bench (its timed passes are not used).
RAY_CASTING_DUMP="$out/rays.bin" "$out/velour_bench" >/dev/null
for i in $(seq "${PAIRS:-2}"); do
  echo "== pair $i"
  "$out/velour_bench" >"$out/velour_$i.txt" &
  "$out/embree_rays" "$out/rays.bin" "${EMBREE_CONFIG:-threads=1}" >"$out/embree_$i.txt"
  wait
  cat "$out/velour_$i.txt" "$out/embree_$i.txt"
done
