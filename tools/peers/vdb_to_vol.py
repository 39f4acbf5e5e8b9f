#!/usr/bin/env python3
"""Convert one scalar grid of an OpenVDB file into Mitsuba's `.vol` grid format.

Runs under the system Python with Debian's OpenVDB bindings (`python3-openvdb`, module
`pyopenvdb`), which the Mitsuba virtual environment does not have; tools/peers/compare.py calls it
as a subprocess:

    /usr/bin/python3 tools/peers/vdb_to_vol.py IN.vdb GRID OUT.vol [--tint R G B] [--check N]

Prints one JSON object on stdout:

  lo             VDB index (i, j, k) of the first stored sample (file voxel 0, 0, 0)
  res            samples per axis (x, y, z) in the file
  index_to_world the grid's own (linear) transform as a 4x4 row-major matrix acting on column
                 vectors (p_world = M [i j k 1]^T); the object transform is applied by compare.py
  max            largest stored value (the tinted one with --tint)
  nonzero_lo/hi  the tight index box of the non-zero values
  check          with --check N: N random index-space points inside the stored box with the
                 OpenVDB-convention trilinear value there (see below), for compare.py to test
                 Mitsuba's gridvolume against

Conventions (docs/peers.md, "Grid media"): an OpenVDB voxel (i, j, k) is the sample *at*
index-space point (i, j, k); lookups are trilinear between the 8 integer points around
p = world_to_index(x); outside the stored voxels the value is the background, which must be 0.
The file stores the samples of the index box [nonzero_lo - 1, nonzero_hi + 1] (one ring of zeros
around the data), x fastest: data[((z * yres + y) * xres + x) * channels + c]. Mitsuba's
gridvolume puts sample n of an axis with `res` samples at the local coordinate (n + 1/2) / res of
its unit cube, so the cube spans index [lo - 1/2, lo + res - 1/2]; compare.py builds `to_world`
from that. In the outer half voxel Mitsuba clamps to the edge samples, which are the zero ring,
so both renderers see the same continuous field everywhere, including the one-voxel border where
velour interpolates toward the background 0.

With --tint R G B the file has 3 channels, value x (R, G, B) (a chromatic extinction).
"""

import argparse
import json
import struct
import sys

import numpy as np
import pyopenvdb as vdb

from velour_transforms import index_to_world


def trilinear(acc, p):
    """OpenVDB's (and velour's) trilinear lookup at index-space point p."""
    i = np.floor(p).astype(int)
    t = p - i
    s = 0.0
    for dz in (0, 1):
        for dy in (0, 1):
            for dx in (0, 1):
                w = (t[0] if dx else 1 - t[0]) * (t[1] if dy else 1 - t[1]) * (t[2] if dz else 1 - t[2])
                s += w * acc.getValue((int(i[0] + dx), int(i[1] + dy), int(i[2] + dz)))
    return s


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("vdb")
    ap.add_argument("grid")
    ap.add_argument("out")
    ap.add_argument("--tint", type=float, nargs=3, default=None)
    ap.add_argument("--check", type=int, default=0)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()

    grid = vdb.read(args.vdb, args.grid)
    if grid.valueTypeName != "float":
        sys.exit(f"{args.vdb}: grid {args.grid} is {grid.valueTypeName}, not a float grid")
    if not grid.transform.isLinear:
        sys.exit(f"{args.vdb}: grid {args.grid} has a non-linear (frustum) transform")
    if grid.background != 0.0:
        sys.exit(f"{args.vdb}: grid {args.grid} has background {grid.background}; only 0 is translated")
    # Every stored value lives in a leaf (voxels) or a tile; copy the box around both, one voxel
    # wider, then shrink to the non-zero values plus a ring of zeros.
    boxes = [grid.evalLeafBoundingBox(), grid.evalActiveVoxelBoundingBox()]
    lo = np.min([b[0] for b in boxes], axis=0) - 1
    hi = np.max([b[1] for b in boxes], axis=0) + 1
    dims = hi - lo + 1
    dense = np.zeros(tuple(int(d) for d in dims), dtype=np.float32)  # [x][y][z]
    grid.copyToArray(dense, ijk=tuple(int(v) for v in lo))
    nz = np.argwhere(dense != 0.0)
    if nz.size == 0:
        sys.exit(f"{args.vdb}: grid {args.grid} is empty")
    if (dense < 0).any() or not np.isfinite(dense).all():
        sys.exit(f"{args.vdb}: grid {args.grid} has negative or non-finite values")
    nz_lo = lo + nz.min(axis=0)
    nz_hi = lo + nz.max(axis=0)
    a = nz_lo - 1 - lo
    b = nz_hi + 1 - lo + 1
    block = dense[a[0]:b[0], a[1]:b[1], a[2]:b[2]]
    res = np.array(block.shape)
    # The ring around the non-zero values is zero by construction (the copy was one wider than
    # every leaf and tile), which the clamped edge of Mitsuba's texture relies on.
    assert block[0].max() == 0 and block[-1].max() == 0 and block[:, 0].max() == 0
    assert block[:, -1].max() == 0 and block[:, :, 0].max() == 0 and block[:, :, -1].max() == 0
    zyx = np.ascontiguousarray(block.transpose(2, 1, 0))  # C order z, y, x: x fastest
    if args.tint is not None:
        data = zyx[..., None] * np.array(args.tint, dtype=np.float32)
        channels = 3
    else:
        data = zyx[..., None]
        channels = 1
    data = np.ascontiguousarray(data, dtype="<f4")
    m = index_to_world(grid.transform)
    # Bounding box header: the world box of the stored cells (informative: Mitsuba ignores it
    # unless use_grid_bbox is set, and it cannot express a rotated grid; compare.py passes
    # to_world instead).
    c0 = nz_lo - 1 - 0.5
    c1 = nz_hi + 1 + 0.5
    corners = np.array([[x, y, z, 1.0] for x in (c0[0], c1[0]) for y in (c0[1], c1[1]) for z in (c0[2], c1[2])])
    w = (m @ corners.T).T[:, :3]
    with open(args.out, "wb") as f:
        f.write(b"VOL")
        f.write(struct.pack("<B", 3))
        f.write(struct.pack("<i", 1))
        f.write(struct.pack("<4i", int(res[0]), int(res[1]), int(res[2]), channels))
        f.write(struct.pack("<6f", *w.min(axis=0), *w.max(axis=0)))
        f.write(data.tobytes())
    out = {
        "lo": (nz_lo - 1).tolist(),
        "res": res.tolist(),
        "channels": channels,
        "index_to_world": m.tolist(),
        "max": float(data.max()),
        "nonzero_lo": nz_lo.tolist(),
        "nonzero_hi": nz_hi.tolist(),
        "active_voxels": int(grid.activeVoxelCount()),
    }
    if args.check:
        rng = np.random.default_rng(args.seed)
        acc = grid.getConstAccessor()
        pts = []
        for _ in range(args.check):
            # Half the points anywhere in the stored cube (including the clamped half voxel),
            # half near non-zero voxels, where the values are not all 0.
            if rng.random() < 0.5:
                p = c0 + rng.random(3) * (c1 - c0)
            else:
                p = nz[rng.integers(len(nz))] + lo + rng.random(3) * 2.0 - 1.0
            v = trilinear(acc, p)
            pts.append([p.tolist(), v])
        out["check"] = pts
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    main()
