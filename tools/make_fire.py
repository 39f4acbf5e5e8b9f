#!/usr/bin/env python3
"""Make the fire plume of scenes/fire.toml with the real OpenVDB library.

Run with Debian's interpreter, which has `pyopenvdb` (package python3-openvdb) and numpy:

    /usr/bin/python3 tools/make_fire.py [--out volumes]

Writes `fire.vdb`: a procedural fire with smoke above it, 48 x 96 x 48 voxels of 0.02 units
(0.96 x 1.92 x 0.96 units; x and z centred on 0, the base at y = 0), two fog-volume grids with the
same transform:

  density      in [0, 1]: thin in the flames near the base, thicker in the smoke that rises and
               widens above them (the scene scales it with `attenuation`)
  temperature  in units of 1000 K (the scene sets `temperature_scale = 1000`): up to about 2.2
               (2200 K) in the core just above the base, falling with height and towards the
               plume's edge in flame tongues shaped by stretched value noise; 0 (inactive) below
               900 K, which emits next to nothing visible, and in the smoke

Values are stored as 16-bit halves and zero voxels are left inactive. Deterministic (fixed seed):
reruns write the same grids; only the random file UUID OpenVDB writes in the header differs.
"""

import argparse
import os

import numpy as np
import pyopenvdb as vdb

NX, NY, NZ = 48, 96, 48
VOXEL = 0.02
SEED = 14


def value_noise(shape, cells, rng):
    """Smooth value noise: a random lattice with step `cells[a]` voxels along axis a, smoothstep-
    interpolated (the lattice is anisotropic, so flames can be stretched along y)."""
    lattice = rng.random(tuple(int(s // c) + 2 for s, c in zip(shape, cells)))
    grids = np.meshgrid(*[np.arange(s) / c for s, c in zip(shape, cells)], indexing="ij")
    i0 = [np.floor(g).astype(int) for g in grids]
    f = [g - np.floor(g) for g in grids]
    f = [t * t * (3.0 - 2.0 * t) for t in f]
    out = np.zeros(shape)
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                w = (f[0] if dx else 1 - f[0]) * (f[1] if dy else 1 - f[1]) * (f[2] if dz else 1 - f[2])
                out += w * lattice[i0[0] + dx, i0[1] + dy, i0[2] + dz]
    return out


def fbm(shape, rng, cells, octaves):
    """Fractal sum of value noise in [0, 1], each octave at half the lattice step."""
    total, norm, amp = np.zeros(shape), 0.0, 1.0
    for o in range(octaves):
        total += amp * value_noise(shape, [max(c / 2**o, 1.0) for c in cells], rng)
        norm += amp
        amp *= 0.5
    return total / norm


def smoothstep(a, b, x):
    t = np.clip((x - a) / (b - a), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def plume(rng):
    """The density and temperature fields (float64 arrays of shape NX x NY x NZ)."""
    shape = (NX, NY, NZ)
    i, j, k = np.meshgrid(np.arange(NX), np.arange(NY), np.arange(NZ), indexing="ij")
    h = (j + 0.5) / NY  # height in [0, 1]
    # Billowing smoke (round noise) and flame tongues (noise stretched upwards).
    billow = fbm(shape, rng, [12.0, 12.0, 12.0], 4)
    tongues = fbm(shape, rng, [6.0, 20.0, 6.0], 3)
    # The axis sways a little with height; the plume widens as it rises.
    cx = 0.5 * NX + 2.5 * np.sin(6.0 * h) + 4.0 * (billow - 0.5) * h
    cz = 0.5 * NZ + 2.0 * np.cos(5.0 * h + 1.0)
    radius = NX * (0.2 + 0.17 * h**0.8)
    q = np.sqrt((i + 0.5 - cx) ** 2 + (k + 0.5 - cz) ** 2) / radius  # 0 on the axis, 1 at the edge
    # Plume membership: soft edge, eroded by the billow noise (more so higher up).
    body = np.clip(1.4 * (1.0 - q) + (0.6 + 0.6 * h) * (billow - 0.5), 0.0, 1.0)
    # Smoke thickens above the flames and thins out towards the top of the box.
    smoke = smoothstep(0.25, 0.6, h) * (1.0 - 0.4 * smoothstep(0.7, 1.0, h))
    density = body * (0.3 + 0.7 * smoke) * (0.5 + billow)
    # Fade in over the first voxels (the fire's source), and to 0 at the box's top and sides.
    density *= smoothstep(0.0, 0.03, h) * (1.0 - smoothstep(0.85, 1.0, h))
    density = np.clip(density, 0.0, 1.0)
    # Flames: hot near the base and the axis, the flame height varying with the tongues.
    flame_top = 0.5 + 0.6 * (tongues - 0.5)
    heat = np.clip(1.0 - h / np.maximum(flame_top, 0.05), 0.0, 1.0)
    core = np.clip(1.0 - q**2 * (1.1 - 0.6 * tongues), 0.0, 1.0)
    # Blackbody brightness rises steeply with temperature (the luminance Y is about 16 times
    # higher at 2260 K than at 1800 K), so the profile is flat: a broad region at 1500-2000 K,
    # the core hotter.
    temperature = 2.2 * (heat * core) ** 0.35
    density[density < 1e-3] = 0.0
    temperature[(temperature < 0.9) | (density == 0.0)] = 0.0
    return density, temperature


def grid(array, name):
    g = vdb.FloatGrid()
    g.copyFromArray(array.astype(np.float32), tolerance=0.0)
    g.name = name
    g.gridClass = vdb.GridClass.FOG_VOLUME
    # Voxel (i, j, k) has its centre at ((i + 1/2) v - NX v / 2, (j + 1/2) v, (k + 1/2) v - NZ v / 2);
    # OpenVDB puts values at integer index points, so the translation includes half a voxel.
    g.transform = vdb.createLinearTransform(voxelSize=VOXEL)
    g.transform.translate(((0.5 - NX / 2) * VOXEL, 0.5 * VOXEL, (0.5 - NZ / 2) * VOXEL))
    g["is_saved_as_half_float"] = True
    g.pruneInactive()
    return g


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "..", "volumes"))
    a = ap.parse_args()
    density, temperature = plume(np.random.default_rng(SEED))
    grids = [grid(density, "density"), grid(temperature, "temperature")]
    path = os.path.join(a.out, "fire.vdb")
    vdb.write(path, grids=grids)
    print(
        f"{path}: {os.path.getsize(path)} bytes; density: {grids[0].activeVoxelCount()} active voxels, "
        f"max {density.max():.3f}; temperature: {grids[1].activeVoxelCount()} active voxels, "
        f"max {1000 * temperature.max():.0f} K"
    )


if __name__ == "__main__":
    main()
