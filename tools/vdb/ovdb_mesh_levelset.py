#!/usr/bin/python3
"""Compare a level set written by `velour voxelize --levelset` with OpenVDB's own
mesh-to-level-set conversion of the same mesh at the same voxel size (Debian's pyopenvdb).

Usage: /usr/bin/python3 ovdb_mesh_levelset.py MESH.json OURS.vdb

MESH.json holds {"points": [[x, y, z], ...] (world units), "triangles": [[i, j, k], ...],
"voxel_size": V, "half_width": W}. OpenVDB builds its level set with
FloatGrid.createLevelSetFromPolygons(points, triangles, createLinearTransform(V), W); our file
is read with pyopenvdb (grid `surface`). Prints one JSON object: the class, background and
transform OpenVDB reads from our file, both active voxel counts, the voxels active in both,
the RMS and largest difference of their values in voxels on that common band, the value at
the voxel nearest the mesh's centroid in both grids (inactive interiors), and the sign
agreement of both grids at every voxel active in either, and how many of our voxels OpenVDB
leaves out with the smallest |value| among them in voxels.
"""
import json
import math
import sys

import numpy as np
import pyopenvdb as vdb


def active(grid):
    out = {}
    for it in grid.citerOnValues():
        if it.count != 1:
            raise SystemExit("unexpected active tile in a level set")
        out[tuple(it.min)] = it.value
    return out


def main():
    mesh = json.load(open(sys.argv[1]))
    ours_path = sys.argv[2]
    dx = float(mesh["voxel_size"])
    hw = float(mesh["half_width"])
    pts = np.array(mesh["points"], dtype=np.float32)
    tris = np.array(mesh["triangles"], dtype=np.uint32)
    ref = vdb.FloatGrid.createLevelSetFromPolygons(
        pts, triangles=tris, transform=vdb.createLinearTransform(dx), halfWidth=hw
    )
    ours = vdb.read(ours_path, "surface")
    a = active(ours)
    b = active(ref)
    common = a.keys() & b.keys()
    diffs = [(a[k] - b[k]) / dx for k in common]
    # Our voxels OpenVDB leaves out: how close to the surface the closest of them is.
    extra = [abs(a[k]) / dx for k in a.keys() - b.keys()]
    rms = math.sqrt(sum(d * d for d in diffs) / max(len(diffs), 1))
    worst = max((abs(d) for d in diffs), default=0.0)
    ra, rb = ours.getConstAccessor(), ref.getConstAccessor()
    sign_mismatch = 0
    for k in a.keys() | b.keys():
        va, vb = ra.getValue(k), rb.getValue(k)
        if (va < 0) != (vb < 0) and min(abs(va), abs(vb)) > 0.5 * dx:
            sign_mismatch += 1
    c = pts.mean(axis=0) / dx
    centre = tuple(int(round(x)) for x in c)
    xf = ours.transform
    print(
        json.dumps(
            {
                "class": ours.gridClass,
                "background": ours.background,
                "ref_background": ref.background,
                "voxel_size": list(xf.voxelSize()),
                "index_to_world_1": list(xf.indexToWorld((1, 2, 3))),
                "ours_active": len(a),
                "ref_active": len(b),
                "common": len(common),
                "rms_voxels": rms,
                "max_voxels": worst,
                "ours_only": len(extra),
                "ours_only_min_voxels": min(extra, default=hw),
                "sign_mismatch": sign_mismatch,
                "centre": list(centre),
                "ours_centre": ra.getValue(centre),
                "ref_centre": rb.getValue(centre),
                "ours_centre_active": ra.isValueOn(centre),
            }
        )
    )


main()
