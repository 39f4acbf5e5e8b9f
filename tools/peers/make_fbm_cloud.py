#!/usr/bin/env python3
"""Write the peer benchmarks' fBm cloud: a deterministic density grid as a real OpenVDB file.

    /usr/bin/python3 tools/peers/make_fbm_cloud.py OUT.vdb [--res 128]

Needs numpy and OpenVDB's Python bindings (Debian: python3-openvdb, module `pyopenvdb`).

The cloud fills the world box [-0.5, 0.5]^3 (one length unit across): `--res` voxels per axis,
voxel size h = 1 / res, voxel (i, j, k) at world point -0.5 + (index + 1/2) h (OpenVDB samples
sit at integer index points; velour, Mitsuba through `vdb_to_vol.py` and Cycles all interpolate
trilinearly between them). Grid `density`, float, background 0, values in [0, 1] with maximum
exactly 1, zero within 6 % of the box's half width of every face (so finer resamplings on an
aligned lattice, `resample_grid.py`, reproduce the same world-space field exactly).

The density is fractal value noise (five octaves, lacunarity 2, gain 0.5) shaped by a radial
falloff:

    d(p) = clamp(4 (n(p) - 1/2) + 1.4 (1 - r) - 0.3, 0, 1) * s(r),   r = |p| / 0.5,
    s(r) = smoothstep of (0.92 - r) / 0.25,

where n is the noise in [0, 1] at 3.2 p + (17.3, 5.1, 9.7) and the lattice values come from an
integer hash (no random-number library, so every numpy version writes the same bits). The result
is divided by its maximum.
"""

import argparse
import sys

import numpy as np

MASK = np.uint64(0xFFFFFFFF)


def hash_unit(ix, iy, iz, seed):
    """A value in [0, 1) for each integer lattice point (uint32 mixing, computed in uint64)."""
    h = (ix.astype(np.uint64) * np.uint64(0x8DA6B343)) & MASK
    h ^= (iy.astype(np.uint64) * np.uint64(0xD8163841)) & MASK
    h ^= (iz.astype(np.uint64) * np.uint64(0xCB1AB31F)) & MASK
    h ^= np.uint64(seed)
    h ^= h >> np.uint64(16)
    h = (h * np.uint64(0x7FEB352D)) & MASK
    h ^= h >> np.uint64(15)
    h = (h * np.uint64(0x846CA68B)) & MASK
    h ^= h >> np.uint64(16)
    return (h & np.uint64(0xFFFFFF)).astype(np.float64) / float(1 << 24)


def value_noise(p, seed):
    """Value noise in [0, 1) at points p (..., 3): quintic blend of the 8 hashed lattice values."""
    f = np.floor(p)
    t = p - f
    w = t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
    i = f.astype(np.int64) & 0xFFFFFFFF
    out = np.zeros(p.shape[:-1])
    for dz in (0, 1):
        for dy in (0, 1):
            for dx in (0, 1):
                v = hash_unit(i[..., 0] + dx, i[..., 1] + dy, i[..., 2] + dz, seed)
                wx = w[..., 0] if dx else 1.0 - w[..., 0]
                wy = w[..., 1] if dy else 1.0 - w[..., 1]
                wz = w[..., 2] if dz else 1.0 - w[..., 2]
                out += wx * wy * wz * v
    return out


def fbm(p, octaves=5, lacunarity=2.0, gain=0.5, seed=1):
    total = np.zeros(p.shape[:-1])
    amp, norm, freq = 1.0, 0.0, 1.0
    for o in range(octaves):
        total += amp * value_noise(p * freq, seed + 101 * o)
        norm += amp
        amp *= gain
        freq *= lacunarity
    return total / norm


def smoothstep(x):
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def density(res, z0, z1):
    """The unnormalised density of voxel slabs z0 <= k < z1, as an array [x][y][z]."""
    h = 1.0 / res
    c = -0.5 + (np.arange(res) + 0.5) * h
    cz = -0.5 + (np.arange(z0, z1) + 0.5) * h
    p = np.stack(np.meshgrid(c, c, cz, indexing="ij"), axis=-1)
    r = np.sqrt((p * p).sum(axis=-1)) / 0.5
    n = fbm(3.2 * p + np.array([17.3, 5.1, 9.7]))
    d = np.clip(4.0 * (n - 0.5) + 1.4 * (1.0 - r) - 0.3, 0.0, 1.0) * smoothstep((0.92 - r) / 0.25)
    return d


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out")
    ap.add_argument("--res", type=int, default=128)
    args = ap.parse_args()
    import pyopenvdb as vdb

    res = args.res
    slab = 16
    d = np.zeros((res, res, res), dtype=np.float64)
    for z0 in range(0, res, slab):
        d[:, :, z0:min(res, z0 + slab)] = density(res, z0, min(res, z0 + slab))
    m = d.max()
    if not m > 0:
        sys.exit("empty cloud")
    d = (d / m).astype(np.float32)
    edge = int(np.ceil(0.06 * res / 2))
    border = np.ones_like(d, dtype=bool)
    border[edge:-edge, edge:-edge, edge:-edge] = False
    if d[border].max() != 0.0:
        sys.exit("the cloud touches the box border; the resampled grids would not match")
    h = 1.0 / res
    grid = vdb.FloatGrid(0.0)
    grid.name = "density"
    grid.gridClass = vdb.GridClass.FOG_VOLUME
    grid.copyFromArray(d, ijk=(0, 0, 0), tolerance=0.0)
    t = -0.5 + 0.5 * h
    grid.transform = vdb.createLinearTransform([[h, 0, 0, 0], [0, h, 0, 0], [0, 0, h, 0], [t, t, t, 1]])
    vdb.write(args.out, grids=[grid])
    print(f"{args.out}: {res}^3, voxel {h:g}, active {grid.activeVoxelCount()}, mean over the box {float(d.mean()):.4f}")


if __name__ == "__main__":
    main()
