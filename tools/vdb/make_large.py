#!/usr/bin/python3
"""Writes a large fog volume with real OpenVDB for velour's load benchmark.

Usage: /usr/bin/python3 make_large.py OUT.vdb [N]

An N^3 (default 320) block of smooth noise (a sum of random sinusoids, values in [0, 1.5]),
cut to a sphere of radius N/2 with a soft shell, voxel size 1/N, default OpenVDB compression
(blosc + active values). Do not commit the result.
"""
import sys

import numpy as np
import pyopenvdb as vdb


def main():
    out = sys.argv[1]
    n = int(sys.argv[2]) if len(sys.argv) > 2 else 320
    rng = np.random.default_rng(3)
    ax = np.arange(n, dtype=np.float32) / n
    x, y, z = np.meshgrid(ax, ax, ax, indexing="ij")
    d = np.zeros((n, n, n), dtype=np.float32)
    for octave in range(5):
        f = 2.0 ** octave * 3.0
        k = rng.normal(size=3) * f
        ph = rng.uniform(0, 2 * np.pi)
        d += np.sin(k[0] * x + k[1] * y + k[2] * z + ph).astype(np.float32) / (2.0 ** octave)
    d = 0.75 + 0.4 * d
    r = np.sqrt((x - 0.5) ** 2 + (y - 0.5) ** 2 + (z - 0.5) ** 2)
    d *= np.clip((0.5 - r) * 20.0, 0.0, 1.0)
    d = np.clip(d, 0.0, 1.5).astype(np.float32)
    g = vdb.FloatGrid(0.0)
    g.copyFromArray(d, ijk=(-n // 2, -n // 2, -n // 2), tolerance=0.0)
    g.name = "density"
    g.gridClass = vdb.GridClass.FOG_VOLUME
    g.transform = vdb.createLinearTransform(voxelSize=1.0 / n)
    vdb.write(out, grids=[g])
    print(out, g.activeVoxelCount(), g.leafCount())


if __name__ == "__main__":
    main()
