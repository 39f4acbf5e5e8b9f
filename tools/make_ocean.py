#!/usr/bin/env python3
"""Make the ocean of scenes/ocean_foam.toml: a closed water body (PLY) and its foam (OpenVDB).

Requirements: Python 3 with numpy; writing the foam VDB also needs OpenVDB's Python module
(`pyopenvdb`, Debian package python3-openvdb). Debian's interpreter has both:

    /usr/bin/python3 tools/make_ocean.py            # writes the two files below
    /usr/bin/python3 tools/make_ocean.py --check    # self-checks only (numpy only), no files

The outputs are committed, so rendering the scene needs no Python. Writes (relative to the
repository root, or --out DIR):

  scenes/meshes/ocean_body.ply  the water body, metres, y up, closed and outward wound: the
        wave surface (per-vertex normals) over a square clipmap of tiles centred at the origin,
        a skirt down the four sides and a flat bottom DEPTH metres down.
  volumes/ocean_foam.vdb        grid `density` (fog volume, values in [0, 1]): foam at the
        breaking crests near the camera, densest at the surface and thinning with depth.

The surface (docs/references.md §13.1–§13.3): a Phillips spectrum (Tessendorf 2001) on an N x N grid of
a PATCH x PATCH metre periodic patch, synthesised by inverse FFT at time 0 with horizontal
("choppy") displacement x + chop * D(x), D = sum of +i (k/|k|) h~ e^{ik.x} (the sign that
sharpens crests; with -i they spread). The mesh is a clipmap: a core of 2n x 2n cells of
PATCH/N metres, then rings whose cells double in size and whose outer half-width doubles, so a
cell covers about the same angle from the centre; each ring samples the field low-passed to
its own spacing, blended across the ring so neighbouring rings agree on their shared vertices;
the cells of a ring that touch the finer level are split into three triangles through the finer
level's middle vertex, so there are no T-junctions and the surface is watertight. The
displacement fades to zero at the outer edge, where the skirt goes straight down.

Whitecaps: where the Jacobian J of the choppy map falls below J_TH, coverage
f = clamp((J_TH - J) / (J_TH - J_MIN)). The foam grid holds rho = f * exp(-s / DELTA) at depth s
below the surface (cut at 4 DELTA), with a one-voxel ramp above it, over the inner part of the
core; it fades to zero towards the grid's edge. The clipmap's centre is put over the part of the
patch with the most whitecaps within the foam box, so that the camera sees foam. The choppiness
is lowered until J >= J_FLOOR everywhere: folded (inverted) triangles would make the body
intersect itself.

--check runs the script's own tests (docs/references.md §13.6) and exits non-zero on a failure:
the inverse FFT is real, the seed-averaged height variance equals the spectrum's sum, a single
mode moves as A cos(k.x - sqrt(g k) t), positive chop sharpens crests (crest spacing < trough
spacing, J(crest) = 1 - chop k A), the spectral Jacobian and normals match finite differences,
a flat sea has normal (0, 1, 0), and the foam profile falls by e^-3 over 3 DELTA.
"""

import argparse
import math
import os
import struct
import sys

import numpy as np

G = 9.81  # m/s^2

# Spectrum and patch.
WIND = 8.0  # wind speed at 10 m, m/s
WIND_DIR = (math.cos(math.radians(-70.0)), math.sin(math.radians(-70.0)))  # (x, z), towards -z, a little +x
HS = 1.3  # significant wave height 4 sqrt(<h^2>), metres (sets Phillips' A)
PATCH = 204.8  # periodic patch, metres (peak wavelength ~ 8.9 WIND^2/g = 58 m)
N = 2048  # FFT resolution: 0.1 m
CHOP = 2.2  # choppiness (clamped so that J >= J_FLOOR everywhere: no folded triangles)
J_FLOOR = 0.03
SEED = 14

# Clipmap.
HALF_CELLS = 40  # n: the core is 2n x 2n cells of PATCH/N; every ring is 2n cells across its outer edge
RINGS = 8  # outer half-width n * 2^RINGS * PATCH/N = 1024 m
DEPTH = 500.0  # bottom of the body, metres below the mean surface
CORE_BLEND = 0.75  # the core starts blending towards ring 1's field at this fraction of its half-width

# Foam.
J_TH = 0.6  # whitecap threshold on the Jacobian
J_MIN = 0.3  # full coverage at and below
DELTA = 0.03  # e-folding depth, metres
VOXEL = 0.015  # foam voxel size, metres (<= DELTA / 2)
FOAM_HALF = 3.0  # foam grid covers |x|, |z| <= FOAM_HALF metres (inside the core's unblended part)
FOAM_FADE = 0.6  # and fades to zero over the last FOAM_FADE metres


# ---------------------------------------------------------------------------------------------
# Spectrum and fields


def wavenumbers(n, patch):
    """k_x, k_z on the FFT grid (numpy's frequency order), shape (n, n), index [ix, iz]."""
    k1 = 2.0 * np.pi * np.fft.fftfreq(n, d=patch / n)
    kx, kz = np.meshgrid(k1, k1, indexing="ij")
    return kx, kz


def phillips(kx, kz, wind, wind_dir, small):
    """Phillips spectrum P(k) / A: exp(-1/(kL)^2)/k^4 |k^.w^|^2 exp(-k^2 l^2), L = V^2/g, P(0) = 0."""
    k = np.hypot(kx, kz)
    big_l = wind * wind / G
    with np.errstate(divide="ignore", invalid="ignore"):
        kd = (kx * wind_dir[0] + kz * wind_dir[1]) / k
        p = np.exp(-1.0 / (k * big_l) ** 2) / k**4 * kd**2 * np.exp(-(k * small) ** 2)
    p[k == 0] = 0.0
    n = kx.shape[0]
    # Zero the Nyquist row and column: there -k aliases to k and derivative fields turn imaginary.
    p[n // 2, :] = 0.0
    p[:, n // 2] = 0.0
    return p


def neg_index(a):
    """a(-k) on numpy's frequency grid."""
    return np.roll(a[::-1, ::-1], 1, axis=(0, 1))


def h0_amplitudes(p, rng):
    """h~0(k) = (xi_r + i xi_i) sqrt(P/2), xi ~ N(0, 1)."""
    xi = rng.standard_normal(p.shape) + 1j * rng.standard_normal(p.shape)
    return xi * np.sqrt(p / 2.0)


def spectrum_at(h0, kx, kz, t, depth=None):
    """h~(k, t) = h~0(k) e^{-i w t} + conj(h~0(-k)) e^{i w t}, w = sqrt(g k) (or sqrt(g k tanh kD)).

    Tessendorf writes e^{+i w t} on h~0(k); with the e^{+ik.x} synthesis that moves each
    h~0(k) against k. The opposite sign moves it along k (with the wind); at t = 0, the
    scene's instant, both agree."""
    k = np.hypot(kx, kz)
    w = np.sqrt(G * k * (np.tanh(k * depth) if depth else 1.0))
    return h0 * np.exp(-1j * w * t) + np.conj(neg_index(h0)) * np.exp(1j * w * t)


def synth(ht):
    """Unnormalised inverse FFT: f(x) = sum_k f~(k) e^{ik.x} (complex)."""
    n = ht.shape[0]
    return np.fft.ifft2(ht) * (n * n)


def fields(ht, kx, kz, chop, lowpass=None):
    """Height, displacement and their derivatives on the grid, as a dict of real arrays.

    D = sum +i (k/|k|) h~ e^{ik.x}; with chop > 0 crests sharpen (docs/references.md §13.2).
    lowpass: a cut-off wavenumber; the spectrum is weighted by exp(-(k/kc)^4).
    """
    k = np.hypot(kx, kz)
    if lowpass is not None:
        ht = ht * np.exp(-((k / lowpass) ** 4))
    with np.errstate(divide="ignore", invalid="ignore"):
        ux = np.where(k > 0, kx / k, 0.0)
        uz = np.where(k > 0, kz / k, 0.0)
    # Two real fields per complex IFFT: f + i g from f~ + i g~ (both Hermitian).
    a = synth(ht + 1j * (1j * kx * ht))  # h, dh/dx
    b = synth(1j * kz * ht + 1j * (1j * ux * ht))  # dh/dz, Dx
    c = synth(1j * uz * ht + 1j * (-kx * ux * ht))  # Dz, dDx/dx
    d = synth(-kz * uz * ht + 1j * (-kx * uz * ht))  # dDz/dz, dDx/dz (= dDz/dx)
    return {
        "h": a.real, "hx": a.imag, "hz": b.real, "Dx": b.imag, "Dz": c.real,
        "Dxx": c.imag, "Dzz": d.real, "Dxz": d.imag, "stride": 1,
    }


FIELD_KEYS = ("h", "hx", "hz", "Dx", "Dz", "Dxx", "Dzz", "Dxz")


def subsample(f, stride):
    """The fields at every stride-th grid point (the only ones a coarse clipmap level reads)."""
    out = {k: np.ascontiguousarray(f[k][::stride, ::stride]) for k in FIELD_KEYS}
    out["stride"] = stride
    return out


def jacobian(f, chop):
    """J = (1 + l Dx,x)(1 + l Dz,z) - (l Dx,z)^2 of the choppy map x -> x + l D."""
    return (1 + chop * f["Dxx"]) * (1 + chop * f["Dzz"]) - (chop * f["Dxz"]) ** 2


def normals(f, chop):
    """Unit normals n = norm(Tz x Tx) from the tangents of the displaced surface (y up)."""
    jxx, jzz, jxz = 1 + chop * f["Dxx"], 1 + chop * f["Dzz"], chop * f["Dxz"]
    tx = np.stack([jxx, f["hx"], jxz], -1)
    tz = np.stack([jxz, f["hz"], jzz], -1)
    n = np.cross(tz, tx)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def clamp_chop(f, chop, floor):
    """The largest chop' <= chop with J >= floor everywhere (bisection; J(0) = 1)."""
    if jacobian(f, chop).min() >= floor:
        return chop
    lo, hi = 0.0, chop
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if jacobian(f, mid).min() >= floor:
            lo = mid
        else:
            hi = mid
    return lo


def ocean_spectrum(n=N, patch=PATCH, seed=SEED):
    """The scene's h~(k, 0), scaled so that 4 sqrt(<h^2>) = HS, and the wavenumbers."""
    kx, kz = wavenumbers(n, patch)
    p = phillips(kx, kz, WIND, WIND_DIR, small=patch / n)
    p *= (HS / 4.0) ** 2 / (2.0 * p.sum())  # <h^2> = 2 sum P
    h0 = h0_amplitudes(p, np.random.default_rng(seed))
    return spectrum_at(h0, kx, kz, 0.0), kx, kz, p


# ---------------------------------------------------------------------------------------------
# The clipmap mesh


def level_of(i, j, n):
    """Clipmap level and blend weight towards the next level's field at lattice point (i, j)."""
    d = max(abs(i), abs(j))
    if d <= n:
        t = (d - CORE_BLEND * n) / ((1.0 - CORE_BLEND) * n)
        return 0, min(max(t, 0.0), 1.0)
    lev = max(1, math.ceil(math.log2(d / n) - 1e-12))
    inner = n * 2 ** (lev - 1)
    return lev, (d - inner) / (inner)


def smooth(t):
    return t * t * (3.0 - 2.0 * t)


def build_surface(n, rings):
    """Vertices (lattice keys), triangles of the clipmap (wound with normals up)."""
    index = {}
    keys = []

    def vid(i, j):
        k = (i, j)
        v = index.get(k)
        if v is None:
            v = len(keys)
            index[k] = v
            keys.append(k)
        return v

    tris = []

    def cell(a, b, s, inner):
        # Corners in the cyclic order whose fan faces +y: (a,b) -> (a,b+s) -> (a+s,b+s) -> (a+s,b).
        poly = [(a, b), (a, b + s), (a + s, b + s), (a + s, b)]
        out = []
        for q in range(4):
            p0, p1 = poly[q], poly[(q + 1) % 4]
            out.append(p0)
            if inner is not None:
                mx, mz = (p0[0] + p1[0]) // 2, (p0[1] + p1[1]) // 2
                on_x = p0[0] == p1[0] and abs(p0[0]) == inner and abs(mz) < inner
                on_z = p0[1] == p1[1] and abs(p0[1]) == inner and abs(mx) < inner
                if on_x or on_z:
                    out.append((mx, mz))
        ids = [vid(*p) for p in out]
        if len(ids) == 4:
            # Alternate the diagonal in a checkerboard so the tessellation has no preferred direction.
            if ((a // s) + (b // s)) % 2 == 0:
                tris.extend([(ids[0], ids[1], ids[2]), (ids[0], ids[2], ids[3])])
            else:
                tris.extend([(ids[1], ids[2], ids[3]), (ids[1], ids[3], ids[0])])
        else:
            m = next(q for q, p in enumerate(out) if p not in poly)
            ring = ids[m + 1:] + ids[:m]
            for q in range(len(ring) - 1):
                tris.append((ids[m], ring[q], ring[q + 1]))

    for a in range(-n, n):
        for b in range(-n, n):
            cell(a, b, 1, None)
    for lev in range(1, rings + 1):
        s = 2**lev
        outer, inner = n * s, n * s // 2
        for a in range(-outer, outer, s):
            for b in range(-outer, outer, s):
                if -inner <= a < inner and -inner <= b < inner:
                    continue
                cell(a, b, s, inner)
    return keys, tris


def surface_vertices(keys, levels_f, n, rings, h0, npatch, chop, offset):
    """Displaced positions and normals of the lattice points, blended between levels."""
    edge = n * 2**rings
    pos = np.zeros((len(keys), 3))
    nor = np.zeros((len(keys), 3))
    for v, (i, j) in enumerate(keys):
        lev, t = level_of(i, j, n)
        t = smooth(t)
        ii, jj = (i + offset[0]) % npatch, (j + offset[1]) % npatch
        # Fade the displacement out over the outer half of the last ring: flat where the skirt starts.
        d = max(abs(i), abs(j)) / edge
        fade = 1.0 - smooth(min(max((d - 0.5) / 0.5, 0.0), 1.0))
        acc = {}
        for w, f in ((1.0 - t, levels_f[min(lev, len(levels_f) - 1)]), (t, levels_f[min(lev + 1, len(levels_f) - 1)])):
            if w == 0.0:
                continue
            st = f["stride"]
            for key in FIELD_KEYS:
                acc[key] = acc.get(key, 0.0) + w * f[key][ii // st, jj // st]
        x, z = i * h0, j * h0
        pos[v] = (x + fade * chop * acc["Dx"], fade * acc["h"], z + fade * chop * acc["Dz"])
        jxx, jzz, jxz = 1 + fade * chop * acc["Dxx"], 1 + fade * chop * acc["Dzz"], fade * chop * acc["Dxz"]
        tx = np.array([jxx, fade * acc["hx"], jxz])
        tz = np.array([jxz, fade * acc["hz"], jzz])
        nn = np.cross(tz, tx)
        nor[v] = nn / np.linalg.norm(nn)
    return pos, nor


def close_body(pos, nor, keys, tris, n, rings, h0, depth):
    """Adds the skirt (four vertical walls) and the bottom (a fan) under the surface's outer edge."""
    edge = n * 2**rings
    s = 2**rings
    index = {k: v for v, k in enumerate(keys)}
    # The outer boundary in the cyclic order (seen from above) that makes outward walls.
    loop = []
    for a in range(-edge, edge, s):
        loop.append((a, -edge))
    for b in range(-edge, edge, s):
        loop.append((edge, b))
    for a in range(edge, -edge, -s):
        loop.append((a, edge))
    for b in range(edge, -edge, -s):
        loop.append((-edge, b))
    top = [index[k] for k in loop]
    pos = list(map(tuple, pos))
    nor = list(map(tuple, nor))
    base = len(pos)
    for k in loop:
        pos.append((k[0] * h0, -depth, k[1] * h0))
        nor.append((0.0, -1.0, 0.0))
    centre = len(pos)
    pos.append((0.0, -depth, 0.0))
    nor.append((0.0, -1.0, 0.0))
    m = len(loop)
    tris = list(tris)
    for q in range(m):
        a, b = top[q], top[(q + 1) % m]
        c, d = base + q, base + (q + 1) % m
        tris.append((a, d, c))
        tris.append((a, b, d))
        tris.append((centre, c, d))
    return pos, nor, tris


def orient_check(pos, tris):
    """Signed volume (positive: outward) and the number of edges not shared by exactly two faces."""
    p = np.asarray(pos, dtype=np.float64)
    t = np.asarray(tris)
    a, b, c = p[t[:, 0]], p[t[:, 1]], p[t[:, 2]]
    vol = float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)
    edges = {}
    for x, y, z in tris:
        for e in ((x, y), (y, z), (z, x)):
            edges[e] = edges.get(e, 0) + 1
    bad = sum(1 for (x, y), cnt in edges.items() if cnt != 1 or edges.get((y, x), 0) != 1)
    return vol, bad


def write_ply(path, verts, faces, normals):
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment generated by tools/make_ocean.py\n"
        f"element vertex {len(verts)}\n"
        "property float x\nproperty float y\nproperty float z\n"
        "property float nx\nproperty float ny\nproperty float nz\n"
        f"element face {len(faces)}\nproperty list uchar uint vertex_indices\nend_header\n")
    v = np.concatenate([np.asarray(verts, np.float32), np.asarray(normals, np.float32)], axis=1)
    f = np.zeros(len(faces), dtype=[("n", "u1"), ("i", "<u4", 3)])
    f["n"] = 3
    f["i"] = np.asarray(faces, dtype=np.uint32)
    with open(path, "wb") as out:
        out.write(header.encode("ascii"))
        out.write(v.astype("<f4").tobytes())
        out.write(f.tobytes())
    return os.path.getsize(path)


# ---------------------------------------------------------------------------------------------
# Foam


def foam_coverage(j):
    return np.clip((J_TH - j) / (J_TH - J_MIN), 0.0, 1.0)


def bilinear(a, x, z, h0):
    """Periodic bilinear lookup of grid array a (spacing h0) at world x, z (arrays)."""
    n = a.shape[0]
    fx, fz = x / h0, z / h0
    i0, j0 = np.floor(fx).astype(np.int64), np.floor(fz).astype(np.int64)
    tx, tz = fx - i0, fz - j0
    i0, j0 = i0 % n, j0 % n
    i1, j1 = (i0 + 1) % n, (j0 + 1) % n
    return ((1 - tx) * (1 - tz) * a[i0, j0] + tx * (1 - tz) * a[i1, j0]
            + (1 - tx) * tz * a[i0, j1] + tx * tz * a[i1, j1])


def foamiest_window(cover, half):
    """The grid point whose (2 half + 1)^2 periodic window holds the most whitecap coverage."""
    n = cover.shape[0]
    box = np.zeros(n)
    box[: half + 1] = 1.0
    box[n - half:] = 1.0
    win = np.fft.irfft2(np.fft.rfft2(cover) * np.fft.rfft2(np.outer(box, box)), s=cover.shape)
    i, j = np.unravel_index(int(np.argmax(win)), win.shape)
    return int(i), int(j)


def foam_profile(s):
    """Foam density factor at depth s below the surface (s < 0: above): e^{-s/DELTA} to 4 DELTA,
    a linear ramp to zero over one voxel above."""
    return np.where(s >= 0, np.where(s <= 4 * DELTA, np.exp(-s / DELTA), 0.0),
                    np.clip(1.0 + s / VOXEL, 0.0, 1.0))


def foam_grid(f0, chop, h0, offset):
    """Dense foam densities over the foam box and the index of its first voxel."""
    m = int(round(FOAM_HALF / VOXEL))
    c = (np.arange(-m, m) + 0.5) * VOXEL  # voxel centres
    x, z = np.meshgrid(c, c, indexing="ij")
    # Invert the choppy map: the rest point p whose displaced image is (x, z).
    # World (x, z) is patch point (x, z) + offset * h0: shift into the patch, look up, shift back.
    x = x + offset[0] * h0
    z = z + offset[1] * h0
    px, pz = x.copy(), z.copy()
    for _ in range(6):
        px = x - chop * bilinear(f0["Dx"], px, pz, h0)
        pz = z - chop * bilinear(f0["Dz"], px, pz, h0)
    ys = bilinear(f0["h"], px, pz, h0)
    cover = foam_coverage(bilinear(jacobian(f0, chop), px, pz, h0))
    edge = np.maximum(np.abs(x - offset[0] * h0), np.abs(z - offset[1] * h0))
    cover *= 1.0 - smooth(np.clip((edge - (FOAM_HALF - FOAM_FADE)) / FOAM_FADE, 0.0, 1.0))
    lo = math.floor((ys.min() - 4 * DELTA) / VOXEL) - 1
    hi = math.ceil((ys.max() + VOXEL) / VOXEL) + 1
    yc = (np.arange(lo, hi) + 0.5) * VOXEL
    dens = np.zeros((2 * m, hi - lo, 2 * m), dtype=np.float32)
    for k, y in enumerate(yc):
        dens[:, k, :] = cover * foam_profile(ys - y)
    dens[dens < 1e-3] = 0.0
    return dens, (-m, lo, -m), cover


def write_vdb(path, dens, ijk0):
    import pyopenvdb as vdb

    grid = vdb.FloatGrid()
    grid.copyFromArray(dens, ijk=ijk0, tolerance=0.0)
    grid.name = "density"
    grid.gridClass = vdb.GridClass.FOG_VOLUME
    # Index (i, j, k) is the voxel whose centre is ((i + 1/2), (j + 1/2), (k + 1/2)) * VOXEL;
    # OpenVDB puts values at integer index points, so translate by half a voxel.
    grid.transform = vdb.createLinearTransform(voxelSize=VOXEL)
    grid.transform.translate((0.5 * VOXEL, 0.5 * VOXEL, 0.5 * VOXEL))
    # Stored as 16-bit halves (OpenVDB's "is_saved_as_half_float" metadata): densities in [0, 1]
    # need no more, and the file is half the size.
    grid["is_saved_as_half_float"] = True
    grid.pruneInactive()
    vdb.write(path, grids=[grid])
    return os.path.getsize(path), grid.activeVoxelCount()


# ---------------------------------------------------------------------------------------------
# Self-checks (docs/references.md §13.6)


def run_checks():
    failures = []

    def check(ok, what):
        print(("ok   " if ok else "FAIL ") + what)
        if not ok:
            failures.append(what)

    n, patch = 128, 64.0
    kx, kz = wavenumbers(n, patch)
    p = phillips(kx, kz, 6.0, (1.0, 0.0), small=patch / n)
    p *= (1.0 / 4.0) ** 2 / (2.0 * p.sum())  # Hs = 1 m
    # 1. Real output, and <h^2> = 2 sum P over seeds.
    var, worst = 0.0, 0.0
    seeds = 64
    for s in range(seeds):
        ht = spectrum_at(h0_amplitudes(p, np.random.default_rng(s)), kx, kz, 1.7)
        f = synth(ht)
        worst = max(worst, float(np.abs(f.imag).max() / np.abs(f.real).max()))
        var += float((f.real**2).mean())
    var /= seeds
    check(worst < 1e-6, f"inverse FFT is real: max |Im| / max |Re| = {worst:.2e} < 1e-6")
    rel = var / (2 * p.sum()) - 1
    check(abs(rel) < 0.03, f"seed-averaged <h^2> = 2 sum P within 3 %: {100 * rel:+.2f} %")
    # 2. A single mode is A cos(k.x - sqrt(g k) t); the patch is periodic.
    h0 = np.zeros((n, n), complex)
    m = (5, 3)
    amp = 0.4
    h0[m] = amp / 2  # h~ = h0(k) e^{iwt} + conj(h0(-k)) e^{-iwt}: real part gives A cos
    t = 2.3
    hmode = synth(spectrum_at(h0, kx, kz, t)).real
    x = np.arange(n) * patch / n
    xx, zz = np.meshgrid(x, x, indexing="ij")
    k = (kx[m], kz[m])
    ref = amp * np.cos(k[0] * xx + k[1] * zz - math.sqrt(G * math.hypot(*k)) * t)
    check(np.abs(hmode - ref).max() < 1e-9, "a single mode is A cos(k.x - sqrt(gk) t)")
    check(abs(k[0] * patch / (2 * math.pi) - round(k[0] * patch / (2 * math.pi))) < 1e-12,
          "every wavenumber is a multiple of 2 pi / PATCH (periodic patch)")
    # 3. Chop sharpens crests: a cosine wave along x, crest spacing < trough spacing, J = 1 - l k A.
    h0 = np.zeros((n, n), complex)
    h0[(4, 0)] = amp / 2
    f = fields(spectrum_at(h0, kx, kz, 0.0), kx, kz, 1.0)
    kk = kx[4, 0]
    lam = 0.2 / (kk * amp)  # l k A = 0.2
    xs = x + lam * f["Dx"][:, 0]
    crest = int(np.argmax(f["h"][:, 0]))
    trough = int(np.argmin(f["h"][:, 0]))
    sp = lambda i: (xs[(i + 1) % n] - xs[i - 1]) % patch / 2  # noqa: E731
    check(sp(crest) < patch / n < sp(trough),
          f"positive chop: crest spacing {sp(crest):.4f} < {patch / n:.4f} < trough spacing {sp(trough):.4f}")
    jc = jacobian(f, lam)[crest, 0]
    check(abs(jc - (1 - 0.2)) < 1e-9, f"J(crest) = 1 - chop k A = 0.8: {jc:.6f}")
    # 4. Spectral J and normals against finite differences of the displaced surface.
    ht = spectrum_at(h0_amplitudes(p, np.random.default_rng(3)), kx, kz, 0.0)
    # Smooth the spectrum so that central differences at the grid spacing are accurate to < 1 %.
    ht = ht * np.exp(-((np.hypot(kx, kz) * patch / n * 4.0) ** 2))
    f = fields(ht, kx, kz, 1.0)
    lam = clamp_chop(f, 1.0, 0.3)
    check(lam > 0.5, f"test sea is choppy (chop {lam:.3f} > 0.5)")
    px = xx + lam * f["Dx"]
    pz = zz + lam * f["Dz"]
    py = f["h"]
    d = patch / n
    dx_ = [(np.roll(a, -1, 0) - np.roll(a, 1, 0)) / (2 * d) for a in (px, py, pz)]
    dz_ = [(np.roll(a, -1, 1) - np.roll(a, 1, 1)) / (2 * d) for a in (px, py, pz)]
    # Periodic wrap of x and z positions across the patch edge.
    dx_[0] = np.where(np.abs(dx_[0]) > n / 4, dx_[0] - np.sign(dx_[0]) * patch / (2 * d), dx_[0])
    dz_[2] = np.where(np.abs(dz_[2]) > n / 4, dz_[2] - np.sign(dz_[2]) * patch / (2 * d), dz_[2])
    jfd = dx_[0] * dz_[2] - dz_[0] * dx_[2]
    js = jacobian(f, lam)
    err_j = float(np.abs(jfd - js).max() / np.abs(js).max())
    check(err_j < 0.01, f"spectral Jacobian = finite differences within 1 %: {100 * err_j:.3f} %")
    nfd = np.cross(np.stack(dz_, -1), np.stack(dx_, -1))
    nfd /= np.linalg.norm(nfd, axis=-1, keepdims=True)
    err_n = float(np.linalg.norm(nfd - normals(f, lam), axis=-1).max())
    check(err_n < 0.01, f"spectral normals = finite differences within 1 %: {100 * err_n:.3f} %")
    flat = fields(np.zeros((n, n), complex), kx, kz, 1.0)
    check(np.allclose(normals(flat, 1.0), [0.0, 1.0, 0.0]), "a flat sea has normal (0, 1, 0)")
    # 5. Foam profile: rho(3 delta) / rho(0) = e^-3, zero beyond 4 delta, in [0, 1].
    r = foam_profile(np.array([0.0, 3 * DELTA, 4.01 * DELTA, -2 * VOXEL]))
    check(abs(r[1] / r[0] - math.exp(-3)) < 1e-12 and r[2] == 0 and r[3] == 0,
          "foam profile: rho(3 delta)/rho(0) = e^-3, 0 below 4 delta and above one voxel")
    check(VOXEL <= DELTA / 2, f"foam voxel {VOXEL} m <= delta/2 = {DELTA / 2} m")
    if failures:
        print(f"{len(failures)} check(s) failed")
        return 1
    print("all checks passed")
    return 0


# ---------------------------------------------------------------------------------------------


def main():
    root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=root, help="repository root to write into")
    ap.add_argument("--check", action="store_true", help="run the self-checks only (numpy only)")
    a = ap.parse_args()
    if a.check:
        sys.exit(run_checks())

    h0 = PATCH / N
    ht, kx, kz, _ = ocean_spectrum()
    base = fields(ht, kx, kz, CHOP)
    chop = clamp_chop(base, CHOP, J_FLOOR)
    j = jacobian(base, chop)
    print(f"patch {PATCH} m, {N}^2, {h0} m; wind {WIND} m/s; Hs {4 * base['h'].std():.3f} m; "
          f"chop {chop:.3f} (asked {CHOP}); J in [{j.min():.3f}, {j.max():.3f}], "
          f"whitecap coverage {100 * foam_coverage(j).mean():.2f} %")
    levels_f = [base]
    for lev in range(1, RINGS + 2):
        kc = math.pi / (2.0 * h0 * 2**lev)
        # Level lev is read at the lattice points of level lev - 1 (stride 2^(lev-1)).
        levels_f.append(subsample(fields(ht, kx, kz, chop, lowpass=kc), 2 ** (lev - 1)))
    keys, tris = build_surface(HALF_CELLS, RINGS)
    offset = foamiest_window(foam_coverage(j), int(round(FOAM_HALF / h0)))
    print(f"the clipmap's centre is patch point {offset} (the most foam within the foam box)")
    pos, nor = surface_vertices(keys, levels_f, HALF_CELLS, RINGS, h0, N, chop, offset)
    pos, nor, tris = close_body(pos, nor, keys, tris, HALF_CELLS, RINGS, h0, DEPTH)
    vol, bad = orient_check(pos, tris)
    if bad or vol <= 0:
        sys.exit(f"the water body is not closed and outward ({bad} bad edges, volume {vol})")
    mesh = os.path.join(a.out, "scenes", "meshes", "ocean_body.ply")
    size = write_ply(mesh, pos, tris, nor)
    print(f"{mesh}: {len(pos)} vertices, {len(tris)} triangles, {size} bytes, "
          f"volume {vol:.4g} m^3 (closed, outward)")
    dens, ijk0, cover = foam_grid(base, chop, h0, offset)
    path = os.path.join(a.out, "volumes", "ocean_foam.vdb")
    size, active = write_vdb(path, dens, ijk0)
    print(f"{path}: {dens.shape} voxels of {VOXEL} m from index {ijk0}, {active} active, "
          f"{size} bytes; foam covers {100 * (cover > 0).mean():.1f} % of the box")


if __name__ == "__main__":
    main()
