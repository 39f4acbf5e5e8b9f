#!/usr/bin/env python3
"""Writes small test textures as 8-bit RGB PNG files (standard library only).

    tools/make_texture.py veins OUT.png [SIZE]   # skin-like albedo with darker 'veins'
    tools/make_texture.py mask OUT.png [SIZE]    # a soft grey mask (left dark, right light)
    tools/make_texture.py constant OUT.png R G B [SIZE]
    tools/make_texture.py check OUT.png [SIZE]    # a printed check: red and cream bands

Used by tools/bench_textures.sh; nothing here is committed as binary data.
"""
import math
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


def veins(x, y, n):
    u, v = x / n, y / n
    # A few sinuous dark lines over a warm base.
    d = min(
        abs(math.sin(6.0 * u + 2.0 * math.sin(9.0 * v) + k) * 0.5 + 0.5 - 0.5) for k in (0.0, 1.7, 3.1)
    )
    t = max(0.0, 1.0 - d * 12.0)
    base = (230, 170, 140)
    vein = (120, 70, 110)
    return tuple(int(b + (c - b) * t) for b, c in zip(base, vein))


def check(x, y, n):
    # Bands a quarter of the image wide along u and along v: red where both are set, cream
    # where neither is, a darker red where one is.
    a = (4 * x // n) % 2 == 0
    b = (4 * y // n) % 2 == 0
    if a and b:
        return (184, 26, 23)
    if a or b:
        return (120, 40, 36)
    return (219, 209, 184)


def main():
    kind, out = sys.argv[1], sys.argv[2]
    if kind == "veins":
        n = int(sys.argv[3]) if len(sys.argv) > 3 else 256
        write_png(out, n, n, lambda x, y: veins(x, y, n))
    elif kind == "mask":
        n = int(sys.argv[3]) if len(sys.argv) > 3 else 64
        write_png(out, n, n, lambda x, y: (int(255 * x / (n - 1)),) * 3)
    elif kind == "constant":
        r, g, b = (int(c) for c in sys.argv[3:6])
        n = int(sys.argv[6]) if len(sys.argv) > 6 else 4
        write_png(out, n, n, lambda x, y: (r, g, b))
    elif kind == "check":
        n = int(sys.argv[3]) if len(sys.argv) > 3 else 64
        write_png(out, n, n, lambda x, y: check(x, y, n))
    else:
        sys.exit(f"unknown kind {kind!r}")


if __name__ == "__main__":
    main()
