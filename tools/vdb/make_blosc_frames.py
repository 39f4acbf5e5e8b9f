#!/usr/bin/python3
"""Writes Blosc frames made by the real C-Blosc library (Debian's libblosc1, via ctypes) for
velour's Blosc decoder test: every codec velour decodes (blosclz, lz4, lz4hc, zlib), with and
without byte shuffle, type sizes 1, 2, 4 and 12, one or several blocks, split and unsplit
streams, compressible and incompressible data.

Usage: /usr/bin/python3 make_blosc_frames.py OUT.bin

Format (little endian): u32 number of data sets, then per data set u32 length and bytes;
then records to the end: u8 data set, u32 raw length (a prefix of the data set), u32 frame
length, frame bytes.
"""
import ctypes
import math
import random
import struct
import sys

blosc = ctypes.CDLL("libblosc.so.1")


def compress(raw, typesize, shuffle, codec, blocksize, clevel=9):
    out = ctypes.create_string_buffer(len(raw) + 16 + 64)
    n = blosc.blosc_compress_ctx(
        ctypes.c_int(clevel), ctypes.c_int(shuffle), ctypes.c_size_t(typesize),
        ctypes.c_size_t(len(raw)), raw, out, ctypes.c_size_t(len(out)),
        codec.encode(), ctypes.c_size_t(blocksize), ctypes.c_int(1))
    if n <= 0:
        raise RuntimeError(f"blosc_compress_ctx failed: {n}")
    return out.raw[:n]


def main():
    rng = random.Random(1)
    smooth = b"".join(struct.pack("<f", math.sin(i * 0.01) * 0.5 + 0.5) for i in range(1024))
    ramps = bytes((i // 7) & 0xFF for i in range(2048))
    noise = bytes(rng.getrandbits(8) for _ in range(600))
    sets = [smooth, ramps, noise]
    records = []
    for codec in ["blosclz", "lz4", "lz4hc", "zlib"]:
        for shuffle in [0, 1]:
            for typesize in [1, 2, 4, 12]:
                for k, data in enumerate(sets):
                    for blocksize in [0, 512]:
                        n = len(data) - len(data) % typesize
                        records.append((k, n, compress(data[:n], typesize, shuffle, codec, blocksize)))
    with open(sys.argv[1], "wb") as f:
        f.write(struct.pack("<I", len(sets)))
        for d in sets:
            f.write(struct.pack("<I", len(d)))
            f.write(d)
        for k, n, frame in records:
            f.write(struct.pack("<BII", k, n, len(frame)))
            f.write(frame)
    print(len(records), "frames")


if __name__ == "__main__":
    main()
