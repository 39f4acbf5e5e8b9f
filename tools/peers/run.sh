#!/usr/bin/env bash
# Peer comparison: velour against Mitsuba 3 on the same machine, in one run.
#
#   tools/peers/run.sh [--spp N] [--passes K] [--width W] [--height H] [--threads T] [SCENE.toml ...]
#
# Creates a virtual environment under ${VELOUR_PEERS_CACHE:-~/.cache/velour-peers} with
# mitsuba, numpy and OpenEXR from PyPI (once), builds velour in release mode, and runs
# tools/peers/compare.py on the given scenes (default: tools/peers/scenes/*.toml). Results
# (EXRs of both renderers, results.json, results.md) go to ${VELOUR_PEERS_OUT:-out/peers}.
# Scenes with voxel interiors also need OpenVDB's Python bindings in the system Python
# (apt-get install -y python3-openvdb; ${VELOUR_PEERS_OPENVDB_PYTHON:-/usr/bin/python3}), else
# they are skipped with the reason.
# See docs/peers.md for the conventions and docs/BENCHMARKS-peers.md for recorded results.
set -euo pipefail
cd "$(dirname "$0")/../.."

CACHE="${VELOUR_PEERS_CACHE:-$HOME/.cache/velour-peers}"
OUT="${VELOUR_PEERS_OUT:-out/peers}"
PY="${PYTHON:-python3}"

if ! "$PY" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else 1)'; then
  echo "error: Python >= 3.11 is needed (tomllib)" >&2
  exit 1
fi
if [ ! -x "$CACHE/venv/bin/python" ]; then
  mkdir -p "$CACHE"
  "$PY" -m venv "$CACHE/venv"
fi
if ! "$CACHE/venv/bin/python" -c 'import mitsuba, numpy, OpenEXR' 2>/dev/null; then
  "$CACHE/venv/bin/pip" install --quiet --upgrade pip
  "$CACHE/venv/bin/pip" install --quiet mitsuba numpy OpenEXR
fi

cargo build --release --quiet
VELOUR="$(pwd)/target/release/velour"

ARGS=()
SCENES=()
while [ $# -gt 0 ]; do
  case "$1" in
    --spp|--passes|--width|--height|--threads|--max-depth) ARGS+=("$1" "$2"); shift 2 ;;
    *) SCENES+=("$1"); shift ;;
  esac
done
if [ ${#SCENES[@]} -eq 0 ]; then
  SCENES=(tools/peers/scenes/*.toml)
fi

exec "$CACHE/venv/bin/python" tools/peers/compare.py --velour "$VELOUR" --out "$OUT" "${ARGS[@]}" "${SCENES[@]}"
