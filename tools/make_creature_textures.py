#!/usr/bin/env python3
"""Paints the creature's skin textures in its UV layout (standard library only).

    tools/make_creature_textures.py [OUT_DIR]     # default: scenes/textures

The skin mesh (tools/make_creature.py) maps a radial direction d to
u = 0.5 + atan2(d.x, d.z) / 2π, v = (d.y + 1) / 2, so each texel is painted from the direction it
stands for, with the same landmark directions the mesh generator displaces:

  creature_albedo.png     skin colour (sRGB) with darker, bluish veins over the brow, temples and
                          cheeks, and warmer, redder skin around the snout
  creature_density.png    skin density (linear data, 0..1 scaled in the scene): thick on the skull,
                          thin on the horns, the snout and the ear-like brow ridges
  creature_lips_mask.png  mask (linear data): 1 on the lips and the horns, 0 elsewhere, soft edges
  creature_albedo_surface.png
                          the same skin colour with veins painted for projection = "surface"
                          (scenes/creature_veins.toml): about twice as wide and darker, more
                          saturated blue-purple, so that they survive the light diffusing around
                          them under the skin instead of washing out to faint shadows

Small files (128 x 64); the scene scales them with the mesh's UVs.
"""
import math
import os
import struct
import sys
import zlib


def write_png(path, w, h, pixel):
    rows = b"".join(
        b"\x00" + bytes(c for x in range(w) for c in pixel(x, y)) for y in range(h)
    )

    def chunk(kind, data):
        c = struct.pack(">I", len(data)) + kind + data
        return c + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    png = b"\x89PNG\r\n\x1a\n"
    png += chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(rows, 9))
    png += chunk(b"IEND", b"")
    with open(path, "wb") as f:
        f.write(png)


def normalize(v):
    n = math.sqrt(sum(c * c for c in v))
    return tuple(c / n for c in v)


D_SNOUT = normalize((0.0, -0.3, 1.0))
D_LIPS = normalize((0.0, -0.55, 0.85))
D_BROW = [normalize((s * 0.38, 0.42, 0.82)) for s in (-1, 1)]
D_HORN = [normalize((s * 0.42, 0.80, -0.42)) for s in (-1, 1)]
D_TEMPLE = [normalize((s * 0.75, 0.35, 0.3)) for s in (-1, 1)]
D_CHEEK = [normalize((s * 0.80, -0.15, 0.55)) for s in (-1, 1)]


def direction(x, y, w, h):
    # Texel centres; row 0 is the top of the image, which is v = 1 (the mesh's top).
    u = (x + 0.5) / w
    v = 1.0 - (y + 0.5) / h
    dy = 2.0 * v - 1.0
    r = math.sqrt(max(0.0, 1.0 - dy * dy))
    phi = 2.0 * math.pi * (u - 0.5)
    return (r * math.sin(phi), dy, r * math.cos(phi))


def near(d, centre, width):
    """1 at `centre`, falling off as a Gaussian of the angle (radians) with `width`."""
    c = max(-1.0, min(1.0, sum(a * b for a, b in zip(d, centre))))
    a = math.acos(c)
    return math.exp(-((a / width) ** 2))


def veins(d):
    """Sinuous dark lines: level sets of a smooth function of the direction."""
    f = math.sin(9.0 * d[0] + 3.0 * math.sin(7.0 * d[1])) + math.sin(8.0 * d[1] + 2.5 * math.sin(6.0 * d[2]))
    line = max(0.0, 1.0 - abs(f) * 3.0)
    where = max(near(d, c, 0.6) for c in D_BROW + D_TEMPLE + D_CHEEK)
    return line * where


def albedo(d):
    base = (236, 178, 150)
    warm = (222, 120, 110)
    vein = (70, 50, 120)
    t = near(d, D_SNOUT, 0.5) * 0.6
    col = [b + (w - b) * t for b, w in zip(base, warm)]
    k = min(1.0, veins(d) * 1.2)
    return tuple(int(round(c + (v - c) * k)) for c, v in zip(col, vein))


def veins_wide(d):
    """The same vein lines as `veins`, about twice as wide, with a saturated core."""
    f = math.sin(9.0 * d[0] + 3.0 * math.sin(7.0 * d[1])) + math.sin(8.0 * d[1] + 2.5 * math.sin(6.0 * d[2]))
    line = max(0.0, 1.0 - abs(f) * 1.6)
    where = max(near(d, c, 0.6) for c in D_BROW + D_TEMPLE + D_CHEEK)
    return min(1.0, 1.8 * line) * where


def albedo_surface(d):
    """Albedo painted for surface projection: wide, dark blue-purple (low albedo) veins."""
    base = (236, 178, 150)
    warm = (222, 120, 110)
    vein = (40, 16, 150)
    t = near(d, D_SNOUT, 0.5) * 0.6
    col = [b + (w - b) * t for b, w in zip(base, warm)]
    k = min(1.0, veins_wide(d) * 1.2)
    return tuple(int(round(c + (v - c) * k)) for c, v in zip(col, vein))


def density(d):
    thin = max([near(d, c, 0.28) for c in D_HORN] + [near(d, D_SNOUT, 0.35)] + [near(d, c, 0.2) for c in D_BROW])
    value = 1.0 - 0.8 * thin
    g = int(round(255 * value))
    return (g, g, g)


def lips_mask(d):
    m = max([near(d, D_LIPS, 0.22)] + [near(d, c, 0.3) for c in D_HORN])
    g = int(round(255 * min(1.0, 1.4 * m)))
    return (g, g, g)


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..", "scenes", "textures")
    os.makedirs(out, exist_ok=True)
    w, h = 128, 64
    for name, fn in (("creature_albedo.png", albedo), ("creature_density.png", density), ("creature_lips_mask.png", lips_mask),
                     ("creature_albedo_surface.png", albedo_surface)):
        write_png(os.path.join(out, name), w, h, lambda x, y, fn=fn: fn(direction(x, y, w, h)))
        print(os.path.join(out, name))


if __name__ == "__main__":
    main()
