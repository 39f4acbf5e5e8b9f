#!/usr/bin/env python3
"""Procedurally generate the creature-head test meshes as small binary PLYs.

Writes into scenes/meshes/ (relative to the repository root, or --out DIR):

  creature_skin.ply      closed, watertight, outward-wound head skin (~20k triangles,
                         about 1 unit tall, centred on the origin): an elongated skull with
                         snout, brow ridges, eye sockets, cheekbones, horns, a dorsal ridge
                         and a neck stump, as a radial displacement of a subdivided
                         icosahedron (a radial graph is embedded by construction).
  creature_skeleton.ply  closed bones strictly inside the skin: skull (with horn cores and
                         eye sockets), a bent mandible and three vertebra rings. The script
                         checks every bone triangle keeps at least CLEARANCE from the skin
                         and from the other bones (Lipschitz bound on the triangle's
                         circumradius), and that each bone lies inside the skin.
  backdrop.ply           open studio sweep (floor curving into a back wall), normals toward
                         the subject.
  sphere.ply             icosphere of radius 0.5 at the origin (5120 triangles, exact radial
                         normals, spherical UVs like the analytic sphere's): the tessellated
                         twin of `Shape::Sphere { center: 0, radius: 0.5 }` for the
                         sphere-of-skin scene, to compare mesh and analytic renders.

Every file has per-vertex normals (area weighted) and UVs. Plain Python 3, no packages.
Usage: python3 tools/make_creature.py [--out DIR] [--no-check]
"""

import math
import os
import struct
import sys

CLEARANCE = 0.012  # minimum skin-to-bone and bone-to-bone distance (scene units)
MAX_DIHEDRAL = 60.0  # largest allowed angle (degrees) between normals of adjacent faces

# ----------------------------------------------------------------------------- vectors


def add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def mul(a, s):
    return (a[0] * s, a[1] * s, a[2] * s)


def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def length(a):
    return math.sqrt(dot(a, a))


def normalize(a):
    n = length(a)
    return (a[0] / n, a[1] / n, a[2] / n) if n > 0 else (0.0, 0.0, 0.0)


# ----------------------------------------------------------------------------- meshes


def icosphere(subdiv):
    """Unit icosphere: (vertices, faces) with counter-clockwise outward winding."""
    t = (1.0 + math.sqrt(5.0)) / 2.0
    verts = [normalize(v) for v in [
        (-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0),
        (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
        (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11),
             (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6), (7, 1, 8),
             (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9),
             (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    for _ in range(subdiv):
        cache = {}

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in cache:
                cache[key] = len(verts)
                verts.append(normalize(mul(add(verts[a], verts[b]), 0.5)))
            return cache[key]

        new = []
        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            new += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = new
    return verts, faces


def torus(major, minor, nu, nv):
    """Torus around +z through the origin, outward winding."""
    verts, faces = [], []
    for i in range(nu):
        u = 2 * math.pi * i / nu
        for j in range(nv):
            v = 2 * math.pi * j / nv
            r = major + minor * math.cos(v)
            verts.append((r * math.cos(u), r * math.sin(u), minor * math.sin(v)))
    for i in range(nu):
        for j in range(nv):
            a = i * nv + j
            b = ((i + 1) % nu) * nv + j
            c = ((i + 1) % nu) * nv + (j + 1) % nv
            d = i * nv + (j + 1) % nv
            faces += [(a, b, c), (a, c, d)]
    return verts, faces


def signed_volume(verts, faces):
    return sum(dot(verts[a], cross(verts[b], verts[c])) for a, b, c in faces) / 6.0


def orient_outward(verts, faces):
    if signed_volume(verts, faces) < 0:
        faces = [(a, c, b) for a, b, c in faces]
    return faces


def is_closed(faces):
    directed = {}
    for f in faces:
        for k in range(3):
            e = (f[k], f[(k + 1) % 3])
            directed[e] = directed.get(e, 0) + 1
    return all(n == 1 and directed.get((b, a), 0) == 1 for (a, b), n in directed.items())


def vertex_normals(verts, faces):
    acc = [(0.0, 0.0, 0.0)] * len(verts)
    for a, b, c in faces:
        n = cross(sub(verts[b], verts[a]), sub(verts[c], verts[a]))  # area weighted
        for i in (a, b, c):
            acc[i] = add(acc[i], n)
    return [normalize(n) for n in acc]


def write_ply(path, verts, faces, normals, uvs):
    with open(path, "wb") as f:
        header = (
            "ply\nformat binary_little_endian 1.0\ncomment generated by tools/make_creature.py\n"
            f"element vertex {len(verts)}\n"
            "property float x\nproperty float y\nproperty float z\n"
            "property float nx\nproperty float ny\nproperty float nz\n"
            "property float u\nproperty float v\n"
            f"element face {len(faces)}\n"
            "property list uchar uint vertex_indices\nend_header\n")
        f.write(header.encode("ascii"))
        vb = bytearray()
        for p, n, t in zip(verts, normals, uvs):
            vb += struct.pack("<8f", p[0], p[1], p[2], n[0], n[1], n[2], t[0], t[1])
        f.write(vb)
        fb = bytearray()
        for a, b, c in faces:
            fb += struct.pack("<BIII", 3, a, b, c)
        f.write(fb)
    return os.path.getsize(path)


def f32(x):
    return struct.unpack("<f", struct.pack("<f", x))[0]


def round_verts(verts):
    """Round to float32 so the checks see exactly what is written."""
    return [(f32(x), f32(y), f32(z)) for x, y, z in verts]


# ----------------------------------------------------------------------------- shapes


def bump(u, centre, width, amp):
    """Gaussian in angle around the unit direction `centre` (width in radians)."""
    c = dot(u, centre)
    ang2 = 2.0 * (1.0 - c)  # ~angle^2 for small angles
    return amp * math.exp(-ang2 / (width * width))


def ellipsoid_radius(u, ax, ay, az):
    return 1.0 / math.sqrt((u[0] / ax) ** 2 + (u[1] / ay) ** 2 + (u[2] / az) ** 2)


D_SNOUT = normalize((0.0, -0.3, 1.0))
D_NECK = normalize((0.0, -0.75, -0.65))
D_BROW = [normalize((s * 0.38, 0.42, 0.82)) for s in (-1, 1)]
D_EYE = [normalize((s * 0.50, 0.18, 0.84)) for s in (-1, 1)]
D_CHEEK = [normalize((s * 0.80, -0.15, 0.55)) for s in (-1, 1)]
D_HORN = [normalize((s * 0.42, 0.80, -0.42)) for s in (-1, 1)]
D_NOSTRIL = [normalize((s * 0.12, -0.12, 1.0)) for s in (-1, 1)]


def skin_radius(u):
    r = ellipsoid_radius(u, 0.33, 0.36, 0.42)
    r += bump(u, D_SNOUT, 0.42, 0.20)
    r += bump(u, D_NECK, 0.55, 0.16)
    for d in D_BROW:
        r += bump(u, d, 0.16, 0.045)
    for d in D_EYE:
        r -= bump(u, d, 0.11, 0.035)
    for d in D_CHEEK:
        r += bump(u, d, 0.25, 0.03)
    for d in D_HORN:
        r += bump(u, d, 0.13, 0.20)
    for d in D_NOSTRIL:
        r -= bump(u, d, 0.05, 0.012)
    # dorsal ridge: small bumps along the top midline, from the brow to the neck
    for k in range(7):
        th = math.radians(30 + 22 * k)
        r += bump(u, (0.0, math.sin(th), math.cos(th)), 0.07, 0.018)
    # flatten the underside of the jaw a little
    if u[1] < 0:
        r *= 1.0 - 0.05 * (-u[1]) ** 2 * max(0.0, u[2])
    return r


def skull_radius(u):
    r = ellipsoid_radius(u, 0.25, 0.27, 0.32)
    r += bump(u, D_SNOUT, 0.36, 0.12)
    for d in D_BROW:
        r += bump(u, d, 0.16, 0.025)
    for d in D_EYE:
        r -= bump(u, d, 0.14, 0.06)
    for d in D_CHEEK:
        r += bump(u, d, 0.22, 0.02)
    for d in D_HORN:
        r += bump(u, d, 0.12, 0.08)
    return r


def radial_mesh(subdiv, radius_fn, centre):
    dirs, faces = icosphere(subdiv)
    verts = [add(centre, mul(u, radius_fn(u))) for u in dirs]
    return dirs, verts, faces


def mandible(centre):
    """A capsule-shaped rod (elliptical section, rounded ends) bent into a horseshoe around a
    vertical axis: chin forward (+z), tapering toward the ends."""
    big_r, half_len, cap = 0.13, 0.19, 0.022
    n_psi, n_cap, n_body = 16, 6, 24
    body = half_len - cap
    prof = [(-half_len, 0.0)]
    for k in range(1, n_cap + 1):
        th = 0.5 * math.pi * k / n_cap
        prof.append((-body - cap * math.cos(th), math.sin(th)))
    for j in range(1, n_body):
        prof.append((-body + 2 * body * j / n_body, 1.0))
    for k in range(n_cap, 0, -1):
        th = 0.5 * math.pi * k / n_cap
        prof.append((body + cap * math.cos(th), math.sin(th)))
    prof.append((half_len, 0.0))
    verts = []
    ring_start = []
    for s, rho in prof:
        ring_start.append(len(verts))
        n = 1 if rho == 0.0 else n_psi
        for i in range(n):
            psi = 2 * math.pi * i / n
            taper = 1.0 - 0.35 * abs(s) / half_len
            a = rho * math.cos(psi) * 0.026 * taper
            b = rho * math.sin(psi) * 0.016 * taper
            phi = s / big_r
            rr = big_r + a
            verts.append((centre[0] + rr * math.sin(phi), centre[1] + b + 0.055 * (phi / 1.5) ** 2,
                          centre[2] - big_r + rr * math.cos(phi)))
    faces = []
    last = len(prof) - 1
    for i in range(n_psi):
        j = (i + 1) % n_psi
        faces.append((0, ring_start[1] + j, ring_start[1] + i))
        faces.append((ring_start[last], ring_start[last - 1] + i, ring_start[last - 1] + j))
    for r in range(1, last - 1):
        a0, b0 = ring_start[r], ring_start[r + 1]
        for i in range(n_psi):
            j = (i + 1) % n_psi
            faces += [(a0 + i, a0 + j, b0 + j), (a0 + i, b0 + j, b0 + i)]
    return verts, faces


def max_dihedral_deg(verts, faces):
    """Largest angle between the normals of two triangles sharing an edge."""
    normals = [normalize(cross(sub(verts[b], verts[a]), sub(verts[c], verts[a]))) for a, b, c in faces]
    edge_face = {}
    worst = 0.0
    for fi, f in enumerate(faces):
        for k in range(3):
            e = (min(f[k], f[(k + 1) % 3]), max(f[k], f[(k + 1) % 3]))
            if e in edge_face:
                c = max(-1.0, min(1.0, dot(normals[fi], normals[edge_face[e]])))
                worst = max(worst, math.degrees(math.acos(c)))
            else:
                edge_face[e] = fi
    return worst


def vertebrae(start, direction, count, spacing):
    verts, faces = [], []
    w = normalize(direction)
    a = normalize(cross(w, (1.0, 0.0, 0.0)))
    b = cross(w, a)
    for k in range(count):
        tv, tf = torus(0.036 - 0.004 * k, 0.014, 24, 12)
        c = add(start, mul(w, spacing * k))
        base = len(verts)
        for x, y, z in tv:
            verts.append(add(c, add(add(mul(a, x), mul(b, y)), mul(w, z))))
        faces += [(i + base, j + base, l + base) for i, j, l in tf]
    return verts, faces


def backdrop():
    """Floor at y = FLOOR_Y from z = +3 back to the bend, quarter circle, wall up to y = 3."""
    floor_y, z_back, bend, width, top = -0.62, -1.6, 0.8, 6.0, 3.0
    # profile along the sweep: (y, z, ny, nz)
    prof = []
    n_floor, n_bend, n_wall = 12, 12, 10
    z0 = z_back + bend
    for i in range(n_floor + 1):
        z = 3.0 + (z0 - 3.0) * i / n_floor
        prof.append((floor_y, z, 1.0, 0.0))
    for i in range(1, n_bend + 1):
        a = 0.5 * math.pi * i / n_bend
        prof.append((floor_y + bend - bend * math.cos(a), z0 - bend * math.sin(a), math.cos(a), math.sin(a)))
    y1 = floor_y + bend
    for i in range(1, n_wall + 1):
        prof.append((y1 + (top - y1) * i / n_wall, z_back, 0.0, 1.0))
    nx = 16
    verts, normals, uvs, faces = [], [], [], []
    arc = [0.0]
    for i in range(1, len(prof)):
        arc.append(arc[-1] + math.hypot(prof[i][0] - prof[i - 1][0], prof[i][1] - prof[i - 1][1]))
    for i, (y, z, ny, nz) in enumerate(prof):
        for j in range(nx + 1):
            x = -width / 2 + width * j / nx
            verts.append((x, y, z))
            normals.append((0.0, ny, nz))
            uvs.append((j / nx, arc[i] / arc[-1]))
    for i in range(len(prof) - 1):
        for j in range(nx):
            a = i * (nx + 1) + j
            b = a + 1
            c = a + nx + 2
            d = a + nx + 1
            faces += [(a, b, c), (a, c, d)]
    # make the winding agree with the normals
    p = verts
    n0 = cross(sub(p[faces[0][1]], p[faces[0][0]]), sub(p[faces[0][2]], p[faces[0][0]]))
    if n0[1] < 0:
        faces = [(a, c, b) for a, b, c in faces]
    return verts, normals, uvs, faces


# ----------------------------------------------------------------------------- checks


def closest_on_triangle(p, a, b, c):
    """Closest point to p on triangle abc (Ericson, Real-Time Collision Detection 5.1.5)."""
    ab, ac, ap = sub(b, a), sub(c, a), sub(p, a)
    d1, d2 = dot(ab, ap), dot(ac, ap)
    if d1 <= 0 and d2 <= 0:
        return a
    bp = sub(p, b)
    d3, d4 = dot(ab, bp), dot(ac, bp)
    if d3 >= 0 and d4 <= d3:
        return b
    vc = d1 * d4 - d3 * d2
    if vc <= 0 and d1 >= 0 and d3 <= 0:
        return add(a, mul(ab, d1 / (d1 - d3)))
    cp = sub(p, c)
    d5, d6 = dot(ab, cp), dot(ac, cp)
    if d6 >= 0 and d5 <= d6:
        return c
    vb = d5 * d2 - d1 * d6
    if vb <= 0 and d2 >= 0 and d6 <= 0:
        return add(a, mul(ac, d2 / (d2 - d6)))
    va = d3 * d6 - d5 * d4
    if va <= 0 and (d4 - d3) >= 0 and (d5 - d6) >= 0:
        return add(b, mul(sub(c, b), (d4 - d3) / ((d4 - d3) + (d5 - d6))))
    denom = 1.0 / (va + vb + vc)
    v, w = vb * denom, vc * denom
    return add(a, add(mul(ab, v), mul(ac, w)))


class TriGrid:
    """Uniform grid of triangle bounding boxes for near-distance queries."""

    def __init__(self, verts, faces, cell):
        self.v, self.f, self.cell = verts, faces, cell
        self.cells = {}
        for ti, (a, b, c) in enumerate(faces):
            lo = [min(verts[a][k], verts[b][k], verts[c][k]) for k in range(3)]
            hi = [max(verts[a][k], verts[b][k], verts[c][k]) for k in range(3)]
            for key in self._keys(lo, hi):
                self.cells.setdefault(key, []).append(ti)

    def _keys(self, lo, hi):
        i0 = [int(math.floor(lo[k] / self.cell)) for k in range(3)]
        i1 = [int(math.floor(hi[k] / self.cell)) for k in range(3)]
        for x in range(i0[0], i1[0] + 1):
            for y in range(i0[1], i1[1] + 1):
                for z in range(i0[2], i1[2] + 1):
                    yield (x, y, z)

    def any_within(self, p, r):
        seen = set()
        for key in self._keys([p[k] - r for k in range(3)], [p[k] + r for k in range(3)]):
            for ti in self.cells.get(key, ()):
                if ti in seen:
                    continue
                seen.add(ti)
                a, b, c = (self.v[i] for i in self.f[ti])
                q = closest_on_triangle(p, a, b, c)
                if length(sub(p, q)) < r:
                    return True
        return False


def ray_parity_inside(p, verts, faces):
    """Point-in-mesh by counting crossings of a ray in an irrational direction."""
    d = normalize((0.5772156649, 0.3183098862, 0.7598356857))
    count = 0
    for a, b, c in faces:
        va, vb, vc = verts[a], verts[b], verts[c]
        e1, e2 = sub(vb, va), sub(vc, va)
        h = cross(d, e2)
        det = dot(e1, h)
        if abs(det) < 1e-15:
            continue
        s = sub(p, va)
        u = dot(s, h) / det
        if u < 0 or u > 1:
            continue
        q = cross(s, e1)
        v = dot(d, q) / det
        if v < 0 or u + v > 1:
            continue
        if dot(e2, q) / det > 0:
            count += 1
    return count % 2 == 1


def components(faces):
    parent = {}

    def find(x):
        while parent.setdefault(x, x) != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for a, b, c in faces:
        ra = find(a)
        parent[find(b)] = ra
        parent[find(c)] = ra
    groups = {}
    for f in faces:
        groups.setdefault(find(f[0]), []).append(f)
    return list(groups.values())


def check_clearance(label, verts, faces, other_verts, other_faces, clearance):
    """Every triangle of (verts, faces) keeps `clearance` from the other mesh."""
    grid = TriGrid(other_verts, other_faces, 0.04)
    for a, b, c in faces:
        g = mul(add(add(verts[a], verts[b]), verts[c]), 1.0 / 3.0)
        rad = max(length(sub(verts[i], g)) for i in (a, b, c))
        if grid.any_within(g, clearance + rad):
            raise SystemExit(f"check failed: {label}: triangle near {g} is closer than {clearance}")


def main():
    out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scenes", "meshes")
    check = True
    args = sys.argv[1:]
    while args:
        a = args.pop(0)
        if a == "--out" and args:
            out = args.pop(0)
        elif a == "--no-check":
            check = False
        else:
            raise SystemExit(__doc__)
    os.makedirs(out, exist_ok=True)

    centre = (0.0, 0.0, 0.0)
    # --- skin
    dirs, skin_v, skin_f = radial_mesh(5, skin_radius, centre)
    skin_f = orient_outward(skin_v, skin_f)
    # centre the bounding box on the origin and scale to 1.0 tall
    ys = [v[1] for v in skin_v]
    scale = 1.0 / (max(ys) - min(ys))
    lo = [min(v[k] for v in skin_v) for k in range(3)]
    hi = [max(v[k] for v in skin_v) for k in range(3)]
    shift = [-(lo[k] + hi[k]) * 0.5 for k in range(3)]

    def place(v):
        return ((v[0] + shift[0]) * scale, (v[1] + shift[1]) * scale, (v[2] + shift[2]) * scale)

    skin_v = round_verts([place(v) for v in skin_v])
    skin_uv = []
    ylo, yhi = min(v[1] for v in skin_v), max(v[1] for v in skin_v)
    for u in dirs:
        skin_uv.append((0.5 + math.atan2(u[0], u[2]) / (2 * math.pi), (u[1] + 1.0) * 0.5))

    # --- skeleton: skull, mandible, vertebrae (built in the unscaled frame, then placed)
    skull_dirs, skull_v, skull_f = radial_mesh(4, skull_radius, (0.0, 0.01, 0.0))
    jaw_v, jaw_f = mandible((0.0, -0.24, 0.36))
    neck = normalize((0.0, -0.75, -0.65))
    vert_v, vert_f = vertebrae(mul(neck, 0.35), neck, 3, 0.06)
    parts = []
    for v, f in ((skull_v, skull_f), (jaw_v, jaw_f), (vert_v, vert_f)):
        v = round_verts([place(p) for p in v])
        parts.append((v, f))
    bone_v, bone_f, bone_uv = [], [], []
    for v, f in parts:
        base = len(bone_v)
        f = orient_outward(v, f)
        bone_f += [(a + base, b + base, c + base) for a, b, c in f]
        bone_v += v
    bone_lo = [min(v[k] for v in bone_v) for k in range(3)]
    bone_hi = [max(v[k] for v in bone_v) for k in range(3)]
    for p in bone_v:
        bone_uv.append(tuple((p[k] - bone_lo[k]) / (bone_hi[k] - bone_lo[k]) for k in (0, 1)))

    # --- backdrop
    bd_v, bd_n, bd_uv, bd_f = backdrop()
    bd_v = round_verts(bd_v)

    if check:
        for name, v, f in (("skin", skin_v, skin_f), ("skeleton", bone_v, bone_f)):
            if not is_closed(f):
                raise SystemExit(f"check failed: {name} is not closed")
            if signed_volume(v, f) <= 0:
                raise SystemExit(f"check failed: {name} is not wound outward")
            # Offsetting a spawned ray along the normal (Waechter & Binder) can land on the
            # wrong side next to features sharper than 90 degrees: keep the meshes smooth.
            worst = max_dihedral_deg(v, f)
            if worst > MAX_DIHEDRAL:
                raise SystemExit(f"check failed: {name} has adjacent faces {worst:.1f} degrees apart")
            print(f"{name}: largest angle between adjacent face normals {worst:.1f} degrees")
        comps = components(bone_f)
        if len(comps) != 5:
            raise SystemExit(f"check failed: expected 5 bone components, found {len(comps)}")
        for ci, comp in enumerate(comps):
            a, b, c = comp[0]
            g = mul(add(add(bone_v[a], bone_v[b]), bone_v[c]), 1.0 / 3.0)
            if not ray_parity_inside(g, skin_v, skin_f):
                raise SystemExit(f"check failed: bone component {ci} is outside the skin")
            check_clearance(f"bone {ci} vs skin", bone_v, comp, skin_v, skin_f, CLEARANCE)
            others = [f for cj, cf in enumerate(comps) if cj != ci for f in cf]
            check_clearance(f"bone {ci} vs other bones", bone_v, comp, bone_v, others, CLEARANCE)
        if not is_closed(skin_f) or max(v[1] for v in skin_v) - min(v[1] for v in skin_v) > 1.0001:
            raise SystemExit("check failed: skin size")
        print(f"checks passed: skin and {len(comps)} bone pieces closed and outward; "
              f"clearance >= {CLEARANCE} everywhere")

    sizes = []
    sizes.append(("creature_skin.ply", write_ply(os.path.join(out, "creature_skin.ply"), skin_v, skin_f,
                                                 vertex_normals(skin_v, skin_f), skin_uv), len(skin_f)))
    sizes.append(("creature_skeleton.ply", write_ply(os.path.join(out, "creature_skeleton.ply"), bone_v,
                                                     bone_f, vertex_normals(bone_v, bone_f), bone_uv),
                  len(bone_f)))
    sizes.append(("backdrop.ply", write_ply(os.path.join(out, "backdrop.ply"), bd_v, bd_f, bd_n, bd_uv),
                  len(bd_f)))
    sp_dirs, sp_f = icosphere(4)
    sp_v = round_verts([mul(u, 0.5) for u in sp_dirs])
    sp_uv = []
    for u in sp_dirs:
        phi = math.atan2(u[2], u[0]) % (2 * math.pi)
        sp_uv.append((phi / (2 * math.pi), math.acos(max(-1.0, min(1.0, u[1]))) / math.pi))
    if check and not (is_closed(sp_f) and signed_volume(sp_v, sp_f) > 0):
        raise SystemExit("check failed: sphere")
    sizes.append(("sphere.ply", write_ply(os.path.join(out, "sphere.ply"), sp_v, sp_f, sp_dirs, sp_uv),
                  len(sp_f)))
    for name, size, nf in sizes:
        print(f"wrote {name}: {nf} triangles, {size} bytes")
    print("skin bounds:", [round(min(v[k] for v in skin_v), 3) for k in range(3)],
          [round(max(v[k] for v in skin_v), 3) for k in range(3)])


if __name__ == "__main__":
    main()
