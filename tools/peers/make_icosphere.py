#!/usr/bin/env python3
"""Write a unit icosphere as a binary PLY (positions and triangles only, wound outward).

    python3 tools/peers/make_icosphere.py OUT.ply [--subdivisions 5]

Standard library only. An icosahedron (20 triangles) is subdivided `--subdivisions` times, each
triangle into four with its edge midpoints pushed onto the unit sphere: 20 * 4^n triangles
(n = 5: 20480 triangles, 10242 vertices). The file has no normals, so every renderer shades the
facets with their geometric normals (velour: no `nx ny nz`; Mitsuba: `face_normals = true`;
Cycles: flat shading) and all three see the same polyhedron.
"""

import argparse
import math
import struct


def icosphere(subdivisions):
    t = (1.0 + math.sqrt(5.0)) / 2.0
    verts = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
             (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    verts = [tuple(c / math.sqrt(sum(x * x for x in v)) for c in v) for v in verts]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6),
             (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10),
             (8, 6, 7), (9, 8, 1)]
    for _ in range(subdivisions):
        cache = {}

        def midpoint(a, b):
            key = (min(a, b), max(a, b))
            if key not in cache:
                m = [(verts[a][k] + verts[b][k]) / 2.0 for k in range(3)]
                n = math.sqrt(sum(x * x for x in m))
                verts.append(tuple(x / n for x in m))
                cache[key] = len(verts) - 1
            return cache[key]

        new = []
        for a, b, c in faces:
            ab, bc, ca = midpoint(a, b), midpoint(b, c), midpoint(c, a)
            new += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = new
    # Outward winding: (b - a) x (c - a) points away from the centre.
    for i, (a, b, c) in enumerate(faces):
        pa, pb, pc = verts[a], verts[b], verts[c]
        u = [pb[k] - pa[k] for k in range(3)]
        v = [pc[k] - pa[k] for k in range(3)]
        n = (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])
        if sum(n[k] * (pa[k] + pb[k] + pc[k]) for k in range(3)) < 0:
            faces[i] = (a, c, b)
    return verts, faces


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out")
    ap.add_argument("--subdivisions", type=int, default=5)
    args = ap.parse_args()
    verts, faces = icosphere(args.subdivisions)
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment velour peer benchmark: unit icosphere, "
        f"{args.subdivisions} subdivisions\nelement vertex {len(verts)}\nproperty float x\nproperty float y\n"
        f"property float z\nelement face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    with open(args.out, "wb") as f:
        f.write(header.encode("ascii"))
        for v in verts:
            f.write(struct.pack("<3f", *v))
        for a, b, c in faces:
            f.write(struct.pack("<B3i", 3, a, b, c))
    print(f"{args.out}: {len(verts)} vertices, {len(faces)} triangles")


if __name__ == "__main__":
    main()
