#!/usr/bin/env bash
# Generates the peer benchmarks' large inputs into tools/peers/generated/ (ignored by git), each
# only when it is missing:
#   fbm_cloud_128.vdb   make_fbm_cloud.py (deterministic fBm density, 128^3 over a unit box)
#   fbm_cloud_256.vdb   resample_grid.py --factor 2 (the same world-space field, finer voxels)
#   fbm_cloud_512.vdb   resample_grid.py --factor 4
#   icosphere_20k.ply   make_icosphere.py (20480 triangles)
#   step.vdb            make_step_grid.py (the grid-convention probe)
# The grids need numpy and OpenVDB's Python bindings in ${VELOUR_PEERS_OPENVDB_PYTHON:-/usr/bin/python3}
# (Debian: apt-get install -y python3-openvdb). With --no-512 the 512^3 grid (130 MB) is skipped.
# Exit status 3 when the OpenVDB bindings are missing (the caller skips the grid scenes).
set -euo pipefail
cd "$(dirname "$0")"
OVDB="${VELOUR_PEERS_OPENVDB_PYTHON:-/usr/bin/python3}"
mkdir -p generated
want512=1
[ "${1:-}" = "--no-512" ] && want512=0
[ -f generated/icosphere_20k.ply ] || python3 make_icosphere.py generated/icosphere_20k.ply --subdivisions 5
if ! "$OVDB" -c 'import numpy, pyopenvdb' 2>/dev/null; then
  echo "notice: $OVDB has no numpy/pyopenvdb (apt-get install -y python3-openvdb): the fBm cloud grids are not generated" >&2
  exit 3
fi
[ -f generated/step.vdb ] || "$OVDB" make_step_grid.py generated/step.vdb
[ -f generated/fbm_cloud_128.vdb ] || "$OVDB" make_fbm_cloud.py generated/fbm_cloud_128.vdb --res 128
[ -f generated/fbm_cloud_256.vdb ] || "$OVDB" resample_grid.py generated/fbm_cloud_128.vdb generated/fbm_cloud_256.vdb --factor 2
if [ "$want512" = 1 ]; then
  [ -f generated/fbm_cloud_512.vdb ] || "$OVDB" resample_grid.py generated/fbm_cloud_128.vdb generated/fbm_cloud_512.vdb --factor 4
fi
exit 0
