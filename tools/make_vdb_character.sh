#!/bin/sh
# Builds the VDB character's volume (scenes/vdb_character.toml) with `velour voxelize`: the
# creature's skin mesh (scenes/meshes/creature_skin.ply, from tools/make_creature.py) becomes
# a fog volume whose density ramps from 0 at the skin to 1 across 4 voxels inside and is
# modulated by rest-space fBm noise, so the flesh is uneven: denser lobes and thinner channels
# that light bleeds through.
#
# Usage: tools/make_vdb_character.sh [VELOUR]     (default: target/release/velour, built if missing)
# Writes volumes/vdb_character.vdb (about 0.5 MB). With LEVELSET=1 it also writes the skin as a
# level set, volumes/vdb_character_skin.vdb (grid `surface`), for a level-set boundary.
set -eu
cd "$(dirname "$0")/.."
VELOUR=${1:-target/release/velour}
if [ ! -x "$VELOUR" ]; then
    cargo build --release
fi
SKIN=scenes/meshes/creature_skin.ply
VOXEL=0.0125   # scene units (the head is about 1 unit tall: ~90 voxels)
"$VELOUR" voxelize "$SKIN" -o volumes/vdb_character.vdb --voxel-size "$VOXEL" \
    --fog --band 4 --noise-frequency 5 --noise-amplitude 2.5 --noise-octaves 4 --noise-seed 3
if [ "${LEVELSET:-0}" = 1 ]; then
    "$VELOUR" voxelize "$SKIN" -o volumes/vdb_character_skin.vdb --voxel-size "$VOXEL" \
        --levelset --half-width 3
fi
ls -l volumes/vdb_character*.vdb
