#!/usr/bin/env python3
"""Render a velour scene with Blender Cycles (PyPI `bpy`), for the peer benchmarks.

Runs in a Python 3.11 environment with `bpy` 5.0.1, numpy and OpenEXR (tools/peers/run_best.sh
makes one); tools/peers/best.py calls it as a subprocess:

    python cycles_render.py SCENE.toml --out PREFIX --width W --height H --spp S
        [--passes K | --budget SECONDS] [--seed0 N] [--threads T] [--max-depth D]
        [--save-blend FILE.blend] [--check-only]

Translates the velour scene (docs/peers.md, "Cycles"), renders K passes of S samples per pixel
with seeds seed0, seed0 + 1, ... (or passes until the summed render time reaches --budget), and
writes PREFIX.npz with the pass images (`passes`, K x H x W x 3, float32, linear Rec.709) and
per-pass times. Prints one JSON object: Blender's version, the pass count, the samples per pixel,
the render times (Cycles' own `render_time` from the EXR metadata, without scene synchronisation)
and the synchronisation times. --check-only translates, saves the .blend if asked and exits.

Settings (docs/peers.md, "Settings per renderer"): Cycles on the CPU with T threads, null-scattering
volumes (`volume_biased = False`), every bounce limit 1000 (Cycles' `volume_bounces` defaults to
0), no denoising, no adaptive sampling, no clamping, no glossy filter, light threshold 0, a box
pixel filter one pixel wide, the standard view transform (the EXR is scene-linear anyway).
Everything else is Cycles' default (light tree, sampling pattern, volume MIS, its Russian
roulette), i.e. Cycles as a user would run it, unbiased.
"""

import argparse
import json
import math
import os
import struct
import sys
import tomllib

import numpy as np

from velour_transforms import object_matrix


class Unsupported(Exception):
    """A velour feature without a faithful Cycles equivalent in this translator."""


def colour(v, default):
    if v is None:
        v = default
    if isinstance(v, (int, float)):
        return [float(v)] * 3
    return [float(x) for x in v]


def read_ply(path):
    """Positions and triangles of a PLY file (ASCII or binary little endian; vertex x y z as the
    first float properties, faces as a uchar/int list). Normals and other properties are refused
    or ignored as velour would shade them: a file with normals is refused (this translator shades
    flat)."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    fmt = None
    elements = []
    for line in header:
        w = line.split()
        if not w:
            continue
        if w[0] == "format":
            fmt = w[1]
        elif w[0] == "element":
            elements.append([w[1], int(w[2]), []])
        elif w[0] == "property":
            elements[-1][2].append(w[1:])
    if fmt != "binary_little_endian":
        raise Unsupported(f"{path}: only binary little-endian PLY files are translated")
    sizes = {"char": "b", "uchar": "B", "short": "h", "ushort": "H", "int": "i", "uint": "I", "float": "f", "double": "d",
             "int8": "b", "uint8": "B", "int16": "h", "uint16": "H", "int32": "i", "uint32": "I", "float32": "f", "float64": "d"}
    pos = end
    verts, faces = None, None
    for name, count, props in elements:
        if name == "vertex":
            names = [p[-1] for p in props]
            if any(n in names for n in ("nx", "ny", "nz")):
                raise Unsupported(f"{path}: vertex normals (this translator shades flat)")
            if any(p[0] == "list" for p in props):
                raise Unsupported(f"{path}: list properties on vertices")
            rec = "<" + "".join(sizes[p[0]] for p in props)
            size = struct.calcsize(rec)
            raw = [struct.unpack_from(rec, data, pos + i * size) for i in range(count)]
            pos += count * size
            ix = [names.index(c) for c in "xyz"]
            verts = [(r[ix[0]], r[ix[1]], r[ix[2]]) for r in raw]
        elif name == "face":
            if len(props) != 1 or props[0][0] != "list":
                raise Unsupported(f"{path}: faces must have exactly one list property")
            cfmt, ifmt = "<" + sizes[props[0][1]], "<" + sizes[props[0][2]]
            cs, isz = struct.calcsize(cfmt), struct.calcsize(ifmt)
            faces = []
            for _ in range(count):
                (n,) = struct.unpack_from(cfmt, data, pos)
                pos += cs
                idx = struct.unpack_from("<" + sizes[props[0][2]] * n, data, pos)
                pos += n * isz
                for k in range(1, n - 1):  # fan triangulation
                    faces.append((idx[0], idx[k], idx[k + 1]))
        else:
            raise Unsupported(f"{path}: element {name!r}")
    return verts, faces


def single_albedo(i):
    return [min(max(a, 0.0), 1.0 - 1e-6) for a in colour(i.get("albedo"), 0.8)]


def hg_g(i):
    phase = i.get("phase", {})
    if phase.get("type", "hg") != "hg":
        raise Unsupported(f"phase type {phase.get('type')!r} (Cycles' Volume Coefficients node has one HG lobe)")
    return max(-0.99, min(0.99, float(phase.get("g", 0.0))))


def coefficients(i, name):
    """(sigma_a, sigma_s) per unit grid value of a velour interior, RGB."""
    if i.get("albedo_mode", "multiple") != "single" and i["type"] != "absorption":
        raise Unsupported(f"{name}: albedo_mode = \"multiple\"; comparisons use \"single\"")
    for k in ("base_albedo", "base_attenuation"):
        if k in i:
            raise Unsupported(f"{name}: combined interiors ({k})")
    tracking = i.get("tracking", {})
    if tracking.get("free_flight", "delta") != "delta" or tracking.get("transmittance", "residual") == "ray_march":
        raise Unsupported(f"{name}: ray marching is biased; comparisons use the unbiased trackers")
    att = colour(i.get("attenuation"), 1.0)
    density = float(i.get("density", 1.0))
    sigma_t = [density / a for a in att]
    if i["type"] == "absorption":
        return sigma_t, [0.0, 0.0, 0.0]
    a = single_albedo(i)
    return [t * (1.0 - x) for t, x in zip(sigma_t, a)], [t * x for t, x in zip(sigma_t, a)]


def build(scene_path, width, height, threads, max_depth):
    import bpy
    from mathutils import Matrix

    with open(scene_path, "rb") as f:
        s = tomllib.load(f)
    folder = os.path.dirname(os.path.abspath(scene_path))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device = "CPU"
    c.volume_biased = False
    depth = int(max_depth or s.get("film", {}).get("max_depth", 256))
    depth = min(depth, 1024)
    for k in ("max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces", "volume_bounces",
              "transparent_max_bounces"):
        setattr(c, k, depth)
    c.use_denoising = False
    c.use_adaptive_sampling = False
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    c.light_sampling_threshold = 0.0
    c.caustics_reflective = True
    c.caustics_refractive = True
    c.use_animated_seed = True  # the frame number changes the pattern as well (see main)
    c.pixel_filter_type = "BOX"
    c.filter_width = 1.0
    c.time_limit = 0.0
    scene.render.threads_mode = "FIXED"
    scene.render.threads = threads
    scene.render.resolution_x = width
    scene.render.resolution_y = height
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    scene.render.use_persistent_data = True
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    img = scene.render.image_settings
    img.file_format = "OPEN_EXR"
    img.color_mode = "RGB"
    img.color_depth = "32"
    img.exr_codec = "ZIP"
    scene.render.use_stamp = False

    # Camera: velour's pinhole, vertical field of view in degrees, pixel (0, 0) top-left.
    cam = s["camera"]
    if cam.get("type", "pinhole") != "pinhole" or float(cam.get("aperture_radius", 0.0)) > 0.0:
        raise Unsupported("thin-lens cameras are not translated")
    eye = np.array(cam["eye"], dtype=float)
    target = np.array(cam["look_at"], dtype=float)
    up = np.array(cam.get("up", [0, 1, 0]), dtype=float)
    fwd = target - eye
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, up)
    right /= np.linalg.norm(right)
    true_up = np.cross(right, fwd)
    cm = np.eye(4)
    cm[:3, 0], cm[:3, 1], cm[:3, 2], cm[:3, 3] = right, true_up, -fwd, eye  # Blender cameras look down -Z
    cdata = bpy.data.cameras.new("camera")
    cdata.type = "PERSP"
    cdata.sensor_fit = "VERTICAL"
    cdata.lens_unit = "FOV"
    cdata.angle_y = math.radians(float(cam.get("fov", 40.0)))
    cdata.clip_start = 1e-4
    cdata.clip_end = 1e6
    cobj = bpy.data.objects.new("camera", cdata)
    cobj.matrix_world = Matrix(cm.tolist())
    scene.collection.objects.link(cobj)
    scene.camera = cobj

    world = bpy.data.worlds.new("world")
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    bg.inputs["Strength"].default_value = 1.0
    scene.world = world
    for k, l in enumerate(s.get("light", [])):
        kind = l["type"]
        if kind == "environment":
            r = colour(l.get("radiance"), 1.0)
            bg.inputs["Color"].default_value = (*r, 1.0)
        elif kind == "distant":
            if float(l.get("angular_radius", 0.0)) > 0.0:
                raise Unsupported("distant lights with an angular radius are not translated")
            irr = colour(l.get("irradiance"), 3.0)
            strength = max(irr)
            ld = bpy.data.lights.new(f"sun{k}", type="SUN")
            ld.energy = strength  # a sun's strength is its irradiance, W/m^2
            ld.color = [x / strength for x in irr]
            ld.angle = 0.0
            lo = bpy.data.objects.new(f"sun{k}", ld)
            to_light = np.array(l["direction"], dtype=float)
            to_light /= np.linalg.norm(to_light)
            # A sun light shines along its local -Z: local +Z is the direction towards the light.
            z = to_light
            x = np.cross([0.0, 0.0, 1.0] if abs(z[2]) < 0.9 else [1.0, 0.0, 0.0], z)
            x /= np.linalg.norm(x)
            y = np.cross(z, x)
            lm = np.eye(4)
            lm[:3, 0], lm[:3, 1], lm[:3, 2] = x, y, z
            lo.matrix_world = Matrix(lm.tolist())
            scene.collection.objects.link(lo)
        else:
            raise Unsupported(f"light type {kind!r} is not translated to Cycles")

    priorities = {int(o.get("priority", 0)) for o in s.get("object", []) if o.get("interior")}
    if len(priorities) > 1:
        raise Unsupported("nested interiors with priorities")
    for k, o in enumerate(s.get("object", [])):
        name = o.get("name", f"object {k}")
        m, _ = object_matrix(o)
        interior = o.get("interior")
        mat = bpy.data.materials.new(f"material{k}")
        mat.use_nodes = True
        nt = mat.node_tree
        for n in list(nt.nodes):
            nt.nodes.remove(n)
        out = nt.nodes.new("ShaderNodeOutputMaterial")
        mat.cycles.volume_interpolation = "LINEAR"
        if interior is not None:
            sa, ss = coefficients(interior, name)
            vc = nt.nodes.new("ShaderNodeVolumeCoefficients")
            vc.phase = "HENYEY_GREENSTEIN"
            vc.inputs["Anisotropy"].default_value = hg_g(interior) if interior["type"] != "absorption" else 0.0
            vc.inputs["Emission Coefficients"].default_value = (0.0, 0.0, 0.0)
            if interior["type"] == "voxel":
                attr = nt.nodes.new("ShaderNodeAttribute")
                attr.attribute_type = "GEOMETRY"
                attr.attribute_name = interior.get("grid", "density")
                for sock, vec in (("Absorption Coefficients", sa), ("Scatter Coefficients", ss)):
                    mul = nt.nodes.new("ShaderNodeVectorMath")
                    mul.operation = "SCALE"
                    mul.inputs[0].default_value = vec
                    nt.links.new(attr.outputs["Fac"], mul.inputs["Scale"])
                    nt.links.new(mul.outputs["Vector"], vc.inputs[sock])
            elif interior["type"] in ("homogeneous", "absorption"):
                vc.inputs["Absorption Coefficients"].default_value = sa
                vc.inputs["Scatter Coefficients"].default_value = ss
            else:
                raise Unsupported(f"{name}: interior type {interior['type']!r}")
            nt.links.new(vc.outputs[0], out.inputs["Volume"])
        surf = o.get("surface")
        if surf is not None:
            kind = surf["type"]
            if "coat" in surf:
                raise Unsupported(f"{name}: coats")
            if kind == "dielectric":
                ior = float(surf.get("ior", 1.4))
                r = float(surf.get("roughness", 0.0))
                tint = colour(surf.get("tint"), 1.0)
                if tint != [1.0, 1.0, 1.0]:
                    raise Unsupported(f"{name}: tinted dielectric (Cycles' glass tints reflection too)")
                if abs(ior - 1.0) > 1e-6:
                    g = nt.nodes.new("ShaderNodeBsdfGlass")
                    dist = surf.get("distribution", "ggx")
                    g.distribution = "GGX" if dist == "ggx" else "BECKMANN"
                    # Cycles' glass roughness r gives alpha = r^2, as velour's; velour is smooth below
                    # alpha = 1e-3, Cycles' GGX with alpha < 1e-3 is also treated as a delta lobe.
                    g.inputs["Roughness"].default_value = r
                    g.inputs["IOR"].default_value = ior
                    g.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
                    nt.links.new(g.outputs[0], out.inputs["Surface"])
            elif kind == "lambertian":
                d = nt.nodes.new("ShaderNodeBsdfDiffuse")
                d.inputs["Color"].default_value = (*colour(surf.get("reflectance"), 0.8), 1.0)
                d.inputs["Roughness"].default_value = 0.0
                nt.links.new(d.outputs[0], out.inputs["Surface"])
            else:
                raise Unsupported(f"{name}: surface type {kind!r}")
        if o["shape"] == "bounds":
            if interior is None or interior["type"] != "voxel":
                raise Unsupported(f"{name}: bounds without a voxel interior")
            vol = bpy.data.volumes.new(name)
            vol.filepath = os.path.join(folder, interior["file"])
            vol.render.precision = "FULL"
            vol.render.clipping = 0.0
            vol.materials.append(mat)
            obj = bpy.data.objects.new(name, vol)
        elif o["shape"] == "mesh":
            verts, faces = read_ply(os.path.join(folder, o["file"]))
            me = bpy.data.meshes.new(name)
            me.from_pydata(verts, [], faces)
            me.update()
            for p in me.polygons:
                p.use_smooth = False
            me.materials.append(mat)
            obj = bpy.data.objects.new(name, me)
        else:
            raise Unsupported(f"{name}: shape {o['shape']!r} (Cycles has no analytic spheres)")
        obj.matrix_world = Matrix(m.tolist())
        scene.collection.objects.link(obj)
    return scene


def read_exr(path):
    import OpenEXR

    f = OpenEXR.File(path, separate_channels=True)
    ch = f.channels()
    header = dict(f.header())
    img = np.stack([np.array(ch[c].pixels, dtype=np.float32) for c in "RGB"], axis=-1)
    return img, header


def meta_seconds(header, key):
    """Cycles' per-view-layer timing metadata (`cycles.<layer>.<key>`), in seconds."""
    for k, v in header.items():
        if k.startswith("cycles.") and k.endswith("." + key):
            v = v.decode() if isinstance(v, bytes) else str(v)
            # "HH:MM:SS.ss" or "MM:SS.ss" or plain seconds
            parts = [float(p) for p in v.split(":")]
            sec = 0.0
            for p in parts:
                sec = sec * 60.0 + p
            return sec
    return None


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene")
    ap.add_argument("--out", required=True, help="output prefix (PREFIX.npz, PREFIX.pass.exr)")
    ap.add_argument("--width", type=int, default=256)
    ap.add_argument("--height", type=int, default=256)
    ap.add_argument("--spp", type=int, default=16, help="samples per pixel per pass")
    ap.add_argument("--passes", type=int, default=0)
    ap.add_argument("--budget", type=float, default=0.0, help="render passes until their render time sums to this")
    ap.add_argument("--max-passes", type=int, default=10000)
    ap.add_argument("--seed0", type=int, default=1)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--max-depth", type=int, default=0)
    ap.add_argument("--save-blend", default="")
    ap.add_argument("--check-only", action="store_true")
    args = ap.parse_args()
    import bpy

    try:
        scene = build(args.scene, args.width, args.height, args.threads, args.max_depth)
    except Unsupported as e:
        print(json.dumps({"skipped": str(e)}))
        return
    if args.save_blend:
        bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(args.save_blend))
    if args.check_only:
        print(json.dumps({"blender": bpy.app.version_string, "checked": True}))
        return
    passes, render_t, sync_t, total_t = [], [], [], []
    k = 0
    while True:
        if args.passes and k >= args.passes:
            break
        if not args.passes and (sum(render_t) >= args.budget or k >= args.max_passes):
            break
        # Persistent data keeps the synchronised scene between the passes. Each pass gets its own
        # seed and frame number (the animated seed hashes both) and its own file: two passes
        # written to one file name read back as the same image.
        scene.cycles.seed = args.seed0 + k
        scene.frame_set(k + 1)
        exr = os.path.abspath(f"{args.out}.pass{k}.exr")
        scene.render.filepath = exr
        scene.cycles.samples = args.spp
        bpy.ops.render.render(write_still=True)
        img, header = read_exr(exr)
        os.remove(exr)
        passes.append(img)
        rt = meta_seconds(header, "render_time")
        st = meta_seconds(header, "synchronization_time")
        tt = meta_seconds(header, "total_time")
        if rt is None:
            raise SystemExit(f"no Cycles render_time in the EXR metadata: {sorted(header)}")
        render_t.append(rt)
        sync_t.append(st)
        total_t.append(tt)
        k += 1
    np.savez(args.out + ".npz", passes=np.stack(passes), render_time=np.array(render_t), spp=args.spp)
    print(json.dumps({"blender": bpy.app.version_string, "passes": len(passes), "spp_per_pass": args.spp,
                      "render_time": render_t, "sync_time": sync_t, "total_time": total_t}))


if __name__ == "__main__":
    main()
