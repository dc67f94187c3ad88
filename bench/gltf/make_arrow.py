#!/usr/bin/env python3
"""make_arrow.py OUT.png - a 64x64 asymmetric test texture: on white, a red
arrow pointing up (toward the image's first row) and a blue square in the
bottom-right corner, so a flipped or mirrored mapping shows at once."""
import struct, sys, zlib

W = H = 64
px = [[(255, 255, 255)] * W for _ in range(H)]
for y in range(H):
    for x in range(W):
        if 26 <= x < 38 and 24 <= y < 56:                 # shaft
            px[y][x] = (220, 20, 20)
        if 8 <= y < 24 and abs(x - 31.5) <= (y - 8) * 1.0:  # head, apex at the top
            px[y][x] = (220, 20, 20)
        if x >= 48 and y >= 48:                             # bottom-right marker
            px[y][x] = (20, 40, 220)
raw = b"".join(b"\0" + bytes(c for p in row for c in p) for row in px)
def chunk(t, d):
    return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xffffffff)
png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", W, H, 8, 2, 0, 0, 0)) + \
      chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b"")
open(sys.argv[1], "wb").write(png)
