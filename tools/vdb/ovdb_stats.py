#!/usr/bin/python3
"""Statistics of every grid of a VDB file, computed by real OpenVDB (Debian's pyopenvdb).

Usage: /usr/bin/python3 ovdb_stats.py [--coords COORDS.json] FILE.vdb...

Prints one JSON object per grid with the definitions of tests/data/vdb/truth.jsonl:
active_voxels (tiles count as the voxels they cover), active_voxels_by_depth, leaf_count,
min, max, sum (value x voxels covered, float64), moment (value x count x index-space centre),
background, class, index_to_world of the unit points, save_half. For vec3s grids min/max/sum
are per component and sum_len is the sum of |v| x count. With COORDS.json (a list of [i, j, k])
each object also holds "values": the grid's value (active or not) at each coordinate.
"""
import json
import math
import sys

import pyopenvdb as vdb


def grid_stats(g, coords):
    is_vec = g.valueTypeName.startswith("vec3")
    n = 3 if is_vec else 1
    mn = [math.inf] * n
    mx = [-math.inf] * n
    sm = [0.0] * n
    moment = [0.0, 0.0, 0.0]
    sum_len = 0.0
    by_depth = [0, 0, 0, 0]
    for it in g.citerOnValues():
        v = list(it.value) if is_vec else [it.value]
        c = it.count
        by_depth[it.depth] += c
        for k in range(n):
            mn[k] = min(mn[k], v[k])
            mx[k] = max(mx[k], v[k])
            sm[k] += v[k] * c
        if is_vec:
            sum_len += math.sqrt(sum(x * x for x in v)) * c
        else:
            lo, hi = it.min, it.max
            for a in range(3):
                moment[a] += v[0] * c * (lo[a] + hi[a]) / 2.0
    t = g.transform
    out = {
        "name": g.name,
        "type": g.valueTypeName,
        "class": g.gridClass,
        "background": list(g.background) if is_vec else g.background,
        "active_voxels": g.activeVoxelCount(),
        "active_voxels_by_depth": by_depth,
        "leaf_count": g.leafCount(),
        "min": mn if is_vec else mn[0],
        "max": mx if is_vec else mx[0],
        "sum": sm if is_vec else sm[0],
        "save_half": bool(g.saveFloatAsHalf),
        "index_to_world_origin": list(t.indexToWorld((0, 0, 0))),
        "index_to_world_x1": list(t.indexToWorld((1, 0, 0))),
        "index_to_world_y1": list(t.indexToWorld((0, 1, 0))),
        "index_to_world_z1": list(t.indexToWorld((0, 0, 1))),
    }
    bbox = g.evalActiveVoxelBoundingBox()
    out["active_bbox"] = [list(bbox[0]), list(bbox[1])]
    if is_vec:
        out["sum_len"] = sum_len
    else:
        out["moment"] = moment
    if coords is not None:
        acc = g.getConstAccessor()
        vals = []
        for ijk in coords:
            v = acc.getValue(tuple(ijk))
            vals.append(list(v) if is_vec else v)
        out["values"] = vals
    return out


def main():
    args = sys.argv[1:]
    coords = None
    if args and args[0] == "--coords":
        with open(args[1]) as f:
            coords = json.load(f)
        args = args[2:]
    for path in args:
        grids, _meta = vdb.readAll(path)
        for g in grids:
            s = grid_stats(g, coords)
            s["file"] = path
            print(json.dumps(s))


if __name__ == "__main__":
    main()
