#!/usr/bin/env python3
"""Procedurally drape a square cloth over a sphere and write it as a binary PLY with UVs.

Writes scenes/meshes/drape.ply (relative to the repository root, or --out FILE): the cloth's
mid-surface, an open N x N grid of vertices with area-weighted normals (facing away from the
sphere) and texture coordinates u, v in [0, 1] along the cloth's two sides. velour tiles a
voxelised weave patch over it as a fabric shell (scenes/draped_cloth.toml).

The drape is a small position-based-dynamics simulation (Mueller et al. 2007): Verlet
integration under gravity, distance constraints along the grid (structural), across each
cell (shear) and two vertices apart (bending, softer), collisions with the sphere and the
floor with friction. Units: centimetres (the yarn presets' unit). Deterministic (no random
numbers). Plain Python 3, no packages; about a minute.

Usage: python3 tools/make_cloth.py [--out FILE] [--n N] [--size CM] [--steps S]
"""

import argparse
import math
import os
import struct

SPHERE_C = (0.0, 5.0, 0.0)  # sphere centre (cm); it rests on the floor y = 0
SPHERE_R = 5.0
START_Y = 10.6  # the cloth starts flat just above the sphere
GRAVITY = -981.0  # cm / s^2
DT = 1.0 / 200.0
DAMPING = 0.985
ITERATIONS = 6
MARGIN = 0.08  # collision margin (cm): about half the shell thickness of the scene
FRICTION = 0.6


def simulate(n, size, steps):
    d = size / (n - 1)
    pos = []
    for j in range(n):
        for i in range(n):
            # A small deterministic tilt breaks the symmetry so the folds are not all alike.
            x = -size / 2 + i * d
            z = -size / 2 + j * d
            y = START_Y + 0.02 * x - 0.015 * z
            pos.append([x, y, z])
    prev = [p[:] for p in pos]
    cons = []

    def idx(i, j):
        return j * n + i

    for j in range(n):
        for i in range(n):
            if i + 1 < n:
                cons.append((idx(i, j), idx(i + 1, j), d, 1.0))
            if j + 1 < n:
                cons.append((idx(i, j), idx(i, j + 1), d, 1.0))
            if i + 1 < n and j + 1 < n:
                cons.append((idx(i, j), idx(i + 1, j + 1), d * math.sqrt(2), 0.7))
                cons.append((idx(i + 1, j), idx(i, j + 1), d * math.sqrt(2), 0.7))
            if i + 2 < n:
                cons.append((idx(i, j), idx(i + 2, j), 2 * d, 0.15))
            if j + 2 < n:
                cons.append((idx(i, j), idx(i, j + 2), 2 * d, 0.15))
    g = GRAVITY * DT * DT
    cx, cy, cz = SPHERE_C
    r_col = SPHERE_R + MARGIN
    for _ in range(steps):
        for k in range(len(pos)):
            p = pos[k]
            q = prev[k]
            vx = (p[0] - q[0]) * DAMPING
            vy = (p[1] - q[1]) * DAMPING
            vz = (p[2] - q[2]) * DAMPING
            prev[k] = p[:]
            p[0] += vx
            p[1] += vy + g
            p[2] += vz
        for _ in range(ITERATIONS):
            for a, b, rest, stiff in cons:
                pa = pos[a]
                pb = pos[b]
                dx = pb[0] - pa[0]
                dy = pb[1] - pa[1]
                dz = pb[2] - pa[2]
                l2 = dx * dx + dy * dy + dz * dz
                if l2 < 1e-18:
                    continue
                ln = math.sqrt(l2)
                c = 0.5 * stiff * (ln - rest) / ln
                pa[0] += dx * c
                pa[1] += dy * c
                pa[2] += dz * c
                pb[0] -= dx * c
                pb[1] -= dy * c
                pb[2] -= dz * c
            for k in range(len(pos)):
                p = pos[k]
                q = prev[k]
                ox = p[0] - cx
                oy = p[1] - cy
                oz = p[2] - cz
                l2 = ox * ox + oy * oy + oz * oz
                if l2 < r_col * r_col:
                    ln = math.sqrt(l2)
                    s = r_col / ln
                    p[0] = cx + ox * s
                    p[1] = cy + oy * s
                    p[2] = cz + oz * s
                    # Friction: pull the previous position along, removing tangential motion.
                    q[0] += (p[0] - q[0]) * FRICTION
                    q[1] += (p[1] - q[1]) * FRICTION
                    q[2] += (p[2] - q[2]) * FRICTION
                if p[1] < MARGIN:
                    p[1] = MARGIN
                    q[0] += (p[0] - q[0]) * FRICTION
                    q[2] += (p[2] - q[2]) * FRICTION
                    q[1] = p[1]
    return pos


def triangles(n):
    tris = []
    for j in range(n - 1):
        for i in range(n - 1):
            a = j * n + i
            b = a + 1
            c = a + n
            e = c + 1
            # Wound so that the geometric normal points up (+y) on the flat cloth.
            tris.append((a, c, b))
            tris.append((b, c, e))
    return tris


def normals(pos, tris):
    nrm = [[0.0, 0.0, 0.0] for _ in pos]
    for a, b, c in tris:
        pa, pb, pc = pos[a], pos[b], pos[c]
        u = [pb[k] - pa[k] for k in range(3)]
        v = [pc[k] - pa[k] for k in range(3)]
        f = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
        for i in (a, b, c):
            for k in range(3):
                nrm[i][k] += f[k]
    out = []
    for v in nrm:
        ln = math.sqrt(sum(x * x for x in v)) or 1.0
        out.append([x / ln for x in v])
    return out


def write_ply(path, pos, nrm, n, tris):
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        "comment velour tools/make_cloth.py: a square cloth draped over a sphere (cm)\n"
        f"element vertex {len(pos)}\n"
        "property float x\nproperty float y\nproperty float z\n"
        "property float nx\nproperty float ny\nproperty float nz\n"
        "property float u\nproperty float v\n"
        f"element face {len(tris)}\n"
        "property list uchar int vertex_indices\nend_header\n"
    )
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        for k, (p, q) in enumerate(zip(pos, nrm)):
            i, j = k % n, k // n
            f.write(struct.pack("<8f", *p, *q, i / (n - 1), j / (n - 1)))
        for t in tris:
            f.write(struct.pack("<B3i", 3, *t))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    ap.add_argument("--out", default=os.path.join(root, "scenes", "meshes", "drape.ply"))
    ap.add_argument("--n", type=int, default=41, help="vertices per side")
    ap.add_argument("--size", type=float, default=18.0, help="side of the cloth, cm")
    ap.add_argument("--steps", type=int, default=360, help="simulation steps of 5 ms")
    a = ap.parse_args()
    pos = simulate(a.n, a.size, a.steps)
    tris = triangles(a.n)
    nrm = normals(pos, tris)
    write_ply(a.out, pos, nrm, a.n, tris)
    ys = [p[1] for p in pos]
    print(f"wrote {a.out}: {len(pos)} vertices, {len(tris)} triangles, y in [{min(ys):.2f}, {max(ys):.2f}] cm")


if __name__ == "__main__":
    main()
