#!/usr/bin/python3
"""Compare a level set written by `velour voxelize --levelset` with OpenVDB's own
mesh-to-level-set conversion of the same mesh at the same voxel size (Debian's pyopenvdb).

Usage: /usr/bin/python3 ovdb_mesh_levelset.py MESH.json OURS.vdb [OURS_FOG.vdb]

MESH.json holds {"points": [[x, y, z], ...] (world units), "triangles": [[i, j, k], ...],
"voxel_size": V, "half_width": W}. OpenVDB builds its level set with
FloatGrid.createLevelSetFromPolygons(points, triangles, createLinearTransform(V), W); our file
is read with pyopenvdb (grid `surface`). Prints one JSON object: the class, background and
transform OpenVDB reads from our file, both active voxel counts, the voxels active in both,
the RMS and largest difference of their values in voxels on that common band, the value at
the voxel nearest the mesh's centroid in both grids (inactive interiors), and the sign
agreement of both grids at every voxel active in either, and how many of our voxels OpenVDB
leaves out with the smallest |value| among them in voxels.

With OURS_FOG.vdb (a `voxelize --fog` of the same mesh, ramp width "band" voxels from MESH.json)
it also applies OpenVDB's sdfToFogVolume rules (which pyopenvdb 10 does not bind) to OpenVDB's
own level set of half width "band": min(1, -phi / (band V)) on inside band voxels, 1 on the
inactive inside, 0 outside. It adds the class and active voxel count OpenVDB reads from our fog,
both integrals (sum of value x voxels covered, in voxel units) and both counts of inside voxels
(fog above 1e-4), and
the RMS difference of the values over OpenVDB's inside band voxels.
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


# Inside voxels are counted where the fog exceeds this, leaving out voxels on the surface
# (within 1e-4 B voxels), whose side is a matter of rounding.
DENSE = 1e-4


def compare_fog(pts, tris, dx, band, ours_path):
    ref = vdb.FloatGrid.createLevelSetFromPolygons(
        pts, triangles=tris, transform=vdb.createLinearTransform(dx), halfWidth=band
    )
    ref_sum = 0.0
    ref_inside = 0
    ramp = {}
    for it in ref.citerOnValues():
        if it.value < 0:
            v = min(1.0, -it.value / (band * dx))
            ramp[tuple(it.min)] = v
            ref_sum += v * it.count
            ref_inside += it.count if v > DENSE else 0
    for it in ref.citerOffValues():
        if it.value < 0:
            ref_sum += it.count
            ref_inside += it.count
    ours = vdb.read(ours_path, "density")
    ours_sum = 0.0
    ours_dense = 0
    for it in ours.citerOnValues():
        ours_sum += it.value * it.count
        ours_dense += it.count if it.value > DENSE else 0
    acc = ours.getConstAccessor()
    d2 = [(acc.getValue(k) - v) ** 2 for k, v in ramp.items()]
    return {
        "fog_class": ours.gridClass,
        "fog_background": ours.background,
        "fog_ours_active": ours.activeVoxelCount(),
        "fog_ours_inside": ours_dense,
        "fog_ref_inside": ref_inside,
        "fog_ours_sum": ours_sum,
        "fog_ref_sum": ref_sum,
        "fog_ramp_rms": math.sqrt(sum(d2) / max(len(d2), 1)),
        "fog_ramp_voxels": len(d2),
    }


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
    fog = {}
    if len(sys.argv) > 3:
        fog = compare_fog(pts, tris, dx, float(mesh["band"]), sys.argv[3])
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
                **fog,
            }
        )
    )


main()
