#!/usr/bin/python3
"""Writes a large, sparse fog volume with real OpenVDB for the majorant benchmark.

Usage: /usr/bin/python3 make_sparse.py OUT.vdb [N]

Twenty noisy puffs of radius N/40..N/16 voxels scattered through an N^3 box (default N = 512,
voxel size 2/N, so the box spans 2 units), the rest empty: a grid whose pyramid has large empty
and thin regions between dense ones, unlike the compact shipped cloud. Do not commit the result.
"""
import sys

import numpy as np
import pyopenvdb as vdb


def main():
    out = sys.argv[1]
    n = int(sys.argv[2]) if len(sys.argv) > 2 else 512
    rng = np.random.default_rng(7)
    g = vdb.FloatGrid(0.0)
    for _ in range(20):
        r = int(rng.uniform(n / 40, n / 16))
        c = rng.integers(r + 2, n - r - 2, size=3)
        ax = np.arange(-r - 1, r + 2, dtype=np.float32) / r
        x, y, z = np.meshgrid(ax, ax, ax, indexing="ij")
        d = np.zeros_like(x)
        for octave in range(3):
            f = 2.0 ** octave * 2.5
            k = rng.normal(size=3) * f
            ph = rng.uniform(0, 2 * np.pi)
            d += np.sin(k[0] * x + k[1] * y + k[2] * z + ph).astype(np.float32) / (2.0 ** octave)
        rad = np.sqrt(x * x + y * y + z * z)
        d = (0.6 + 0.35 * d) * np.clip((1.0 - rad) * 4.0, 0.0, 1.0)
        d = np.clip(d, 0.0, 1.0).astype(np.float32)
        puff = vdb.FloatGrid(0.0)
        origin = tuple(int(v) for v in (c - r - 1 - n // 2))
        puff.copyFromArray(d, ijk=origin, tolerance=0.0)
        g.combine(puff, lambda a, b: max(a, b))
    g.name = "density"
    g.gridClass = vdb.GridClass.FOG_VOLUME
    g.transform = vdb.createLinearTransform(voxelSize=2.0 / n)
    vdb.write(out, grids=[g])
    print(out, g.activeVoxelCount(), g.leafCount())


if __name__ == "__main__":
    main()
