#!/usr/bin/env python3
"""Render one small scene with velour, Mitsuba (LLVM, no roulette) and Cycles and print the mean
of the pixels that see the object, with its standard error (the evidence behind the findings in
docs/BENCHMARKS-peers.md; the probe scenes are in tools/peers/probes/).

    python probe.py SCENE.toml --velour BIN --cycles-python PY [--size 64] [--velour-spp 1024]
                    [--passes 16] [--pass-spp 64] [--integrator volpathmis] [--variant llvm_ad_rgb]

Runs in the Mitsuba environment of tools/peers/run_best.sh (DRJIT_LIBLLVM_PATH set for LLVM).
"Object pixels" are those where velour's variance of the mean is non-zero in some channel (the
background is exact in every renderer). The standard error of the image mean is
sqrt(sum of pixel variances) / pixels (velour: its own estimate; the peers: batch means over the
passes). Also prints the aggregate bias z of each peer against velour over all pixels.
"""

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import compare  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene")
    ap.add_argument("--velour", required=True)
    ap.add_argument("--cycles-python", default="")
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--velour-spp", type=int, default=1024)
    ap.add_argument("--passes", type=int, default=16)
    ap.add_argument("--pass-spp", type=int, default=64)
    ap.add_argument("--integrator", default="volpathmis")
    ap.add_argument("--variant", default="llvm_ad_rgb")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--work", default="out/peers-probe")
    args = ap.parse_args()
    import drjit as dr
    import mitsuba as mi

    os.makedirs(args.work, exist_ok=True)
    name = os.path.splitext(os.path.basename(args.scene))[0]
    n = args.size
    images = {}
    out = os.path.join(args.work, f"{name}.velour.exr")
    subprocess.run([args.velour, "render", args.scene, "--spp", str(args.velour_spp), "--width", str(n), "--height", str(n),
                    "--threads", str(args.threads), "--seed", "7", "-q", "-o", out], check=True, capture_output=True)
    m, v, _ = compare.read_velour_exr(out)
    images["velour"] = (m, v)

    mi.set_variant(args.variant)
    dr.set_thread_count(args.threads)
    d, _ = compare.translate(args.scene, n, n, 0, args.work)
    depth = d["integrator"]["max_depth"]
    d["integrator"] = {"type": args.integrator, "max_depth": depth, "rr_depth": depth}
    d["sensor"]["sampler"] = {"type": "independent", "sample_count": args.pass_spp}
    scene = mi.load_dict(d)
    passes = [np.array(mi.render(scene, seed=100 + k, spp=args.pass_spp), dtype=np.float64)[..., :3] for k in range(args.passes)]
    stack = np.stack(passes)
    images[f"Mitsuba {args.variant} {args.integrator}, no roulette"] = (stack.mean(0), stack.var(0, ddof=1) / len(passes))

    if args.cycles_python:
        prefix = os.path.join(args.work, f"{name}.cycles")
        p = subprocess.run([args.cycles_python, os.path.join(HERE, "cycles_render.py"), args.scene, "--out", prefix,
                            "--width", str(n), "--height", str(n), "--spp", str(args.pass_spp), "--passes", str(args.passes),
                            "--threads", str(args.threads)], capture_output=True, text=True, check=True)
        info = json.loads(p.stdout.strip().splitlines()[-1])
        if "skipped" in info:
            print(f"Cycles skipped: {info['skipped']}")
        else:
            stack = np.load(prefix + ".npz")["passes"].astype(np.float64)
            images[f"Cycles (Blender {info['blender']})"] = (stack.mean(0), stack.var(0, ddof=1) / len(stack))

    vm, vv = images["velour"]
    obj = vv.max(axis=2) > 0
    print(f"{args.scene}: {n}x{n}, {obj.sum()} object pixels; mean +- standard error (R, G, B)")
    for label, (m, v) in images.items():
        mu = m[obj].mean(axis=0)
        se = np.sqrt(v[obj].sum(axis=0)) / obj.sum()
        line = f"  {label:48s} " + ", ".join(f"{a:.5f} +- {b:.5f}" for a, b in zip(mu, se))
        if label != "velour":
            z = compare.z_summary(vm, vv, m, v)
            line += "   bias z vs velour " + ", ".join(f"{b:+.1f}" for b in z["bias_z"])
        print(line)


if __name__ == "__main__":
    main()
