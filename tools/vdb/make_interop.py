#!/usr/bin/python3
"""Writes small VDB files with real OpenVDB (Debian's pyopenvdb) for velour's reader tests.

Usage: /usr/bin/python3 make_interop.py OUTDIR

Base files (pyopenvdb's default blosc + active-mask compression):
  tiles_affine.vdb   float: active root tile, inactive non-background root tile, 128^3 and 8^3
                     tiles, noisy leaves with many distinct inactive values; rotated AffineMap
  levelset.vdb       level-set sphere: inactive -background interior tiles, leaves whose
                     inactive voxels are +/- background (selection masks); UniformScaleMap
  vec3_scale.vdb     vec3s grid with leaves and an active 8^3 tile; ScaleMap
  float_half.vdb     float saved as half, with tiles; ScaleTranslateMap
  vec3_half.vdb      vec3s saved as half; UniformScaleTranslateMap
  multi.vdb          three grids (two float, one vec3s) in one file
Each base file is then rewritten by OpenVDB's vdb_tool with codec=none, zip (+ active mask)
and active (mask only) (suffixes _none, _zip, _active) and, for three files, with bits=16
(half floats, suffix _b16).
Prints the list of files written, one per line.
"""
import math
import os
import random
import subprocess
import sys

import pyopenvdb as vdb


def noisy_leaves(g, rng, origin, n, vec=False):
    acc = g.getAccessor()
    ox, oy, oz = origin
    for i in range(n):
        for j in range(n):
            for k in range(n):
                v = (rng.random(), rng.random() - 0.5, rng.random() * 2) if vec else rng.random() * 2.0
                ijk = (ox + i, oy + j, oz + k)
                if rng.random() < 0.7:
                    acc.setValueOn(ijk, v)
                else:
                    acc.setValueOff(ijk, v)


def main():
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)
    rng = random.Random(7)
    written = []

    g = vdb.FloatGrid(0.0)
    g.name = "density"
    g.gridClass = vdb.GridClass.FOG_VOLUME
    g.fill((8192, 0, 0), (8192 + 4095, 4095, 4095), 0.25, True)
    g.fill((-8192, 0, 0), (-8192 + 4095, 4095, 4095), 3.0, False)
    g.fill((128, 0, 0), (255, 127, 127), 1.5, True)
    g.fill((0, 0, 64), (7, 7, 71), 0.75, True)
    noisy_leaves(g, rng, (-5, -3, 2), 13)
    t = vdb.createLinearTransform(voxelSize=0.1)
    t.rotate(0.4, vdb.Axis.Y)
    t.rotate(0.3, vdb.Axis.Z)
    t.translate((0.5, -1.0, 2.0))
    g.transform = t
    base = {"tiles_affine.vdb": [g]}

    ls = vdb.createLevelSetSphere(radius=1.2, center=(0.05, 0.1, -0.2), voxelSize=0.1, halfWidth=3.0)
    ls.name = "surface"
    base["levelset.vdb"] = [ls]

    v = vdb.Vec3SGrid((0.0, 0.0, 0.0))
    v.name = "velocity"
    noisy_leaves(v, rng, (3, -9, 4), 11, vec=True)
    v.fill((64, 64, 64), (71, 71, 71), (1.0, -2.0, 0.5), True)
    tv = vdb.createLinearTransform(voxelSize=0.5)
    tv.scale((1.0, 2.0, 3.0))
    v.transform = tv
    base["vec3_scale.vdb"] = [v]

    h = vdb.FloatGrid(0.0)
    h.name = "density"
    noisy_leaves(h, rng, (0, 0, 0), 10)
    h.fill((512, 0, 0), (639, 127, 127), 0.3333, True)
    h.fill((0, 256, 0), (7, 263, 7), 1.0 / 3.0, True)
    th = vdb.createLinearTransform(voxelSize=0.2)
    th.scale((1.0, 0.5, 2.0))
    th.translate((3.0, 2.0, 1.0))
    h.transform = th
    h.saveFloatAsHalf = True
    base["float_half.vdb"] = [h]

    vh = vdb.Vec3SGrid((0.0, 0.0, 0.0))
    vh.name = "vel_half"
    noisy_leaves(vh, rng, (-7, -7, -7), 9, vec=True)
    tvh = vdb.createLinearTransform(voxelSize=0.05)
    tvh.translate((1.0, 1.0, 1.0))
    vh.transform = tvh
    vh.saveFloatAsHalf = True
    base["vec3_half.vdb"] = [vh]

    m1 = vdb.FloatGrid(0.0)
    m1.name = "density"
    noisy_leaves(m1, rng, (0, 0, 0), 6)
    m2 = vdb.FloatGrid(1.0)
    m2.name = "temperature"
    noisy_leaves(m2, rng, (20, 0, 0), 6)
    m3 = vdb.Vec3SGrid((0.0, 0.0, 0.0))
    m3.name = "vel"
    noisy_leaves(m3, rng, (0, 20, 0), 6, vec=True)
    base["multi.vdb"] = [m1, m2, m3]

    for name, grids in base.items():
        path = os.path.join(out, name)
        vdb.write(path, grids=grids)
        written.append(path)
        stem = path[:-4]
        # The base file already has OpenVDB's default blosc + active-mask compression.
        variants = [("none", []), ("zip", []), ("active", [])]
        if name in ("tiles_affine.vdb", "levelset.vdb", "vec3_scale.vdb"):
            variants.append(("b16", ["bits=16"]))
        for codec, extra in variants:
            dst = f"{stem}_{codec}.vdb"
            c = "blosc" if codec == "b16" else codec
            subprocess.run(
                ["vdb_tool", "-read", path, "-write", f"codec={c}", *extra, dst],
                check=True,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
            written.append(dst)
    print("\n".join(written))


if __name__ == "__main__":
    main()
