#!/usr/bin/env python3
"""Race velour against the best available peers at equal render time, against a converged reference.

    python best.py --velour BIN --out DIR [--budget 60] [--rounds 3] [--reference-seconds 600]
                   [--width 256] [--height 256] [--threads 2] [--cycles-python PY] [--no-scalar]
                   [--seed-offset K] [--references-only | --translate-only] SCENE.toml ...
    python best.py --markdown-from DIR/best.json

Runs in the Mitsuba environment (mitsuba, numpy, OpenEXR; tools/peers/run_best.sh makes it). For
each scene (a velour TOML file; docs/peers.md, "The benchmark race"):

  1. Translation: the scene is translated to Mitsuba 3 (compare.py's translator; written out as
     Mitsuba XML, DIR/<scene>.mitsuba.xml) and to Blender Cycles (cycles_render.py in the bpy
     environment; saved as DIR/<scene>.blend). Grids are checked against the OpenVDB lookup.
  2. Reference: velour `reference --time R` (a seed of its own; reused from DIR/references/ when a
     reference of the same scene text and resolution exists there; a scene may name another
     scene's reference with a comment line `# reference: OTHER.toml`, for resamplings of the same
     field). Its per-pixel variance of the mean is var_ref.
  3. Race: every renderer gets the same render-time budget B, spent in `--rounds` interleaved
     rounds (velour, Mitsuba LLVM, Cycles, Mitsuba scalar, then again, each round starting one
     renderer later), so that load changes on a shared machine hit all of them alike. velour
     renders `--spp n` per round (n brings its total to k B / R seconds after round k, at the
     speed measured so far); Mitsuba renders passes of a fixed spp (`mi.render`, timed per call, after
     one untimed warm-up pass that compiles its kernels); Cycles renders passes (its own
     `render_time`, without scene synchronisation). Each renderer's image is the sample-weighted
     mean of its rounds or passes; its per-pixel variance of the mean comes from velour's own
     estimate (combined over rounds) or, for the peers, from the spread of the passes (batch
     means).
  4. Error: MSE_ref = mean((image - ref)^2) - mean(var_ref) over pixels and channels, and
     MSE_var = mean(variance of the pixel mean) (the noise alone). Efficiency = 1 / (MSE x seconds).
     Headline: MSE_ref when the renderer agrees with the reference (aggregate bias |z| < 4 in
     every channel), else MSE_var and the row is flagged (the renderers' models differ, which is
     not noise; the bias is reported).
  5. Agreement: per pixel and channel z = (a - ref) / sqrt(var_a + var_ref): fractions beyond 2
     and 3, mean z^2, over all tested pixel-channels and over those where both variance estimates
     are non-zero (rare-event pixels, where one renderer saw no event and so estimates a zero
     variance, are where the all-pixel numbers blow up), and the aggregate bias z per channel.
     Pairwise velour-vs-peer the same way (as compare.py does). The tables show the per-pixel
     fractions of the pairwise test: against the reference, z is normalised almost entirely by
     the raced image's own variance estimate, which is correlated with its error at low sample
     counts of a skewed integrand, so those fractions run high for every renderer.
  6. Throughput: samples/s for every renderer; rays/s, density lookups/s and lookups per real
     collision for velour (from its render summary); the peers do not report those.

Mitsuba runs `llvm_ad_rgb` (libLLVM 19 through DRJIT_LIBLLVM_PATH) with its default Russian
roulette (rr_depth 5): `volpath` for grey media, `volpathmis` for chromatic ones. volpathmis with
roulette is biased (docs/peers.md, "Mitsuba's Russian roulette"), so chromatic scenes also run
volpathmis without roulette, and the headline takes the unbiased one. `scalar_rgb` runs the
headline configuration as a second column.

Writes DIR/best.json and DIR/best.md (the tables for docs/BENCHMARKS-peers.md).
"""

import argparse
import hashlib
import json
import math
import os
import re
import subprocess
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import compare  # noqa: E402  (the Mitsuba translator and the z statistics)

HERE = os.path.dirname(os.path.abspath(__file__))
BIAS_Z_LIMIT = 4.0
SEED_OFFSET = 0  # --seed-offset: a repeated race with independent noise


# --------------------------------------------------------------------------------------------
# Helpers
# --------------------------------------------------------------------------------------------

def load_average():
    with open("/proc/loadavg") as f:
        return [float(x) for x in f.read().split()[:3]]


def scene_text_key(scene, width, height):
    with open(scene, "rb") as f:
        h = hashlib.sha256(f.read()).hexdigest()[:16]
    return f"{os.path.splitext(os.path.basename(scene))[0]}.{width}x{height}.{h}"


def reference_scene(scene):
    """The scene whose reference this scene uses (`# reference: OTHER.toml`), or itself."""
    with open(scene) as f:
        for line in f:
            m = re.match(r"#\s*reference:\s*(\S+)", line)
            if m:
                return os.path.join(os.path.dirname(scene), m.group(1))
    return scene


def is_grey(scene):
    """Whether every interior of the scene has grey extinction and albedo (Mitsuba: volpath)."""
    import tomllib

    with open(scene, "rb") as f:
        s = tomllib.load(f)
    for o in s.get("object", []):
        i = o.get("interior")
        if not i:
            continue
        for k in ("attenuation", "albedo"):
            v = i.get(k)
            if isinstance(v, list) and len(set(float(x) for x in v)) > 1:
                return False
    return True


VELOUR_STATS = {
    "seconds": r"time ([0-9.]+) s",
    "samples": r"\| (\d+) samples",
    "rays": r"\| (\d+) rays",
    "free_flight_lookups": r"(\d+) free-flight lookups",
    "real_collisions": r"\((\d+) real \+",
    "null_collisions": r"\+ (\d+) null collisions",
    "transmittance_lookups": r"(\d+) transmittance lookups",
}


def parse_velour(stdout):
    out = {}
    for k, rx in VELOUR_STATS.items():
        m = re.search(rx, stdout)
        out[k] = float(m.group(1)) if m else None
    return out


def velour_cmd(velour, kind, scene, out, width, height, threads, seed, extra):
    return [velour, kind, scene, "--width", str(width), "--height", str(height), "--threads", str(threads),
            "--seed", str(seed), "-q", "-o", out, "--checkpoint", "1000000"] + extra


def run_velour(velour, kind, scene, out, width, height, threads, seed, extra):
    p = subprocess.run(velour_cmd(velour, kind, scene, out, width, height, threads, seed, extra), capture_output=True,
                       text=True)
    if p.returncode != 0:
        raise RuntimeError(f"velour {kind} failed: {p.stderr.strip()}")
    stats = parse_velour(p.stdout)
    mean, var, n = compare.read_velour_exr(out)
    return mean, var, n, stats


def stats_of(mean, var, ref, var_ref):
    """MSE against the reference (its variance subtracted), MSE from the variance alone, and
    agreement statistics against the reference."""
    err = mean - ref
    mse_ref = float((err * err).mean() - var_ref.mean())
    mse_var = float(var.mean())
    z = compare.z_summary(mean, var, ref, var_ref)
    z["both_nonzero"] = both_nonzero(mean, var, ref, var_ref)
    return mse_ref, mse_var, z


def both_nonzero(a, va, b, vb):
    scale = np.maximum(np.abs(a), np.abs(b))
    ok = (np.sqrt(va) > 1e-6 * scale + 1e-12) & (np.sqrt(vb) > 1e-6 * scale + 1e-12)
    if not ok.any():
        return {"tested": 0}
    z = (a[ok] - b[ok]) / np.sqrt(va[ok] + vb[ok])
    return {"tested": int(ok.sum()), "frac_above_2": float((np.abs(z) > 2).mean()),
            "frac_above_3": float((np.abs(z) > 3).mean()), "mean_z2": float((z * z).mean())}


# --------------------------------------------------------------------------------------------
# Renderers
# --------------------------------------------------------------------------------------------

class Velour:
    name = "velour"

    def __init__(self, binary, scene, width, height, threads, workdir, key):
        self.binary, self.scene, self.width, self.height, self.threads = binary, scene, width, height, threads
        self.workdir, self.key = workdir, key
        self.rounds = []
        self.rate = None  # samples per second, from calibration and each round

    def calibrate(self):
        out = os.path.join(self.workdir, f"{self.key}.velour.calibrate.exr")
        _, _, _, st = run_velour(self.binary, "render", self.scene, out, self.width, self.height, self.threads, 999,
                                 ["--spp", "2"])
        self.rate = st["samples"] / st["seconds"]
        os.remove(out)
        return st

    def round(self, budget, k):
        # Aim at the cumulative budget (k + 1) x budget, so that a round slowed down or sped up by
        # the machine's load is made up for in the next one.
        pixels = self.width * self.height
        spent = sum(r[3]["seconds"] for r in self.rounds)
        spp = max(1, int(round(max(0.25 * budget, (k + 1) * budget - spent) * self.rate / pixels)))
        out = os.path.join(self.workdir, f"{self.key}.velour.round{k}.exr")
        mean, var, n, st = run_velour(self.binary, "render", self.scene, out, self.width, self.height, self.threads,
                                      1000 + SEED_OFFSET + k, ["--spp", str(spp)])
        self.rate = st["samples"] / st["seconds"]
        self.rounds.append((mean, var, spp, st))
        return st["seconds"]

    def result(self):
        n = np.array([r[2] for r in self.rounds], dtype=float)
        N = n.sum()
        mean = sum(r[0] * r[2] for r in self.rounds) / N
        var = sum(r[1] * r[2] ** 2 for r in self.rounds) / N ** 2
        stats = {k: sum(r[3][k] for r in self.rounds) if all(r[3][k] is not None for r in self.rounds) else None
                 for k in VELOUR_STATS}
        return mean, var, int(N), stats["seconds"], stats


class Mitsuba:
    def __init__(self, variant, integrator, rr_depth, scene, width, height, workdir, label):
        import mitsuba as mi

        self.variant, self.integrator, self.rr_depth, self.label = variant, integrator, rr_depth, label
        self.name = label
        mi.set_variant(variant)
        # Translated under this variant: the transforms in the dictionary are variant types.
        d, _ = compare.translate(scene, width, height, 0, workdir)
        d["integrator"] = {"type": integrator, "max_depth": d["integrator"]["max_depth"]}
        if rr_depth is not None:
            d["integrator"]["rr_depth"] = rr_depth
        self.dict = d
        self.width, self.height = width, height
        self.scene = None
        self.passes, self.times = [], []
        self.spp = None
        self.seed = 5000 + SEED_OFFSET

    def _load(self):
        import mitsuba as mi

        mi.set_variant(self.variant)
        if self.scene is None:
            d = dict(self.dict)
            d["sensor"] = dict(d["sensor"])
            d["sensor"]["sampler"] = {"type": "independent", "sample_count": 1}
            self.scene = mi.load_dict(d)
        return mi

    def _render(self, spp):
        mi = self._load()
        self.seed += 1
        t0 = time.perf_counter()
        img = mi.render(self.scene, seed=self.seed, spp=spp)
        arr = np.array(img, dtype=np.float64)[..., :3]
        return arr, time.perf_counter() - t0

    def calibrate(self, pass_seconds):
        """An untimed warm-up pass (kernel compilation, memory) and a timed one fix the pass spp."""
        self._render(2)
        _, t2 = self._render(2)
        self.spp = int(max(1, min(256, round(pass_seconds / (t2 / 2)))))
        return {"seconds_2spp": t2, "pass_spp": self.spp}

    def round(self, budget, k):
        spent = 0.0
        while spent < budget:
            arr, t = self._render(self.spp)
            self.passes.append(arr)
            self.times.append(t)
            spent += t
        return spent

    def result(self):
        stack = np.stack(self.passes)
        K = stack.shape[0]
        return stack.mean(0), stack.var(0, ddof=1) / K, K * self.spp, float(sum(self.times)), {"passes": K,
                                                                                             "pass_spp": self.spp}

    def free(self):
        self.scene = None


class Cycles:
    name = "Cycles"

    def __init__(self, python, scene, width, height, threads, workdir, key):
        self.python, self.scene, self.width, self.height, self.threads = python, scene, width, height, threads
        self.workdir, self.key = workdir, key
        self.passes, self.times = [], []
        self.spp = None
        self.seed0 = 100 + SEED_OFFSET
        self.version = None

    def _run(self, extra):
        out = os.path.join(self.workdir, f"{self.key}.cycles")
        cmd = [self.python, os.path.join(HERE, "cycles_render.py"), self.scene, "--out", out, "--width", str(self.width),
               "--height", str(self.height), "--threads", str(self.threads)] + extra
        p = subprocess.run(cmd, capture_output=True, text=True)
        if p.returncode != 0:
            raise RuntimeError(f"cycles_render.py failed: {p.stderr.strip()[-2000:]}")
        info = json.loads(p.stdout.strip().splitlines()[-1])
        return out, info

    def translate(self, blend):
        _, info = self._run(["--check-only", "--save-blend", blend])
        return info

    def calibrate(self, pass_seconds):
        out, info = self._run(["--spp", "1", "--passes", "2", "--seed0", "1"])
        self.version = info.get("blender")
        t = max(0.01, min(info["render_time"]))
        self.spp = int(max(1, min(1024, round(pass_seconds / t))))
        return {"seconds_1spp": t, "pass_spp": self.spp}

    def round(self, budget, k):
        out, info = self._run(["--spp", str(self.spp), "--budget", str(budget), "--seed0", str(self.seed0)])
        self.seed0 += info["passes"]
        z = np.load(out + ".npz")
        self.passes += [p.astype(np.float64) for p in z["passes"]]
        self.times += list(info["render_time"])
        return float(sum(info["render_time"]))

    def result(self):
        stack = np.stack(self.passes)
        K = stack.shape[0]
        return stack.mean(0), stack.var(0, ddof=1) / K, K * self.spp, float(sum(self.times)), {"passes": K,
                                                                                             "pass_spp": self.spp}


# --------------------------------------------------------------------------------------------
# The race
# --------------------------------------------------------------------------------------------

def write_mitsuba_xml(scene_dict, path):
    import mitsuba as mi

    try:
        config = mi.parser.ParserConfig(mi.variant())
        state = mi.parser.parse_dict(config, scene_dict)
        mi.parser.write_file(state, path)
        return None
    except Exception as e:  # the XML is a by-product; the race does not depend on it
        return str(e)


def reference(args, scene, refdir):
    ref_scene = reference_scene(scene)
    key = scene_text_key(ref_scene, args.width, args.height)
    path = os.path.join(refdir, key + ".exr")
    meta = os.path.join(refdir, key + ".json")
    if os.path.exists(path) and os.path.exists(meta):
        with open(meta) as f:
            info = json.load(f)
        info["reused"] = True
    else:
        t0 = time.time()
        _, _, _, st = run_velour(args.velour, "reference", ref_scene, path, args.width, args.height, args.threads,
                                 777001, ["--time", str(args.reference_seconds)])
        info = {"scene": ref_scene, "seconds": st["seconds"], "samples": st["samples"], "velour": args.velour_version,
                "wall": time.time() - t0, "load_after": load_average()}
        with open(meta, "w") as f:
            json.dump(info, f, indent=2)
        info["reused"] = False
    mean, var, n = compare.read_velour_exr(path)
    info["spp"] = float(n.mean())
    info["path"] = path
    return mean, var, info


def race(args, scene):
    import mitsuba as mi

    name = os.path.splitext(os.path.basename(scene))[0]
    entry = {"scene": scene, "name": name, "load_before": load_average(), "start": time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime())}
    workdir = os.path.join(args.out, "work")
    refdir = os.path.join(args.out, "references")
    os.makedirs(workdir, exist_ok=True)
    mi.set_variant(args.variant)
    try:
        md, grids = compare.translate(scene, args.width, args.height, 0, workdir)
    except compare.Unsupported as e:
        entry["skipped"] = f"Mitsuba: {e}"
        return entry
    entry["grids"] = []
    for g in grids:
        err = compare.check_grid(g)
        entry["grids"].append({"file": g["file"], "res": g["res"], "channels": g["channels"], "check_max_abs_error": err})
        if not err <= 1e-5 * max(1.0, g["max"]):
            raise RuntimeError(f"{name}: the translated grid does not reproduce the VDB field (error {err})")
    grey = is_grey(scene)
    integrator = "volpath" if grey else "volpathmis"
    depth = int(md["integrator"]["max_depth"])
    # The Mitsuba file carries the headline configuration: the default roulette for volpath
    # (grey media), none for volpathmis (chromatic; its roulette is biased).
    md["integrator"] = {"type": integrator, "max_depth": depth} | ({} if grey else {"rr_depth": depth})
    entry["mitsuba_xml"] = os.path.join(args.out, f"{name}.mitsuba.xml")
    xml_error = write_mitsuba_xml(md, entry["mitsuba_xml"])
    if xml_error:
        entry["mitsuba_xml_error"] = xml_error
    if args.translate_only:
        if args.cycles_python:
            cyc = Cycles(args.cycles_python, scene, args.width, args.height, args.threads, workdir, name)
            entry["cycles"] = cyc.translate(os.path.join(args.out, f"{name}.blend"))
        print(f"{name}: wrote {entry['mitsuba_xml']}" + (f" and {name}.blend" if args.cycles_python else ""), file=sys.stderr)
        return entry

    os.makedirs(refdir, exist_ok=True)
    ref, var_ref, rinfo = reference(args, scene, refdir)
    entry["reference"] = rinfo
    if args.references_only:
        return entry
    print(f"{name}: reference {rinfo['spp']:.0f} spp ({'reused' if rinfo['reused'] else 'rendered'})", file=sys.stderr)

    renderers = [Velour(args.velour, scene, args.width, args.height, args.threads, workdir, name)]
    renderers.append(Mitsuba(args.variant, integrator, None, scene, args.width, args.height, workdir,
                             f"Mitsuba {args.variant} {integrator}, roulette"))
    if not grey:
        renderers.append(Mitsuba(args.variant, integrator, depth, scene, args.width, args.height, workdir,
                                 f"Mitsuba {args.variant} {integrator}, no roulette"))
    cycles = None
    if args.cycles_python:
        cycles = Cycles(args.cycles_python, scene, args.width, args.height, args.threads, workdir, name)
        info = cycles.translate(os.path.join(args.out, f"{name}.blend"))
        if "skipped" in info:
            entry["cycles_skipped"] = info["skipped"]
            cycles = None
        else:
            renderers.append(cycles)
    if args.scalar:
        scalar_rr = None if grey else depth
        renderers.append(Mitsuba("scalar_rgb", integrator, scalar_rr, scene, args.width, args.height, workdir,
                                 f"Mitsuba scalar_rgb {integrator}" + (", roulette" if grey else ", no roulette")))
    pass_seconds = args.budget / args.rounds / args.passes_per_round
    entry["calibration"] = {}
    for r in renderers:
        entry["calibration"][r.name] = r.calibrate() if isinstance(r, Velour) else r.calibrate(pass_seconds)
    per_round = args.budget / args.rounds
    for k in range(args.rounds):
        # Each round starts with the next renderer, so that none is always first after the
        # (untimed) work between rounds.
        start = k % len(renderers)
        for r in renderers[start:] + renderers[:start]:
            t = r.round(per_round, k)
            print(f"{name}: round {k + 1}/{args.rounds}: {r.name} {t:.1f} s", file=sys.stderr)
    entry["load_after"] = load_average()
    entry["end"] = time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime())

    results = []
    velour_mean = velour_var = None
    for r in renderers:
        mean, var, spp, seconds, extra = r.result()
        mse_ref, mse_var, z = stats_of(mean, var, ref, var_ref)
        biased = any(abs(b) >= BIAS_Z_LIMIT for b in z["bias_z"])
        mse = mse_var if biased else mse_ref
        row = {"renderer": r.name, "spp": spp, "seconds": seconds, "mse_ref": mse_ref, "mse_var": mse_var,
               "headline_mse": "variance" if biased else "reference", "efficiency": 1.0 / (mse * seconds) if mse > 0 else None,
               "efficiency_ref": 1.0 / (mse_ref * seconds) if mse_ref > 0 else None,
               "efficiency_var": 1.0 / (mse_var * seconds) if mse_var > 0 else None,
               "samples_per_second": spp * args.width * args.height / seconds, "z_vs_reference": z,
               "mean_rgb": mean.mean(axis=(0, 1)).tolist()} | extra
        if isinstance(r, Mitsuba):
            row["unbiased_config"] = r.rr_depth is not None or r.integrator == "volpath"
        if isinstance(r, Velour):
            velour_mean, velour_var = mean, var
            st = extra
            row["rays_per_second"] = st["rays"] / seconds if st.get("rays") else None
            lookups = (st.get("free_flight_lookups") or 0) + (st.get("transmittance_lookups") or 0)
            row["density_lookups_per_second"] = lookups / seconds if lookups else None
            row["lookups_per_real_collision"] = lookups / st["real_collisions"] if st.get("real_collisions") else None
            row["free_flight_lookups_per_real_collision"] = (st["free_flight_lookups"] / st["real_collisions"]
                                                             if st.get("real_collisions") else None)
        else:
            row["z_vs_velour"] = compare.z_summary(velour_mean, velour_var, mean, var)
            row["z_vs_velour"]["both_nonzero"] = both_nonzero(velour_mean, velour_var, mean, var)
        path = os.path.join(args.out, f"{name}.{r.name.replace(' ', '_').replace(',', '')}.exr")
        compare.write_velour_layout_exr(path, mean, var, spp)
        results.append(row)
        if isinstance(r, Mitsuba):
            r.free()
    entry["integrator"] = integrator
    entry["results"] = results
    v = results[0]
    for row in results[1:]:
        row["velour_over_peer"] = (v["efficiency"] / row["efficiency"]) if v["efficiency"] and row["efficiency"] else None
    return entry


def fmt(x, spec):
    return "n/a" if x is None else format(x, spec)


def markdown(results):
    st = results["settings"]
    lines = [f"velour {results['velour_version']} vs Mitsuba {results['mitsuba']} and {results.get('cycles', 'no Cycles')}; "
             f"{st['width']}x{st['height']}, {st['budget']:g} s of render time each in {st['rounds']} interleaved rounds, "
             f"{st['threads']} threads; {results['machine']['cpu']}, {results['machine']['cores']} cores.", ""]
    lines += ["| scene | renderer | spp | s | MSE vs reference | MSE (variance) | bias z vs reference (R, G, B) | "
              "bias z vs velour | \\|z\\|>2, \\|z\\|>3 vs velour (4.55 %, 0.27 %) | efficiency 1/(MSE·s) | velour ÷ this |",
              "|---|---|---|---|---|---|---|---|---|---|---|"]
    for e in results["scenes"]:
        if "skipped" in e:
            lines.append(f"| {e['name']} | skipped: {e['skipped']} | | | | | | | | |")
            continue
        for r in e["results"]:
            z = r["z_vs_reference"]
            flag = "" if r["headline_mse"] == "reference" else " (noise only: biased vs reference)"
            if r.get("unbiased_config") is False:
                flag += " (biased estimator: not a headline)"
            if "z_vs_velour" in r:
                zv = r["z_vs_velour"]
                bn = zv["both_nonzero"]
                pair = (f"{', '.join(f'{b:+.1f}' for b in zv['bias_z'])} | "
                        f"{100 * bn.get('frac_above_2', 0):.2f}%, {100 * bn.get('frac_above_3', 0):.2f}%")
            else:
                pair = "– | –"
            lines.append(
                f"| {e['name']} | {r['renderer']} | {r['spp']} | {r['seconds']:.1f} | {r['mse_ref']:.3e} | {r['mse_var']:.3e} | "
                f"{', '.join(f'{b:+.1f}' for b in z['bias_z'])} | {pair} | "
                f"{fmt(r['efficiency'], '.4g')}{flag} | {fmt(r.get('velour_over_peer'), '.2f')} |")
    lines += ["", "Throughput (the same runs):", "",
              "| scene | renderer | samples/s | rays/s | density lookups/s | lookups per real collision |", "|---|---|---|---|---|---|"]
    for e in results["scenes"]:
        if "skipped" in e:
            continue
        for r in e["results"]:
            if r["renderer"] == "velour" and r.get("density_lookups_per_second") is None:
                lines.append(f"| {e['name']} | velour | {r['samples_per_second']:.4g} | {fmt(r['rays_per_second'], '.4g')} | "
                             "none (homogeneous medium) | none |")
            elif r["renderer"] == "velour":
                lines.append(f"| {e['name']} | velour | {r['samples_per_second']:.4g} | {fmt(r['rays_per_second'], '.4g')} | "
                             f"{fmt(r['density_lookups_per_second'], '.4g')} | {fmt(r['lookups_per_real_collision'], '.2f')} "
                             f"({fmt(r['free_flight_lookups_per_real_collision'], '.2f')} in free flights) |")
            else:
                lines.append(f"| {e['name']} | {r['renderer']} | {r['samples_per_second']:.4g} | not reported | not reported | not reported |")
    return "\n".join(lines) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenes", nargs="*")
    ap.add_argument("--velour", default="")
    ap.add_argument("--markdown-from", default="", help="print the tables of an earlier run's best.json and stop")
    ap.add_argument("--velour-version", default="")
    ap.add_argument("--out", default="")
    ap.add_argument("--width", type=int, default=256)
    ap.add_argument("--height", type=int, default=256)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--budget", type=float, default=60.0, help="render seconds per renderer and scene")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--passes-per-round", type=int, default=8, help="target peer passes per round (batch variance)")
    ap.add_argument("--reference-seconds", type=float, default=600.0)
    ap.add_argument("--variant", default="llvm_ad_rgb")
    ap.add_argument("--cycles-python", default="", help="Python with bpy 5.0.1 (empty: no Cycles)")
    ap.add_argument("--no-scalar", dest="scalar", action="store_false")
    ap.add_argument("--seed-offset", type=int, default=0,
                    help="added to every renderer's seeds (repeat a race with independent noise)")
    ap.add_argument("--references-only", action="store_true", help="render (or reuse) the references and stop")
    ap.add_argument("--translate-only", action="store_true",
                    help="write the Mitsuba XML and the Cycles .blend of each scene to --out and stop")
    args = ap.parse_args()
    if args.markdown_from:
        with open(args.markdown_from) as f:
            print(markdown(json.load(f)), end="")
        return
    if not args.velour or not args.out or not args.scenes:
        ap.error("--velour, --out and at least one scene are needed")

    import drjit as dr
    import mitsuba as mi

    global SEED_OFFSET
    SEED_OFFSET = 100000 * args.seed_offset
    mi.set_variant(args.variant)
    dr.set_thread_count(args.threads)
    os.makedirs(args.out, exist_ok=True)
    results = {"machine": compare.machine(), "mitsuba": mi.__version__, "velour_version": args.velour_version,
               "settings": {k: v for k, v in vars(args).items() if k != "scenes"}, "scenes": []}
    for scene in args.scenes:
        entry = race(args, scene)
        results["scenes"].append(entry)
        for r in entry.get("results", []):
            if r["renderer"] == "Cycles":
                results["cycles"] = f"Cycles (Blender {r.get('blender', '5.0.1')})"
        if args.translate_only or args.references_only:
            continue
        with open(os.path.join(args.out, "best.json"), "w") as f:
            json.dump(results, f, indent=2)
    if args.translate_only or args.references_only:
        return
    md = markdown(results)
    with open(os.path.join(args.out, "best.md"), "w") as f:
        f.write(md)
    print(md)


if __name__ == "__main__":
    main()
