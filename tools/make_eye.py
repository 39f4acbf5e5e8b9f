#!/usr/bin/env python3
"""Generate the meshes of scenes/eye.toml as small binary PLYs (plain Python 3, no packages).

Writes into scenes/meshes/ (relative to the repository root, or --out DIR):

  eye_globe.ply  the outer surface of an eye, about 2 units across (1 unit ~ 12 mm): the
                 globe (a unit sphere at the origin) smoothly united with the cornea (a sphere
                 of radius CORNEA_R centred at (0, 0, CORNEA_Z), bulging out to z = 1.22
                 along +z). A radial graph r(theta) about the z axis, so it is closed and
                 embedded by construction; per-vertex normals are the exact normals of the
                 smooth surface (the manifold walk follows them, so they must be smooth).
  eye_iris.ply   the iris: a closed washer (annulus from PUPIL_R to IRIS_R, between
                 z = IRIS_Z0 and a front face at IRIS_Z1 with radial ridges), inside the
                 anterior chamber (the sphere of radius CHAMBER_R at the cornea's centre,
                 which scenes/eye.toml uses as an analytic sphere). No normals: its boundary
                 is index-matched.

The script checks that the iris lies inside the chamber and the chamber inside the globe.
Usage: python3 tools/make_eye.py [--out DIR]
"""

import math
import os
import struct
import sys

CORNEA_R = 0.65  # corneal curvature radius (7.8 mm)
CORNEA_Z = 0.57  # centre of the corneal sphere on the optical (z) axis
SMOOTH = 0.06  # width of the smooth union at the limbus
CHAMBER_R = 0.64  # the anterior chamber (clear aqueous) sphere, same centre as the cornea
PUPIL_R = 0.19
IRIS_R = 0.54
IRIS_Z0 = 0.70
IRIS_Z1 = 0.745
RIDGES = 36  # radial ridges (crypts) on the front of the iris
RIDGE_H = 0.008


def cornea_radius(theta):
    """Distance from the origin along direction theta (from +z) to the corneal sphere."""
    s = math.sin(theta)
    disc = CORNEA_R * CORNEA_R - (CORNEA_Z * s) ** 2
    if disc < 0:
        return None
    return CORNEA_Z * math.cos(theta) + math.sqrt(disc)


def globe_radius(theta):
    """Smooth maximum of the unit sphere and the cornea (adds at most SMOOTH/2)."""
    c = cornea_radius(theta)
    if c is None:
        return 1.0
    a, b = 1.0, c
    return 0.5 * (a + b + math.sqrt((a - b) ** 2 + SMOOTH * SMOOTH))


def sph(r, theta, phi):
    s = math.sin(theta)
    return (r * s * math.cos(phi), r * s * math.sin(phi), r * math.cos(theta))


def normalize(v):
    l = math.sqrt(sum(x * x for x in v))
    return tuple(x / l for x in v)


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def globe(n_theta=112, n_phi=160):
    """UV sphere with poles on the z axis, displaced radially by globe_radius."""
    verts, normals, faces = [], [], []
    verts.append((0.0, 0.0, globe_radius(0.0)))
    normals.append((0.0, 0.0, 1.0))
    h = 1e-5
    for i in range(1, n_theta):
        # Rows denser over the cornea (theta < 0.9), where the light refracts.
        t = i / n_theta
        theta = math.pi * (0.55 * t + 0.45 * t * t)
        r = globe_radius(theta)
        dr = (globe_radius(theta + h) - globe_radius(theta - h)) / (2 * h)
        for j in range(n_phi):
            phi = 2 * math.pi * j / n_phi
            verts.append(sph(r, theta, phi))
            # dp/dtheta and dp/dphi of p = r(theta) * dir(theta, phi).
            st, ct, sp, cp = math.sin(theta), math.cos(theta), math.sin(phi), math.cos(phi)
            d_theta = (dr * st * cp + r * ct * cp, dr * st * sp + r * ct * sp, dr * ct - r * st)
            d_phi = (-sp, cp, 0.0)  # divided by r sin(theta) > 0
            normals.append(normalize(cross(d_theta, d_phi)))
    verts.append((0.0, 0.0, -1.0))
    normals.append((0.0, 0.0, -1.0))
    last = len(verts) - 1
    ring = lambda i, j: 1 + (i - 1) * n_phi + (j % n_phi)
    for j in range(n_phi):
        faces.append((0, ring(1, j), ring(1, j + 1)))
    for i in range(1, n_theta - 1):
        for j in range(n_phi):
            a, b = ring(i, j), ring(i, j + 1)
            c, d = ring(i + 1, j + 1), ring(i + 1, j)
            faces += [(a, d, c), (a, c, b)]
    for j in range(n_phi):
        faces.append((last, ring(n_theta - 1, j + 1), ring(n_theta - 1, j)))
    return verts, normals, faces


def iris(n_phi=192, n_r=24):
    """A closed washer swept about z: profile inner wall, back, outer wall, ridged front."""
    prof = []  # (r, z(phi) function) around the rectangle, counter-clockwise in (r, z)
    for k in range(n_r):
        prof.append((PUPIL_R + (IRIS_R - PUPIL_R) * k / n_r, None, IRIS_Z0))
    for k in range(4):
        prof.append((IRIS_R, None, IRIS_Z0 + (IRIS_Z1 - IRIS_Z0) * k / 4))
    for k in range(n_r):
        prof.append((IRIS_R - (IRIS_R - PUPIL_R) * k / n_r, "front", IRIS_Z1))
    for k in range(4):
        prof.append((PUPIL_R, None, IRIS_Z1 - (IRIS_Z1 - IRIS_Z0) * k / 4))
    verts, faces = [], []
    for j in range(n_phi):
        phi = 2 * math.pi * j / n_phi
        for r, kind, z in prof:
            if kind == "front":
                # Ridges fading towards both rims.
                w = math.sin(math.pi * (r - PUPIL_R) / (IRIS_R - PUPIL_R))
                z = z + RIDGE_H * w * (0.5 + 0.5 * math.cos(RIDGES * phi + 9.0 * r))
            verts.append((r * math.cos(phi), r * math.sin(phi), z))
    m = len(prof)
    for j in range(n_phi):
        for k in range(m):
            a = j * m + k
            b = j * m + (k + 1) % m
            c = ((j + 1) % n_phi) * m + (k + 1) % m
            d = ((j + 1) % n_phi) * m + k
            faces += [(a, b, c), (a, c, d)]
    return verts, faces


def write_ply(path, verts, faces, normals=None):
    props = "property float x\nproperty float y\nproperty float z\n"
    if normals:
        props += "property float nx\nproperty float ny\nproperty float nz\n"
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment generated by tools/make_eye.py\n"
        f"element vertex {len(verts)}\n{props}"
        f"element face {len(faces)}\nproperty list uchar uint vertex_indices\nend_header\n")
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        vb = bytearray()
        for i, p in enumerate(verts):
            vb += struct.pack("<3f", *p)
            if normals:
                vb += struct.pack("<3f", *normals[i])
        f.write(vb)
        fb = bytearray()
        for a, b, c in faces:
            fb += struct.pack("<BIII", 3, a, b, c)
        f.write(fb)
    return os.path.getsize(path)


def check(globe_verts, iris_verts):
    cz = (0.0, 0.0, CORNEA_Z)
    for p in iris_verts:
        d = math.dist(p, cz)
        assert d < CHAMBER_R - 0.02, f"iris vertex {p} outside the chamber ({d})"
    # The chamber sphere inside the globe: along every direction from the origin the chamber
    # ends before the globe surface (both are radial graphs about the origin there).
    for i in range(1, 2000):
        theta = math.pi * i / 2000
        s = math.sin(theta)
        disc = CHAMBER_R ** 2 - (CORNEA_Z * s) ** 2
        if disc < 0:
            continue
        r_ch = CORNEA_Z * math.cos(theta) + math.sqrt(disc)
        assert r_ch < globe_radius(theta) - 0.005, f"chamber leaves the globe at theta {theta}"


def main():
    out = "scenes/meshes"
    if "--out" in sys.argv:
        out = sys.argv[sys.argv.index("--out") + 1]
    else:
        os.chdir(os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
    os.makedirs(out, exist_ok=True)
    gv, gn, gf = globe()
    iv, iface = iris()
    check(gv, iv)
    n1 = write_ply(os.path.join(out, "eye_globe.ply"), gv, gf, gn)
    n2 = write_ply(os.path.join(out, "eye_iris.ply"), iv, iface)
    print(f"eye_globe.ply: {len(gv)} vertices, {len(gf)} triangles, {n1} bytes")
    print(f"eye_iris.ply: {len(iv)} vertices, {len(iface)} triangles, {n2} bytes")


if __name__ == "__main__":
    main()
