#!/usr/bin/env python3
"""Render velour scenes with velour and with Mitsuba 3 on the same machine and compare them.

For each scene (a velour TOML file):
  1. translate it into a Mitsuba 3 scene dictionary (camera, film, lights, spheres, PLY meshes,
     lambertian / dielectric / rough dielectric / null boundaries, homogeneous and absorbing
     interiors, and voxel (OpenVDB) interiors in their bounding box as `heterogeneous` media on a
     `gridvolume` converted to .vol by vdb_to_vol.py; see docs/peers.md for the conventions that
     must match). Every converted grid is checked against the OpenVDB-convention trilinear
     lookup of the original grid at random points before rendering;
  2. render it with the velour binary (`velour render --spp N`), which writes the per-pixel
     variance of the mean;
  3. render it with Mitsuba (`volpathmis`, box filter, independent sampler) in K passes of
     N/K samples with different seeds; the per-pixel mean is the mean of the passes and its
     variance is the batch-means variance (sample variance of the K pass images / K);
  4. compare per pixel and channel with z = (a - b) / sqrt(var_a + var_b) and report the
     fraction of |z| beyond 2 and 3, mean z, mean z^2, the aggregate bias z per channel
     (sum(a - b) / sqrt(sum(var_a + var_b))), and `velour diff --json`'s verdict (Student's t
     with the sample counts). Pixel-channels whose standard error is at float-rounding level
     (<= 1e-6 relative) in both images (constant background) are not z-tested; they must agree
     to 1e-6 relative ("untested_different" counts those that do not);
  5. report efficiency = 1 / (MSE x time) for each renderer, where MSE is estimated by the mean
     over pixels and channels of the variance of the pixel mean (both estimators are unbiased,
     which step 4 checks, so MSE = variance) and time is the wall time of one render of all
     the samples (velour: the render loop time it prints; Mitsuba: one mi.render call with
     all the samples, timed separately from the passes), and the ratio velour / Mitsuba.

Results are printed as a Markdown table and written as JSON and Markdown to --out.
Needs: mitsuba, numpy, OpenEXR (tools/peers/run.sh installs them in a venv), and for voxel interiors
a Python with pyopenvdb (Debian's python3-openvdb; $VELOUR_PEERS_OPENVDB_PYTHON, default /usr/bin/python3).
"""

import argparse
import json
import math
import os
import platform
import re
import subprocess
import sys
import time
import tomllib

import numpy as np

from velour_transforms import object_matrix


class Unsupported(Exception):
    """A velour feature without a faithful Mitsuba equivalent."""


# --------------------------------------------------------------------------------------------
# Scene translation
# --------------------------------------------------------------------------------------------

def colour(v, default):
    if v is None:
        v = default
    if isinstance(v, (int, float)):
        return [float(v)] * 3
    return [float(x) for x in v]


def rgb(v):
    return {"type": "rgb", "value": v}


SMOOTH_ALPHA = 1e-3  # velour: below alpha = roughness^2 = 1e-3 a dielectric is smooth


def boundary_bsdf(o, name):
    surf = o.get("surface")
    if surf is None:
        return {"type": "null"}
    kind = surf["type"]
    if "coat" in surf:
        raise Unsupported(f"{name}: coats have no Mitsuba equivalent in this translator")
    if kind == "lambertian":
        return {"type": "diffuse", "reflectance": rgb(colour(surf.get("reflectance"), 0.8))}
    if kind == "dielectric":
        ior = float(surf.get("ior", 1.4))
        r = float(surf.get("roughness", 0.0))
        alpha = r * r
        tint = colour(surf.get("tint"), 1.0)
        if abs(ior - 1.0) < 1e-6:
            if tint != [1.0, 1.0, 1.0]:
                raise Unsupported(f"{name}: index-matched tinted boundary")
            return {"type": "null"}
        d = {"int_ior": ior, "ext_ior": 1.0, "specular_transmittance": rgb(tint)}
        if alpha < SMOOTH_ALPHA:
            d["type"] = "dielectric"
        else:
            d["type"] = "roughdielectric"
            d["alpha"] = alpha
            d["distribution"] = surf.get("distribution", "ggx")
            d["sample_visible"] = True
        return d
    raise Unsupported(f"{name}: surface type {kind!r} has no faithful Mitsuba equivalent here")


def interior_medium(o, name):
    i = o.get("interior")
    if i is None:
        return None
    att = colour(i.get("attenuation"), 1.0)
    density = float(i.get("density", 1.0))
    sigma_t = [density / a for a in att]
    # Mitsuba reads an RGB sigma_t as a reflectance-like spectrum in [0, 1]: pass the largest
    # channel as `scale` and the normalised colour.
    scale = max(sigma_t) if max(sigma_t) > 0 else 1.0
    sig = [x / scale for x in sigma_t]
    if i["type"] == "absorption":
        return {"type": "homogeneous", "sigma_t": rgb(sig), "scale": scale, "albedo": rgb([0.0, 0.0, 0.0])}
    if i["type"] != "homogeneous":
        raise Unsupported(f"{name}: interior type {i['type']!r} (only voxel interiors with shape = \"bounds\" are translated)")
    if i.get("albedo_mode", "multiple") != "single":
        raise Unsupported(f"{name}: albedo_mode = \"multiple\" (van de Hulst inversion); use \"single\" for comparisons")
    albedo = single_albedo(i)
    return {"type": "homogeneous", "sigma_t": rgb(sig), "scale": scale, "albedo": rgb(albedo), "phase": phase_function(i)}


def single_albedo(i):
    # velour clamps the single-scattering albedo to 1 - 1e-6 (MAX_SINGLE_SCATTERING_ALBEDO).
    return [min(max(a, 0.0), 1.0 - 1e-6) for a in colour(i.get("albedo"), 0.8)]


def phase_function(i):
    phase = i.get("phase", {})
    ptype = phase.get("type", "hg")
    if ptype == "hg":
        g = max(-0.99, min(0.99, float(phase.get("g", 0.0))))  # velour clamps |g| to 0.99
        return {"type": "hg", "g": g} if g != 0.0 else {"type": "isotropic"}
    if ptype == "double_hg":
        return {
            "type": "blendphase",
            "weight": 1.0 - float(phase.get("w", 0.5)),  # Mitsuba: weight of the second phase
            "phase1": {"type": "hg", "g": max(-0.99, min(0.99, float(phase["g1"])))},
            "phase2": {"type": "hg", "g": max(-0.99, min(0.99, float(phase["g2"])))},
        }
    raise Unsupported(f"phase type {ptype!r}")


OPENVDB_PYTHON = os.environ.get("VELOUR_PEERS_OPENVDB_PYTHON", "/usr/bin/python3")
GRID_CHECK_POINTS = 2000


def voxel_medium(o, name, folder, xf, assets, key):
    """A velour `voxel` interior -> (Mitsuba `heterogeneous` medium, world matrix of the
    gridvolume's unit cube, grid record). The VDB grid is converted by vdb_to_vol.py (system
    Python, pyopenvdb) into a .vol holding the samples of index box [lo, lo + res - 1]; the
    volume's unit cube maps to index [lo - 1/2, lo + res - 1/2] (Mitsuba: sample n of an axis at
    local (n + 1/2) / res), then through the grid's own transform and the object transform
    (velour places the grid at `object transform . grid index_to_world`)."""
    i = o["interior"]
    if i.get("albedo_mode", "multiple") != "single":
        raise Unsupported(f"{name}: albedo_mode = \"multiple\" (van de Hulst inversion); use \"single\" for comparisons")
    for k in ("base_albedo", "base_attenuation"):
        if k in i:
            raise Unsupported(f"{name}: combined interiors ({k}) are not translated")
    tracking = i.get("tracking", {})
    if tracking.get("free_flight", "delta") != "delta" or tracking.get("transmittance", "residual") == "ray_march":
        raise Unsupported(f"{name}: ray marching is biased; comparisons use the unbiased trackers")
    att = colour(i.get("attenuation"), 1.0)
    density = float(i.get("density", 1.0))
    sigma_t = [density / a for a in att]  # per unit grid value (velour: sigma_t(x) = d(x) density / attenuation)
    scale = max(sigma_t)
    tint = [s / scale for s in sigma_t]
    vdb_path = os.path.join(folder, i["file"])
    grid_name = i.get("grid", "density")
    vol = os.path.join(assets, f"{key}.vol")
    cmd = [OPENVDB_PYTHON, os.path.join(os.path.dirname(os.path.abspath(__file__)), "vdb_to_vol.py"),
           vdb_path, grid_name, vol, "--check", str(GRID_CHECK_POINTS)]
    if not np.allclose(tint, tint[0]):
        cmd += ["--tint", *(repr(t) for t in tint)]
    try:
        p = subprocess.run(cmd, capture_output=True, text=True)
    except OSError as e:
        raise Unsupported(f"{name}: cannot run {OPENVDB_PYTHON} for pyopenvdb ({e})")
    if p.returncode != 0:
        if "No module named 'pyopenvdb'" in p.stderr:
            raise Unsupported(f"{name}: {OPENVDB_PYTHON} has no pyopenvdb (apt-get install python3-openvdb)")
        raise RuntimeError(f"{name}: vdb_to_vol.py failed: {p.stderr.strip()}")
    info = json.loads(p.stdout)
    lo = np.array(info["lo"], dtype=float)
    res = np.array(info["res"], dtype=float)
    unit_to_index = np.eye(4)
    unit_to_index[:3, :3] = np.diag(res)
    unit_to_index[:3, 3] = lo - 0.5
    index_to_world = xf @ np.array(info["index_to_world"])
    unit_to_world = index_to_world @ unit_to_index
    import mitsuba as mi

    volume = {"type": "gridvolume", "filename": vol, "filter_type": "trilinear", "wrap_mode": "clamp",
              "to_world": mi.ScalarTransform4f(unit_to_world.tolist())}
    medium = {"type": "heterogeneous", "sigma_t": volume, "scale": scale, "albedo": rgb(single_albedo(i)),
              "phase": phase_function(i)}
    record = {"object": name, "file": i["file"], "grid": grid_name, "vol": vol, "res": info["res"], "lo": info["lo"],
              "channels": info["channels"], "tint": tint, "scale": scale, "max": info["max"],
              "index_to_world": index_to_world.tolist(), "check": info.get("check", [])}
    return medium, unit_to_world, record


def check_grid(record):
    """Mitsuba's gridvolume, as translated, against the OpenVDB-convention trilinear lookup of the
    original grid at random points (vdb_to_vol.py --check): returns the largest absolute error."""
    import mitsuba as mi

    unit_to_index = np.eye(4)
    unit_to_index[:3, :3] = np.diag(np.array(record["res"], dtype=float))
    unit_to_index[:3, 3] = np.array(record["lo"], dtype=float) - 0.5
    m = np.array(record["index_to_world"])
    vol = mi.load_dict({"type": "gridvolume", "filename": record["vol"], "filter_type": "trilinear", "wrap_mode": "clamp",
                        "to_world": mi.ScalarTransform4f((m @ unit_to_index).tolist())})
    it = mi.Interaction3f()
    worst = 0.0
    for p, v in record["check"]:
        w = m @ np.array(list(p) + [1.0])
        it.p = mi.Point3f(*w[:3].tolist())
        # np.array(...).ravel() reads both scalar variants' numbers and JIT variants' 1-wide arrays.
        if record["channels"] == 1:
            got = np.array([float(np.array(vol.eval_1(it), dtype=float).ravel()[0])] * 3)
        else:
            got = np.array(vol.eval_3(it), dtype=float).ravel()[:3]
        want = v * np.array(record["tint"])
        worst = max(worst, float(np.abs(got - want).max()))
    return worst


def ply_has_normals(path):
    """Whether a PLY file's vertices carry normals (nx, ny, nz)."""
    with open(path, "rb") as f:
        head = f.read(4096)
    header = head[: head.find(b"end_header")].decode("ascii", "replace").split()
    return all(n in header for n in ("nx", "ny", "nz"))


def translate(scene_path, width, height, max_depth, assets):
    """velour TOML -> (Mitsuba dict, grid records). Raises Unsupported for features without a match.
    Converted grids (.vol) are written to `assets`."""
    import mitsuba as mi

    with open(scene_path, "rb") as f:
        s = tomllib.load(f)
    folder = os.path.dirname(os.path.abspath(scene_path))
    cam = s["camera"]
    if cam.get("type", "pinhole") != "pinhole" or float(cam.get("aperture_radius", 0.0)) > 0.0:
        raise Unsupported("thin-lens cameras are not translated")
    film = s.get("film", {})
    d = {
        "type": "scene",
        # rr_depth = max_depth turns Mitsuba's Russian roulette off: volpathmis folds the
        # roulette's survival probability into the unidirectional strategy's pdf but not into the
        # MIS weight of next event estimation, so with roulette on the two weights sum to less
        # than 1 and media lose ~0.2 % of their energy (docs/peers.md, "Mitsuba's Russian
        # roulette"). velour's roulette (survival min(1, max throughput)) never fires at
        # throughput 1, so neither renderer terminates paths in a white furnace.
        "integrator": {"type": "volpathmis", "max_depth": int(max_depth or film.get("max_depth", 256)),
                       "rr_depth": int(max_depth or film.get("max_depth", 256))},
        "sensor": {
            "type": "perspective",
            "fov": float(cam.get("fov", 40.0)),
            "fov_axis": "y",
            "to_world": mi.ScalarTransform4f().look_at(origin=cam["eye"], target=cam["look_at"], up=cam.get("up", [0, 1, 0])),
            "film": {
                "type": "hdrfilm",
                "width": width,
                "height": height,
                "rfilter": {"type": "box"},
                "pixel_format": "rgb",
                "component_format": "float32",
            },
            "sampler": {"type": "independent", "sample_count": 1},
        },
    }
    for k, l in enumerate(s.get("light", [])):
        kind = l["type"]
        if kind == "environment":
            d[f"light{k}"] = {"type": "constant", "radiance": rgb(colour(l.get("radiance"), 1.0))}
        elif kind == "distant":
            if float(l.get("angular_radius", 0.0)) > 0.0:
                raise Unsupported("distant lights with an angular radius (Mitsuba's directional is a delta light)")
            to_light = np.array(l["direction"], dtype=float)
            to_light /= np.linalg.norm(to_light)
            d[f"light{k}"] = {"type": "directional", "direction": (-to_light).tolist(), "irradiance": rgb(colour(l.get("irradiance"), 3.0))}
        elif kind == "sphere":
            d[f"light{k}"] = {
                "type": "sphere",
                "center": l.get("center", [0, 0, 0]),
                "radius": float(l.get("radius", 0.1)),
                "emitter": {"type": "area", "radiance": rgb(colour(l.get("radiance"), 10.0))},
            }
        else:
            raise Unsupported(f"light type {kind!r}")
    grids = []
    priorities = {int(o.get("priority", 0)) for o in s.get("object", []) if o.get("interior")}
    if len(priorities) > 1:
        raise Unsupported("nested interiors with priorities (Mitsuba has no priority nesting)")
    for k, o in enumerate(s.get("object", [])):
        name = o.get("name", f"object {k}")
        m, sc = object_matrix(o)
        if o["shape"] == "sphere":
            if not np.allclose(sc, sc[0]):
                raise Unsupported(f"{name}: non-uniform sphere scale")
            c = m @ np.array(list(o.get("center", [0, 0, 0])) + [1.0])
            shape = {"type": "sphere", "center": c[:3].tolist(), "radius": float(o.get("radius", 1.0)) * abs(sc[0])}
        elif o["shape"] == "mesh":
            ply = os.path.join(folder, o["file"])
            shape = {
                "type": "ply",
                "filename": ply,
                "to_world": mi.ScalarTransform4f(m.tolist()),
                # velour shades a PLY without normals with its facets' geometric normals; Mitsuba
                # would interpolate vertex normals it computes itself unless told otherwise.
                "face_normals": not ply_has_normals(ply),
            }
        elif o["shape"] == "bounds" and o.get("interior", {}).get("type") == "voxel":
            # velour: an invisible box around the grid's non-empty bricks. Mitsuba: a `cube` on the
            # gridvolume's unit cube (the non-zero voxels plus a ring of zeros); both boxes hold the
            # whole non-zero field, and the field is 0 between them.
            scene_key = os.path.splitext(os.path.basename(scene_path))[0]
            med, unit_to_world, record = voxel_medium(o, name, folder, m, assets, f"{scene_key}.object{k}")
            cube = unit_to_world @ np.array([[0.5, 0, 0, 0.5], [0, 0.5, 0, 0.5], [0, 0, 0.5, 0.5], [0, 0, 0, 1.0]])
            shape = {"type": "cube", "to_world": mi.ScalarTransform4f(cube.tolist()), "bsdf": boundary_bsdf(o, name),
                     "interior": med}
            grids.append(record)
            d[f"object{k}"] = shape
            continue
        else:
            raise Unsupported(f"{name}: shape {o['shape']!r} with interior {o.get('interior', {}).get('type')!r} is not translated")
        shape["bsdf"] = boundary_bsdf(o, name)
        med = interior_medium(o, name)
        if med is not None:
            shape["interior"] = med
        d[f"object{k}"] = shape
    return d, grids


# --------------------------------------------------------------------------------------------
# Rendering
# --------------------------------------------------------------------------------------------

def read_velour_exr(path):
    import OpenEXR

    ch = OpenEXR.File(path, separate_channels=True).channels()
    mean = np.stack([ch[c].pixels for c in "RGB"], axis=-1).astype(np.float64)
    var = np.stack([ch[f"variance.{c}"].pixels for c in "RGB"], axis=-1).astype(np.float64)
    n = ch["samples.N"].pixels.astype(np.float64)
    return mean, var, n


def write_velour_layout_exr(path, mean, var, n):
    """Writes an EXR with velour's channel names (R, G, B, variance.*, samples.N) so that
    `velour diff` can test it."""
    import OpenEXR

    chans = {}
    for i, c in enumerate("RGB"):
        chans[c] = np.ascontiguousarray(mean[..., i].astype(np.float32))
        chans[f"variance.{c}"] = np.ascontiguousarray(var[..., i].astype(np.float32))
    chans["samples.N"] = np.ascontiguousarray(np.full(mean.shape[:2], n, dtype=np.float32))
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    OpenEXR.File(header, chans).write(path)


def render_velour(velour, scene, out, spp, width, height, threads, seed, max_depth):
    cmd = [velour, "render", scene, "--spp", str(spp), "--width", str(width), "--height", str(height),
           "--threads", str(threads), "--seed", str(seed), "-q", "-o", out]
    if max_depth:
        cmd += ["--max-depth", str(max_depth)]
    p = subprocess.run(cmd, capture_output=True, text=True, check=True)
    m = re.search(r"time ([0-9.]+) s", p.stdout)
    seconds = float(m.group(1)) if m else float("nan")
    mean, var, n = read_velour_exr(out)
    return mean, var, seconds


def render_mitsuba(scene_dict, spp, passes, seed0):
    import mitsuba as mi

    per_pass = max(1, spp // passes)
    scene_dict = dict(scene_dict)
    scene_dict["sensor"] = dict(scene_dict["sensor"])
    scene_dict["sensor"]["sampler"] = {"type": "independent", "sample_count": per_pass}
    scene = mi.load_dict(scene_dict)
    images = []
    seconds = 0.0
    for k in range(passes):
        t0 = time.perf_counter()
        img = mi.render(scene, seed=seed0 + k, spp=per_pass)
        arr = np.array(img, dtype=np.float64)
        seconds += time.perf_counter() - t0
        images.append(arr[..., :3])
    stack = np.stack(images)
    mean = stack.mean(axis=0)
    var = stack.var(axis=0, ddof=1) / passes
    # The time of one render of all the samples (what a user would run), for the efficiency.
    t0 = time.perf_counter()
    mi.render(scene, seed=seed0 + passes, spp=per_pass * passes)
    single = time.perf_counter() - t0
    return mean, var, seconds, single, per_pass * passes


# --------------------------------------------------------------------------------------------
# Statistics
# --------------------------------------------------------------------------------------------

def z_summary(a, va, b, vb):
    tot = va + vb
    # Pixel-channels whose standard error is at float-rounding level in both images (a constant
    # background, seen directly or through a box of zero density) are deterministic: a variance
    # of ~1e-16 there comes from summing identical f32 samples, not from noise, and a z against
    # it is meaningless. They must agree to 1e-6 relative instead (Mitsuba's RGB -> spectrum ->
    # RGB round trip and the pass averaging differ by ~1 ulp).
    scale = np.maximum(np.abs(a), np.abs(b))
    deterministic = np.sqrt(np.maximum(tot, 0.0)) <= 1e-6 * scale + 1e-12
    ok = (~deterministic) & np.isfinite(a) & np.isfinite(b) & np.isfinite(tot)
    z = np.zeros_like(a)
    z[ok] = (a[ok] - b[ok]) / np.sqrt(tot[ok])
    zt = z[ok]
    close = np.abs(a - b) <= 1e-6 * scale + 1e-12
    both_zero = (~ok) & close
    bias = []
    for c in range(3):
        okc = ok[..., c]
        num = (a[..., c][okc] - b[..., c][okc]).sum()
        den = math.sqrt(tot[..., c][okc].sum()) if okc.any() else 0.0
        bias.append(float(num / den) if den > 0 else 0.0)
    return {
        "tested": int(ok.sum()),
        "untested_equal": int(both_zero.sum()),
        "untested_different": int(((~ok) & ~close).sum()),
        "frac_above_2": float((np.abs(zt) > 2).mean()) if zt.size else 0.0,
        "frac_above_3": float((np.abs(zt) > 3).mean()) if zt.size else 0.0,
        "mean_z": float(zt.mean()) if zt.size else 0.0,
        "mean_z2": float((zt * zt).mean()) if zt.size else 0.0,
        "bias_z": bias,
    }


def closed_form(scene_path):
    """A scene's closed-form pixel value, declared in a comment line `# closed-form: R G B`
    (a number per channel, `-` where there is none): every pixel must have that expected value
    (a white furnace). None when the scene declares none."""
    with open(scene_path) as f:
        for line in f:
            m = re.match(r"#\s*closed-form:\s*(\S+)\s+(\S+)\s+(\S+)", line)
            if m:
                return [None if v == "-" else float(v) for v in m.groups()]
    return None


def closed_form_z(mean, var, expected):
    """Per channel: (image mean - expected) / its standard error sqrt(sum of pixel variances) / N."""
    out = []
    n = mean.shape[0] * mean.shape[1]
    for c in range(3):
        if expected[c] is None:
            out.append(None)
            continue
        se = math.sqrt(var[..., c].sum()) / n
        dev = float(mean[..., c].mean() - expected[c])
        out.append({"mean": float(mean[..., c].mean()), "se": se, "z": dev / se if se > 0 else (0.0 if dev == 0 else math.copysign(math.inf, dev))})
    return out


def velour_diff(velour, a, b):
    p = subprocess.run([velour, "diff", "--json", a, b], capture_output=True, text=True)
    if p.returncode != 0:
        return {"error": p.stderr.strip()}
    j = json.loads(p.stdout)
    return {"verdict": j.get("verdict"), "rmse": j.get("rmse"), "rel_mse": j.get("rel_mse")}


def machine():
    cpu = platform.processor() or ""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return {"cpu": cpu, "cores": os.cpu_count(), "python": platform.python_version(), "system": platform.platform()}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenes", nargs="+", help="velour scene files (TOML)")
    ap.add_argument("--velour", required=True, help="path of the velour binary")
    ap.add_argument("--out", required=True, help="output folder (EXRs, results.json, results.md)")
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--passes", type=int, default=16, help="Mitsuba passes for the batch variance")
    ap.add_argument("--width", type=int, default=96)
    ap.add_argument("--height", type=int, default=72)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--max-depth", type=int, default=0, help="override film.max_depth in both renderers")
    args = ap.parse_args()

    import drjit as dr
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    dr.set_thread_count(args.threads)
    os.makedirs(args.out, exist_ok=True)
    results = {"machine": machine(), "mitsuba": mi.__version__, "settings": vars(args), "scenes": []}
    for scene in args.scenes:
        name = os.path.splitext(os.path.basename(scene))[0]
        entry = {"scene": scene, "name": name}
        try:
            md, grids = translate(scene, args.width, args.height, args.max_depth, args.out)
        except Unsupported as e:
            entry["skipped"] = str(e)
            results["scenes"].append(entry)
            print(f"{name}: skipped: {e}", file=sys.stderr)
            continue
        entry["grids"] = []
        for g in grids:
            err = check_grid(g)
            entry["grids"].append({k: g[k] for k in ("object", "file", "grid", "res", "lo", "channels", "scale", "max")} | {"check_points": len(g["check"]), "check_max_abs_error": err})
            print(f"{name}: {g['object']}: {g['file']}:{g['grid']} -> {os.path.basename(g['vol'])} {g['res']} x {g['channels']}, "
                  f"gridvolume vs OpenVDB trilinear at {len(g['check'])} points: max |error| {err:.2e}", file=sys.stderr)
            if not err <= 1e-5 * max(1.0, g["max"]):
                raise RuntimeError(f"{name}: the translated grid of {g['object']} does not reproduce the VDB field (error {err})")
        vel_exr = os.path.join(args.out, f"{name}.velour.exr")
        mts_exr = os.path.join(args.out, f"{name}.mitsuba.exr")
        va_mean, va_var, va_t = render_velour(args.velour, scene, vel_exr, args.spp, args.width, args.height, args.threads, 1, args.max_depth)
        mb_mean, mb_var, mb_t_passes, mb_t, mb_spp = render_mitsuba(md, args.spp, args.passes, 1000)
        write_velour_layout_exr(mts_exr, mb_mean, mb_var, args.passes)
        z = z_summary(va_mean, va_var, mb_mean, mb_var)
        mse_v = float(va_var.mean())
        mse_m = float(mb_var.mean())
        eff_v = 1.0 / (mse_v * va_t) if mse_v > 0 and va_t > 0 else float("inf")
        eff_m = 1.0 / (mse_m * mb_t) if mse_m > 0 and mb_t > 0 else float("inf")
        entry.update({
            "spp": args.spp,
            "velour_seconds": va_t,
            "mitsuba_seconds": mb_t,
            "mitsuba_seconds_in_passes": mb_t_passes,
            "mitsuba_spp": mb_spp,
            "velour_mean": va_mean.mean(axis=(0, 1)).tolist(),
            "mitsuba_mean": mb_mean.mean(axis=(0, 1)).tolist(),
            "velour_mse": mse_v,
            "mitsuba_mse": mse_m,
            "efficiency_ratio": eff_v / eff_m if math.isfinite(eff_v) and math.isfinite(eff_m) else None,
            "z": z,
            "velour_diff": velour_diff(args.velour, vel_exr, mts_exr),
        })
        expected = closed_form(scene)
        if expected is not None:
            entry["closed_form"] = {"expected": expected, "velour": closed_form_z(va_mean, va_var, expected),
                                    "mitsuba": closed_form_z(mb_mean, mb_var, expected)}
        results["scenes"].append(entry)
        print(f"{name}: velour {va_t:.2f} s, mitsuba {mb_t:.2f} s, z>2 {100 * z['frac_above_2']:.2f}%, z>3 {100 * z['frac_above_3']:.2f}%, "
              f"bias z {['%.2f' % b for b in z['bias_z']]}, efficiency ratio {entry['efficiency_ratio']}", file=sys.stderr)
    with open(os.path.join(args.out, "results.json"), "w") as f:
        json.dump(results, f, indent=2)
    md = markdown(results)
    with open(os.path.join(args.out, "results.md"), "w") as f:
        f.write(md)
    print(md)


def markdown(results):
    m = results["machine"]
    st = results["settings"]
    lines = [
        f"Mitsuba {results['mitsuba']} (`scalar_rgb`, `volpathmis`) vs velour; {st['width']}x{st['height']}, "
        f"{st['spp']} spp each (Mitsuba in {st['passes']} passes), {st['threads']} threads; {m['cpu']}, {m['cores']} cores.",
        "",
        "| scene | velour s | Mitsuba s | mean RGB velour | mean RGB Mitsuba | \\|z\\|>2 (4.55%) | \\|z\\|>3 (0.27%) | mean z² | bias z (R, G, B) | velour diff | efficiency velour/Mitsuba |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for e in results["scenes"]:
        if "skipped" in e:
            lines.append(f"| {e['name']} | skipped: {e['skipped']} | | | | | | | | | |")
            continue
        z = e["z"]
        fmt = lambda v: ", ".join(f"{x:.4f}" for x in v)
        eff = e["efficiency_ratio"]
        lines.append(
            f"| {e['name']} | {e['velour_seconds']:.2f} | {e['mitsuba_seconds']:.2f} | {fmt(e['velour_mean'])} | {fmt(e['mitsuba_mean'])} | "
            f"{100 * z['frac_above_2']:.2f}% | {100 * z['frac_above_3']:.2f}% | {z['mean_z2']:.3f} | {', '.join(f'{b:+.2f}' for b in z['bias_z'])} | "
            f"{e['velour_diff'].get('verdict', e['velour_diff'].get('error'))} | {'n/a' if eff is None else f'{eff:.2f}'} |"
        )
    cf = [e for e in results["scenes"] if "closed_form" in e]
    if cf:
        lines += ["", "Closed forms (every pixel's expected value; image mean, its standard error and z = (mean − expected) / error):", "",
                  "| scene | channel | expected | velour mean ± se | velour z | Mitsuba mean ± se | Mitsuba z |", "|---|---|---|---|---|---|---|"]
        for e in cf:
            c = e["closed_form"]
            for k, ch in enumerate("RGB"):
                if c["expected"][k] is None:
                    continue
                v, m = c["velour"][k], c["mitsuba"][k]
                lines.append(f"| {e['name']} | {ch} | {c['expected'][k]:g} | {v['mean']:.5f} ± {v['se']:.5f} | {v['z']:+.2f} | "
                             f"{m['mean']:.5f} ± {m['se']:.5f} | {m['z']:+.2f} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
