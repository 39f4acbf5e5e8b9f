#!/usr/bin/env bash
# The peer benchmark race: velour against Mitsuba 3 (LLVM) and Blender Cycles at equal render time.
#
#   tools/peers/run_best.sh [--budget S] [--rounds R] [--reference-seconds S] [--width W] [--height H]
#                           [--threads T] [--seed-offset K] [--no-scalar] [--references-only] [--translate-only]
#                           [SCENE.toml ...]
#
# Default scenes: tools/peers/bench/*.toml. Their large inputs (fBm cloud grids, icosphere) are
# generated on demand into tools/peers/generated/ (tools/peers/generate.sh). Results go to
# ${VELOUR_PEERS_OUT:-out/peers-best} (best.md, best.json, every renderer's EXR, the Mitsuba XML
# and Cycles .blend of each scene, references/ which later runs reuse). --translate-only writes
# the Mitsuba and Cycles files into tools/peers/generated/ and renders nothing.
#
# Installs into ${VELOUR_PEERS_CACHE:-~/.cache/velour-peers} (once):
#   venv/         Python >= 3.11 with mitsuba, numpy, OpenEXR (as tools/peers/run.sh)
#   cycles-venv/  Python 3.11 with bpy==5.0.1, OpenEXR (PyPI's bpy 5.0.1 is built for CPython 3.11
#                 only; the interpreter is ${VELOUR_PEERS_PY311:-python3.11, else pyenv's 3.11})
# Mitsuba's LLVM variant needs libLLVM 19 (Debian: apt-get install -y libllvm19), found through
# DRJIT_LIBLLVM_PATH (default /usr/lib/x86_64-linux-gnu/libLLVM.so.19.1); the grids need OpenVDB's
# Python bindings (apt-get install -y python3-openvdb).
#
# A peer that cannot be installed is skipped with a notice (no Cycles; Mitsuba's scalar variant
# instead of LLVM; no grid scenes); with VELOUR_REQUIRE_EXTERNAL=1 each of those is an error.
# VELOUR_BINARY=path races that velour (e.g. tools/build_pgo.sh's target/pgo/release/velour)
# instead of building target/release/velour.
# See docs/peers.md ("The benchmark race") and docs/BENCHMARKS-peers.md.
set -euo pipefail
cd "$(dirname "$0")/../.."

CACHE="${VELOUR_PEERS_CACHE:-$HOME/.cache/velour-peers}"
OUT="${VELOUR_PEERS_OUT:-out/peers-best}"
PY="${PYTHON:-python3}"
REQUIRE="${VELOUR_REQUIRE_EXTERNAL:-0}"

missing() {
  if [ "$REQUIRE" = "1" ]; then
    echo "error: $1 (VELOUR_REQUIRE_EXTERNAL=1)" >&2
    exit 1
  fi
  echo "notice: $1" >&2
}

ARGS=()
SCENES=()
TRANSLATE=0
while [ $# -gt 0 ]; do
  case "$1" in
    --budget|--rounds|--reference-seconds|--width|--height|--threads|--passes-per-round|--seed-offset) ARGS+=("$1" "$2"); shift 2 ;;
    --no-scalar|--references-only) ARGS+=("$1"); shift ;;
    --translate-only) TRANSLATE=1; ARGS+=("$1"); shift ;;
    *) SCENES+=("$1"); shift ;;
  esac
done
if [ ${#SCENES[@]} -eq 0 ]; then
  SCENES=(tools/peers/bench/*.toml)
fi

# Inputs.
gen=0
tools/peers/generate.sh || gen=$?
if [ "$gen" = 3 ]; then
  missing "no OpenVDB Python bindings: the fBm cloud scenes are skipped"
  KEEP=()
  for s in "${SCENES[@]}"; do grep -q 'type = "voxel"' "$s" || KEEP+=("$s"); done
  SCENES=("${KEEP[@]}")
elif [ "$gen" != 0 ]; then
  exit "$gen"
fi

# Mitsuba.
if ! "$PY" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else 1)'; then
  missing "Python >= 3.11 is needed for the Mitsuba environment; no race"
  exit 0
fi
if [ ! -x "$CACHE/venv/bin/python" ]; then
  mkdir -p "$CACHE"
  "$PY" -m venv "$CACHE/venv"
fi
if ! "$CACHE/venv/bin/python" -c 'import mitsuba, numpy, OpenEXR' 2>/dev/null; then
  "$CACHE/venv/bin/pip" install --quiet --upgrade pip || true
  if ! "$CACHE/venv/bin/pip" install --quiet mitsuba numpy OpenEXR; then
    missing "cannot install mitsuba from PyPI; no race"
    exit 0
  fi
fi
export DRJIT_LIBLLVM_PATH="${DRJIT_LIBLLVM_PATH:-/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1}"
VARIANT=llvm_ad_rgb
if [ ! -f "$DRJIT_LIBLLVM_PATH" ]; then
  missing "no libLLVM 19 at $DRJIT_LIBLLVM_PATH (apt-get install -y libllvm19): Mitsuba runs scalar_rgb only"
  VARIANT=scalar_rgb
fi

# Cycles.
CYCLES_PY=""
PY311="${VELOUR_PEERS_PY311:-}"
if [ -z "$PY311" ]; then
  if command -v python3.11 >/dev/null 2>&1; then PY311="$(command -v python3.11)"
  else PY311="$(ls -d "$HOME"/.pyenv/versions/3.11*/bin/python 2>/dev/null | tail -1 || true)"; fi
fi
if [ -x "$CACHE/cycles-venv/bin/python" ] && "$CACHE/cycles-venv/bin/python" -c 'import bpy, numpy, OpenEXR' 2>/dev/null; then
  CYCLES_PY="$CACHE/cycles-venv/bin/python"
elif [ -n "$PY311" ] && "$PY311" -c 'import sys; sys.exit(0 if sys.version_info[:2] == (3, 11) else 1)' 2>/dev/null; then
  "$PY311" -m venv "$CACHE/cycles-venv" && "$CACHE/cycles-venv/bin/pip" install --quiet --upgrade pip || true
  if "$CACHE/cycles-venv/bin/pip" install --quiet bpy==5.0.1 OpenEXR; then
    CYCLES_PY="$CACHE/cycles-venv/bin/python"
  fi
fi
if [ -z "$CYCLES_PY" ]; then
  missing "cannot set up bpy 5.0.1 (needs CPython 3.11): Cycles is skipped"
fi

# VELOUR_BINARY races a velour built otherwise (e.g. tools/build_pgo.sh's
# target/pgo/release/velour); by default the plain release build.
if [ -n "${VELOUR_BINARY:-}" ]; then
  if [ ! -x "$VELOUR_BINARY" ]; then
    echo "run_best.sh: VELOUR_BINARY=$VELOUR_BINARY is not an executable file" >&2
    exit 2
  fi
  VELOUR="$(cd "$(dirname "$VELOUR_BINARY")" && pwd)/$(basename "$VELOUR_BINARY")"
else
  cargo build --release --quiet
  VELOUR="$(pwd)/target/release/velour"
fi
# velour is named by the last commit that changed its sources (the tools do not change it).
VERSION="$(git log -1 --format=%h -- src Cargo.toml Cargo.lock 2>/dev/null || echo unknown)$(git diff --quiet -- src Cargo.toml Cargo.lock 2>/dev/null || echo '+dirty')"
if [ -n "${VELOUR_BINARY:-}" ]; then
  VERSION="$VERSION ($VELOUR_BINARY)"
fi
if [ "$TRANSLATE" = 1 ]; then
  OUT=tools/peers/generated
fi
exec "$CACHE/venv/bin/python" tools/peers/best.py --velour "$VELOUR" --velour-version "$VERSION" --out "$OUT" \
  --variant "$VARIANT" --cycles-python "$CYCLES_PY" "${ARGS[@]}" "${SCENES[@]}"
