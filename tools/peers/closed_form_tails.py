#!/usr/bin/env python3
"""Per-pixel test of each renderer alone against a scene's closed form, from a comparison run.

    ~/.cache/velour-peers/venv/bin/python tools/peers/closed_form_tails.py [--out out/peers] SCENE.toml ...

For every scene that declares `# closed-form: R G B` (see compare.py), reads
`<out>/<scene>.velour.exr` and `<out>/<scene>.mitsuba.exr` written by compare.py and prints, per
renderer and channel, the per-pixel z = (pixel mean - expected) / sqrt(its variance) over the
pixels with more than float-rounding variance: the fractions beyond |z| > 2 and > 3 (4.55 % and
0.27 % for a Gaussian estimate; somewhat more for Mitsuba's batch variance with K - 1 degrees of
freedom), split by sign, and the smallest, median and largest pixel value. Where the two renderers
disagree per pixel but their image means match the closed form, this shows which renderer's
per-pixel distribution is not Gaussian (skewed or heavy-tailed sample weights).
"""

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import compare  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenes", nargs="+")
    ap.add_argument("--out", default="out/peers")
    args = ap.parse_args()
    for scene in args.scenes:
        expected = compare.closed_form(scene)
        name = os.path.splitext(os.path.basename(scene))[0]
        if expected is None:
            print(f"{name}: no closed form declared")
            continue
        for who in ("velour", "mitsuba"):
            mean, var, _ = compare.read_velour_exr(os.path.join(args.out, f"{name}.{who}.exr"))
            print(f"{name} {who}:")
            for c in range(3):
                if expected[c] is None:
                    continue
                m, v = mean[..., c], var[..., c]
                tested = np.sqrt(v) > 1e-6 * np.abs(m) + 1e-12
                z = (m[tested] - expected[c]) / np.sqrt(v[tested])
                print(f"  {'RGB'[c]}: {tested.sum()} pixels, |z|>2 {100 * (np.abs(z) > 2).mean():.2f}%, "
                      f"|z|>3 {100 * (np.abs(z) > 3).mean():.2f}% (z>3 {100 * (z > 3).mean():.2f}%, z<-3 {100 * (z < -3).mean():.2f}%), "
                      f"pixel min {m[tested].min():.3f} median {np.median(m[tested]):.4f} max {m[tested].max():.3f}")


if __name__ == "__main__":
    main()
