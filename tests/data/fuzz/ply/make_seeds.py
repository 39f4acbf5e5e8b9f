#!/usr/bin/env python3
"""Writes the small PLY seed files of the PLY fuzz test (tests/fuzz_ply.rs) next to this script.

Each seed is a valid mesh exercising a different part of the reader: ASCII and binary of both
byte orders, every scalar type, polygons, alternative property names, extra elements, CRLF line
ends, zero-size elements and elements in an unusual order. Run it again only to change the seeds.
"""
import os
import struct

HERE = os.path.dirname(os.path.abspath(__file__))


def write(name, data):
    with open(os.path.join(HERE, name), "wb") as f:
        f.write(data)


def header(fmt, lines):
    return ("ply\nformat %s 1.0\n" % fmt + "".join(l + "\n" for l in lines) + "end_header\n").encode()


# ASCII: normals, u/v, a quad and a triangle, comments, an extra element with a list.
write("ascii_quad.ply", header("ascii", [
    "comment a unit quad and a triangle above it",
    "obj_info seed 1",
    "element vertex 5",
    "property float x", "property float y", "property float z",
    "property float nx", "property float ny", "property float nz",
    "property float u", "property float v",
    "element face 2",
    "property list uchar int vertex_indices",
    "element material 1",
    "property uchar red", "property list uchar float weights",
]) + b"""0 0 0 0 0 1 0 0
1 0 0 0 0 1 1 0
1 1 0 0 0 1 1 1
0 1 0 0 0 1 0 1
0.5 1.5 -0.25 0 0.6 0.8 0.5 1.5
4 0 1 2 3
3 3 2 4
255 2 0.25 0.75
""")

# ASCII with CRLF line ends, `vertex_index` and texture_u/texture_v.
write("ascii_crlf.ply", header("ascii", [
    "element vertex 3",
    "property double x", "property double y", "property double z",
    "property float texture_u", "property float texture_v",
    "element face 1",
    "property list uint8 uint32 vertex_index",
]).replace(b"\n", b"\r\n") + b"0 0 0 0 0\r\n1e-3 0 2.5 1 0\r\n0 -1.25e2 0 0 1\r\n3 0 1 2\r\n")

# ASCII with integer coordinates and the face element before the vertex element.
write("ascii_faces_first.ply", header("ascii", [
    "element face 2",
    "property list uchar uint vertex_indices",
    "element vertex 4",
    "property int x", "property short y", "property uchar z",
]) + b"3 0 1 2\n3 0 2 3\n-5 0 0\n5 -7 0\n5 7 255\n-5 7 1\n")

# Binary little endian: an octahedron as `velour` writes it (float x y z nx ny nz u v).
octa = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]
tris = [(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5), (0, 3, 5)]
body = b""
for p in octa:
    body += struct.pack("<8f", *p, *p, p[0] * 0.5 + 0.5, p[1] * 0.25 + 0.125)
for t in tris:
    body += struct.pack("<B3I", 3, *t)
write("binary_le_octahedron.ply", header("binary_little_endian", [
    "comment written like velour's write_ply",
    "element vertex 6",
    "property float x", "property float y", "property float z",
    "property float nx", "property float ny", "property float nz",
    "property float u", "property float v",
    "element face 8",
    "property list uchar uint vertex_indices",
]) + body)

# Binary big endian: double positions, s/t, int `vertex_index`, a pentagon and a quad, and an
# extra element with scalars and a float list after the faces.
pts = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0.5, 1.5, 0)]
body = b""
for i, p in enumerate(pts):
    body += struct.pack(">3d2f", *p, float(i), 0.5)
body += struct.pack(">B5i", 5, 0, 1, 2, 4, 3)
body += struct.pack(">B4i", 4, 0, 1, 2, 3)
body += struct.pack(">2iB2f", 0, 1, 2, 0.5, -0.5)
write("binary_be_polygons.ply", header("binary_big_endian", [
    "element vertex 5",
    "property float64 x", "property float64 y", "property float64 z",
    "property float32 s", "property float32 t",
    "element face 2",
    "property list uint8 int32 vertex_index",
    "element edge 1",
    "property int vertex1", "property int vertex2",
    "property list uchar float weights",
]) + body)

# Binary little endian with small integer types, double normals, a ushort list length, an
# empty (zero-byte) element and a trailing element of shorts.
body = b""
for p in [(0, 0, 0), (100, 0, 0), (0, 100, 0), (0, 0, 100)]:
    body += struct.pack("<bhH3d", p[0] - 50 if p[0] else 0, p[1], p[2], 0.0, 0.0, 1.0)
for t in [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]:
    body += struct.pack("<H3B", 3, *t)
body += struct.pack("<2h", -3, 4)
write("binary_le_small_types.ply", header("binary_little_endian", [
    "element vertex 4",
    "property char x", "property short y", "property ushort z",
    "property double nx", "property double ny", "property double nz",
    "element nothing 3",
    "element face 4",
    "property list ushort uchar vertex_indices",
    "element tail 1",
    "property int16 a", "property int16 b",
]) + body)
