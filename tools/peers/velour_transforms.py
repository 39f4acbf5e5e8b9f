"""Transforms shared by the peer tools: velour's object transform (as its scene format defines
it) and an OpenVDB grid's index-to-world map as a 4x4 matrix. Plain numpy, so every tool's
interpreter (the Mitsuba venv, the Cycles venv, the system Python with pyopenvdb) can import it
from this directory."""

import math

import numpy as np


def rot_matrix(deg):
    """velour's rotation: about x, then y, then z (R = Rz Ry Rx), angles in degrees."""
    rx, ry, rz = (math.radians(a) for a in deg)
    cx, sx, cy, sy, cz, sz = math.cos(rx), math.sin(rx), math.cos(ry), math.sin(ry), math.cos(rz), math.sin(rz)
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def object_matrix(o):
    """An object's 4x4 world matrix (translate · rotate · scale) and its per-axis scale."""
    t = np.array(o.get("translate", [0, 0, 0]), dtype=float)
    s = o.get("scale", 1.0)
    s = np.array([s] * 3 if isinstance(s, (int, float)) else s, dtype=float)
    m = np.eye(4)
    m[:3, :3] = rot_matrix(o.get("rotate", [0, 0, 0])) @ np.diag(s)
    m[:3, 3] = t
    return m, s


def index_to_world(transform):
    """An OpenVDB (linear) transform's index-to-world map as a 4x4 matrix."""
    o = np.array(transform.indexToWorld((0, 0, 0)), dtype=float)
    m = np.eye(4)
    for a in range(3):
        e = [0, 0, 0]
        e[a] = 1
        m[:3, a] = np.array(transform.indexToWorld(tuple(e)), dtype=float) - o
    m[:3, 3] = o
    return m
