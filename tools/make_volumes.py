#!/usr/bin/env python3
"""Make the small OpenVDB assets in volumes/ with the real OpenVDB library.

Run with Debian's interpreter, which has the `pyopenvdb` module (package python3-openvdb):

    /usr/bin/python3 tools/make_volumes.py [--out volumes]

Writes
  cloud.vdb  a free-standing cumulus-like cloud: a union of soft spheres eroded by value noise,
             64 x 44 x 44 voxels of 0.03 units (about 1.9 x 1.3 x 1.3 units), grid `density`
  foam.vdb   a thin sheet of foam: 96 x 10 x 96 voxels of 0.033 units just under a water
             surface (y in [-0.3, 0]), grid `density`, densest at depth. It was the old ocean
             scene's foam and is kept as a small asset for the fuzz seed
             tests/data/fuzz/scene/ocean_box_combined.toml; scenes/ocean_foam.toml uses
             volumes/ocean_foam.vdb from tools/make_ocean.py

Deterministic (fixed seeds). Values are densities in [0, 1]; the scenes scale them with
`attenuation` and `density`.
"""

import argparse
import math
import os

import numpy as np
import pyopenvdb as vdb


def value_noise(shape, cell, rng):
    """Smooth value noise by trilinear upsampling of a random lattice (cell = lattice step in voxels)."""
    lattice = rng.random(tuple(s // cell + 2 for s in shape))
    idx = [np.arange(s) / cell for s in shape]
    out = np.zeros(shape, dtype=np.float64)
    gx, gy, gz = np.meshgrid(*idx, indexing="ij")
    i0 = [np.floor(g).astype(int) for g in (gx, gy, gz)]
    f = [g - np.floor(g) for g in (gx, gy, gz)]
    f = [t * t * (3 - 2 * t) for t in f]
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                w = (f[0] if dx else 1 - f[0]) * (f[1] if dy else 1 - f[1]) * (f[2] if dz else 1 - f[2])
                out += w * lattice[i0[0] + dx, i0[1] + dy, i0[2] + dz]
    return out


def fbm(shape, rng, octaves=4, base=16):
    total = np.zeros(shape)
    amp, norm = 1.0, 0.0
    cell = base
    for _ in range(octaves):
        total += amp * value_noise(shape, max(cell, 1), rng)
        norm += amp
        amp *= 0.5
        cell //= 2
    return total / norm


def save(path, array, voxel, origin, name="density"):
    grid = vdb.FloatGrid()
    grid.copyFromArray(array.astype(np.float32), tolerance=1e-4)
    grid.name = name
    grid.gridClass = vdb.GridClass.FOG_VOLUME
    grid.transform = vdb.createLinearTransform(voxelSize=voxel)
    grid.transform.translate(origin)
    vdb.write(path, grids=[grid])


def cloud(rng):
    nx, ny, nz = 64, 44, 44
    x, y, z = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")
    k = 2.0 / 3.0
    blobs = [(30 * k, 26 * k, 32 * k, 18 * k), (52 * k, 30 * k, 30 * k, 21 * k), (70 * k, 24 * k, 34 * k, 15 * k),
             (44 * k, 40 * k, 34 * k, 13 * k), (58 * k, 20 * k, 22 * k, 12 * k)]
    field = np.zeros((nx, ny, nz))
    for cx, cy, cz, r in blobs:
        d = np.sqrt((x - cx) ** 2 + (y - cy) ** 2 + (z - cz) ** 2) / r
        field = np.maximum(field, 1.0 - d)
    noise = fbm((nx, ny, nz), rng, base=12)
    d = np.clip((field - 0.3 * noise) * 4.0, 0.0, 1.0)
    # Flatten the base like a cumulus.
    d[:, :7, :] *= np.linspace(0, 1, 7)[None, :, None]
    return d


def foam(rng):
    nx, ny, nz = 96, 10, 96
    noise = fbm((nx, ny, nz), rng, octaves=3, base=8)
    depth = np.linspace(1.0, 0.0, ny)[None, :, None]
    d = np.clip((noise - 0.55) * 6.0, 0.0, 1.0) * depth
    return d


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "..", "volumes"))
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    rng = np.random.default_rng(20261122)
    save(os.path.join(a.out, "cloud.vdb"), cloud(rng), 0.03, (-0.96, 0.0, -0.66))
    save(os.path.join(a.out, "foam.vdb"), foam(rng), 0.033, (-1.6, -0.3, -1.6))
    for f in ("cloud.vdb", "foam.vdb"):
        p = os.path.join(a.out, f)
        print(f, os.path.getsize(p), "bytes")


if __name__ == "__main__":
    main()
