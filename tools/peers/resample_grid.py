#!/usr/bin/env python3
"""Resample an OpenVDB density grid onto a lattice `factor` times finer, keeping the world field.

    /usr/bin/python3 tools/peers/resample_grid.py IN.vdb OUT.vdb --factor 2 [--grid density]

Needs numpy and OpenVDB's Python bindings (Debian: python3-openvdb, module `pyopenvdb`).

OpenVDB voxels are samples at integer index points, and renderers interpolate trilinearly between
them (docs/peers.md, "Grid media"). The fine grid's voxel size is h / factor and its index point
j sits at the coarse index point j / factor (same world origin), so every fine cell lies inside
one coarse cell. There the coarse field is trilinear, and trilinear interpolation reproduces a
trilinear function exactly from its corner values: sampling the coarse field at the fine lattice
points therefore gives a fine grid whose trilinear field is the coarse one, up to float32
rounding (checked at random points before writing). The coarse grid must have background 0 and
zero values on the faces of its stored box (make_fbm_cloud.py's cloud has a zero border), so the
fine grid needs no values outside the coarse data's index box.

For the 128^3 cloud (voxel 1/128 of its box): factor 2 gives the 256^3 grid (voxel 1/256; the
non-zero values fill an active box of 231 x 229 x 229 voxels), factor 4 the 512^3 grid (voxel
1/512; 463 x 459 x 459, 38 M active voxels). Only non-zero values are stored.
"""

import argparse
import sys

import numpy as np

from velour_transforms import index_to_world


def trilinear_dense(dense, p):
    """Trilinear value of a dense array (index = array index) at points p (N, 3); 0 outside."""
    f = np.floor(p).astype(np.int64)
    t = p - f
    out = np.zeros(len(p))
    shape = np.array(dense.shape)
    for dz in (0, 1):
        for dy in (0, 1):
            for dx in (0, 1):
                q = f + np.array([dx, dy, dz])
                inside = np.all((q >= 0) & (q < shape), axis=1)
                v = np.zeros(len(p))
                v[inside] = dense[q[inside, 0], q[inside, 1], q[inside, 2]]
                w = (t[:, 0] if dx else 1 - t[:, 0]) * (t[:, 1] if dy else 1 - t[:, 1]) * (t[:, 2] if dz else 1 - t[:, 2])
                out += w * v
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("input")
    ap.add_argument("output")
    ap.add_argument("--factor", type=int, required=True)
    ap.add_argument("--grid", default="density")
    args = ap.parse_args()
    import pyopenvdb as vdb

    f = args.factor
    if f < 1:
        sys.exit("--factor must be >= 1")
    grid = vdb.read(args.input, args.grid)
    if grid.background != 0.0 or not grid.transform.isLinear:
        sys.exit(f"{args.input}: grid {args.grid} needs background 0 and a linear transform")
    lo, hi = grid.evalActiveVoxelBoundingBox()
    lo = np.array(lo) - 1
    hi = np.array(hi) + 1
    coarse = np.zeros(tuple(int(v) for v in hi - lo + 1), dtype=np.float32)
    grid.copyToArray(coarse, ijk=tuple(int(v) for v in lo))
    if coarse[0].max() or coarse[-1].max() or coarse[:, 0].max() or coarse[:, -1].max() or coarse[:, :, 0].max() or coarse[:, :, -1].max():
        sys.exit("internal error: the copied box does not have a zero border")
    # Fine lattice points j in [f lo, f hi] cover the coarse box; fine point j is at coarse index j / f.
    n = (np.array(coarse.shape) - 1) * f + 1
    c = coarse.astype(np.float64)
    fine_grid = vdb.FloatGrid(0.0)
    fine_grid.name = grid.name
    fine_grid.gridClass = grid.gridClass
    # Separable exact evaluation: along each axis, fine point j lies between coarse points
    # floor(j / f) and floor(j / f) + 1 with weight (j mod f) / f.
    def upsample_axis(a, axis):
        m = a.shape[axis]
        j = np.arange((m - 1) * f + 1)
        i0 = np.minimum(j // f, m - 1)
        i1 = np.minimum(i0 + 1, m - 1)
        w = (j - i0 * f) / f
        shape = [1] * a.ndim
        shape[axis] = len(j)
        w = w.reshape(shape)
        return np.take(a, i0, axis=axis) * (1 - w) + np.take(a, i1, axis=axis) * w

    slab = max(1, 64 // f)  # coarse z-slabs per step (keeps the 512^3 case in memory)
    z = 0
    while z < c.shape[2] - 1:
        z1 = min(c.shape[2] - 1, z + slab)
        block = upsample_axis(upsample_axis(upsample_axis(c[:, :, z:z1 + 1], 0), 1), 2)
        if z1 < c.shape[2] - 1:
            block = block[:, :, :-1]  # the last plane belongs to the next slab
        block = block.astype(np.float32)
        fine_grid.copyFromArray(block, ijk=tuple(int(v) for v in (lo[0] * f, lo[1] * f, (lo[2] + z) * f)), tolerance=0.0)
        z = z1
    m = index_to_world(grid.transform)
    mf = m.copy()
    mf[:3, :3] = m[:3, :3] / f
    fine_grid.transform = vdb.createLinearTransform(mf.T.tolist())
    # Check: the fine grid's trilinear field equals the coarse one at random world points.
    rng = np.random.default_rng(1)
    pts = lo + rng.random((4000, 3)) * (hi - lo)
    want = trilinear_dense(c, pts - lo)
    fine_lo = np.array(fine_grid.evalActiveVoxelBoundingBox()[0]) - 1
    fine_hi = np.array(fine_grid.evalActiveVoxelBoundingBox()[1]) + 1
    # Only the neighbourhood of each point is needed: look the fine values up through an accessor.
    acc = fine_grid.getConstAccessor()
    worst = 0.0
    for p, w in zip(pts, want):
        q = p * f
        i = np.floor(q).astype(int)
        t = q - i
        s = 0.0
        for dz in (0, 1):
            for dy in (0, 1):
                for dx in (0, 1):
                    wt = (t[0] if dx else 1 - t[0]) * (t[1] if dy else 1 - t[1]) * (t[2] if dz else 1 - t[2])
                    s += wt * acc.getValue((int(i[0] + dx), int(i[1] + dy), int(i[2] + dz)))
        worst = max(worst, abs(s - w))
    if worst > 1e-5:
        sys.exit(f"resampled field differs from the original by {worst}")
    vdb.write(args.output, grids=[fine_grid])
    dims = fine_hi - fine_lo - 1
    print(f"{args.output}: factor {f}, fine lattice {n.tolist()}, active bbox {dims.tolist()}, voxel {mf[0, 0]:g}, "
          f"active {fine_grid.activeVoxelCount()}, max |field difference| at 4000 points {worst:.2e}")


if __name__ == "__main__":
    main()
