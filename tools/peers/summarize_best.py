#!/usr/bin/env python3
"""Headline table of one or more benchmark races (best.json files written by best.py).

    python3 tools/peers/summarize_best.py out/peers-best/best.json [out/peers-best-2/best.json ...]

For each scene and run: velour's efficiency divided by that of the headline Mitsuba LLVM
configuration (the unbiased one: volpath with its roulette on grey media, volpathmis without
roulette on chromatic ones), of Cycles and of Mitsuba scalar (the same configuration), and which
renderer is the most efficient. A ratio > 1 means velour reaches a given error sooner. Rows whose
image is biased against the reference use the noise-only MSE (best.py, step 4); they are marked
with *. Standard library only.
"""

import json
import sys


def headline_rows(entry):
    rows = {r["renderer"]: r for r in entry["results"]}
    grey = entry.get("integrator") == "volpath"
    out = {"velour": rows.get("velour")}
    for name, r in rows.items():
        if name.startswith("Mitsuba llvm") or name.startswith("Mitsuba scalar"):
            unbiased = grey or "no roulette" in name
            if not unbiased:
                continue
            out["Mitsuba LLVM" if "llvm" in name else "Mitsuba scalar"] = r
        elif name == "Cycles":
            out["Cycles"] = r
    return out


def main():
    runs = []
    for path in sys.argv[1:]:
        with open(path) as f:
            runs.append((path, json.load(f)))
    peers = ["Mitsuba LLVM", "Cycles", "Mitsuba scalar"]
    print("| scene | run | " + " | ".join(f"velour ÷ {p}" for p in peers) + " | most efficient |")
    print("|---|---|" + "---|" * len(peers) + "---|")
    for path, res in runs:
        for e in res["scenes"]:
            if "results" not in e:
                continue
            h = headline_rows(e)
            v = h["velour"]
            cells = []
            for p in peers:
                r = h.get(p)
                if r is None or not r.get("efficiency") or not v.get("efficiency"):
                    cells.append("n/a")
                    continue
                mark = "*" if r["headline_mse"] != "reference" else ""
                cells.append(f"{v['efficiency'] / r['efficiency']:.2f}{mark}")
            best = max(((k, r["efficiency"]) for k, r in h.items() if r and r.get("efficiency")), key=lambda t: t[1])[0]
            print(f"| {e['name']} | {path} | " + " | ".join(cells) + f" | {best} |")


if __name__ == "__main__":
    main()
