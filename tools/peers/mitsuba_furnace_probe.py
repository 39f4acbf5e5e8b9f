#!/usr/bin/env python3
"""Mitsuba alone on a white-furnace peer scene, under integrator variants, against the closed form.

    ~/.cache/velour-peers/venv/bin/python tools/peers/mitsuba_furnace_probe.py \
        tools/peers/scenes/grid_furnace.toml [--spp 1024] [--width 48] [--height 36] [--threads 2]

Translates the scene with compare.py and renders it with Mitsuba in 16 passes for each variant:
volpathmis with Mitsuba's default Russian roulette (rr_depth 5), volpathmis without roulette,
volpathmis without next event estimation (`sample_emitters = false` on the media), and volpath with
the default roulette. Every pixel of a white furnace (albedo 1, environment radiance 1) has the
expected value the scene declares (`# closed-form: R G B`, `-` for a channel without one), so the
image mean must match it within its standard error (the spread of the pass means / sqrt(passes)).
Prints, per variant, the image mean, its standard error and (mean - expected) / error. This is the evidence for docs/peers.md, "Mitsuba's Russian roulette".
"""

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import compare  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene")
    ap.add_argument("--spp", type=int, default=1024)
    ap.add_argument("--width", type=int, default=48)
    ap.add_argument("--height", type=int, default=36)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--passes", type=int, default=16)
    ap.add_argument("--out", default="out/peers/probe")
    args = ap.parse_args()

    import drjit as dr
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    dr.set_thread_count(args.threads)
    os.makedirs(args.out, exist_ok=True)
    base, _ = compare.translate(args.scene, args.width, args.height, 1000, args.out)
    expected = compare.closed_form(args.scene)
    if expected is None:
        sys.exit(f"{args.scene} declares no closed form (`# closed-form: R G B`)")

    def with_integrator(**kw):
        def f(d):
            d["integrator"] = {"type": "volpathmis", "max_depth": 1000} | kw
        return f

    def without_nee(d):
        with_integrator(rr_depth=1000)(d)
        for v in d.values():
            if isinstance(v, dict) and "interior" in v:
                v["interior"] = dict(v["interior"]) | {"sample_emitters": False}

    variants = [
        ("volpathmis, rr_depth 5 (Mitsuba's default)", with_integrator(rr_depth=5)),
        ("volpathmis, no roulette (rr_depth 1000)", with_integrator(rr_depth=1000)),
        ("volpathmis, no roulette, no NEE", without_nee),
        ("volpath, rr_depth 5 (Mitsuba's default)", with_integrator(type="volpath", rr_depth=5)),
    ]
    per_pass = max(1, args.spp // args.passes)
    print(f"{args.scene}: {args.width}x{args.height}, {per_pass * args.passes} spp in {args.passes} passes, Mitsuba {mi.__version__}")
    for label, modify in variants:
        d = {k: (dict(v) if isinstance(v, dict) else v) for k, v in base.items()}
        modify(d)
        scene = mi.load_dict(d)
        t0 = time.perf_counter()
        means = np.array([np.array(mi.render(scene, seed=500 + k, spp=per_pass))[..., :3].mean(axis=(0, 1))
                          for k in range(args.passes)])
        mean = means.mean(axis=0)
        se = means.std(axis=0, ddof=1) / np.sqrt(args.passes)
        zs = []
        for c in range(3):
            if expected[c] is None:
                zs.append("-")
            else:
                zs.append(f"{(mean[c] - expected[c]) / se[c]:+.1f}" if se[c] > 0 else f"{mean[c] - expected[c]:+.1g} (no variance)")
        print(f"  {label:45s} mean {', '.join(f'{m:.5f}' for m in mean)}  +- {', '.join(f'{s:.5f}' for s in se)}  "
              f"z {', '.join(zs)}  ({time.perf_counter() - t0:.1f} s)", flush=True)


if __name__ == "__main__":
    main()
