#!/usr/bin/env python3
"""Which voxel convention and pixel filter does each renderer use? Renders probes/grid_step.toml
with velour, Mitsuba (as translated) and Cycles and compares each transmittance profile (the mean
of the four image rows) with the pixel-averaged transmittance of three candidate fields:

  trilinear, 1-pixel box   the OpenVDB convention (voxel i at index point i) and velour's filter
  trilinear, 1.5-pixel box the same field seen through a wider pixel filter
  cubic B-spline           the same voxels reconstructed with a cubic B-spline (Cycles' "cubic")

    python grid_convention_probe.py --velour BIN [--cycles-python PY]

Runs in the Mitsuba environment of run_best.sh; needs generated/step.vdb (generate.sh makes it).
Prints the largest absolute difference of each renderer's profile from each candidate.
"""

import argparse
import json
import os
import subprocess
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import compare  # noqa: E402

SCENE = os.path.join(HERE, "probes", "grid_step.toml")
OPTICAL = 32.0 / 20.0  # depth in voxels x sigma_t per unit density


def sample(i):
    return 1.0 if -8 <= i <= -1 else 0.0


def trilinear(x):
    f = np.floor(x)
    t = x - f
    return np.array([(1 - tt) * sample(ff) + tt * sample(ff + 1) for ff, tt in zip(f, t)])


def bspline(x):
    out = []
    for xx in x:
        f = np.floor(xx)
        t = xx - f
        w = [(1 - t) ** 3 / 6, (3 * t ** 3 - 6 * t ** 2 + 4) / 6, (-3 * t ** 3 + 3 * t ** 2 + 3 * t + 1) / 6, t ** 3 / 6]
        out.append(sum(wk * sample(f - 1 + k) for k, wk in enumerate(w)))
    return np.array(out)


def profile(field, width):
    out = []
    for k in range(64):
        xs = -32 + k + 0.5 + ((np.arange(4000) + 0.5) / 4000 - 0.5) * width
        out.append(np.exp(-OPTICAL * field(xs)).mean())
    return np.array(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--velour", required=True)
    ap.add_argument("--cycles-python", default="")
    ap.add_argument("--work", default="out/peers-probe")
    args = ap.parse_args()
    os.makedirs(args.work, exist_ok=True)
    got = {}
    out = os.path.join(args.work, "grid_step.velour.exr")
    subprocess.run([args.velour, "render", SCENE, "--spp", "4096", "--threads", "2", "-q", "-o", out], check=True,
                   capture_output=True)
    got["velour"] = compare.read_velour_exr(out)[0][..., 0].mean(axis=0)
    import drjit as dr
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    dr.set_thread_count(2)
    d, _ = compare.translate(SCENE, 64, 4, 0, args.work)
    got["Mitsuba"] = np.array(mi.render(mi.load_dict(d), spp=4096), dtype=np.float64)[..., 0].mean(axis=0)
    if args.cycles_python:
        prefix = os.path.join(args.work, "grid_step.cycles")
        p = subprocess.run([args.cycles_python, os.path.join(HERE, "cycles_render.py"), SCENE, "--out", prefix, "--width", "64",
                            "--height", "4", "--spp", "1024", "--passes", "4"], capture_output=True, text=True, check=True)
        json.loads(p.stdout.strip().splitlines()[-1])
        got["Cycles"] = np.load(prefix + ".npz")["passes"].astype(np.float64).mean(axis=0)[..., 0].mean(axis=0)
    candidates = {"trilinear, 1-pixel box": profile(trilinear, 1.0), "trilinear, 1.5-pixel box": profile(trilinear, 1.5),
                  "cubic B-spline, 1-pixel box": profile(bspline, 1.0)}
    print("largest |pixel - candidate| over the 64 columns (transmittance)")
    print(f"{'':10s}" + "".join(f"{c:>30s}" for c in candidates))
    for name, prof in got.items():
        print(f"{name:10s}" + "".join(f"{np.abs(prof - c).max():30.4f}" for c in candidates.values()))


if __name__ == "__main__":
    main()
