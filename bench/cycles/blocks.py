#!/usr/bin/env python3
"""blocks.py - do two renders show the same scene? Compares the mean colour
per B x B block (default 16) of two linear images (.pfm, as written by
`tessera tonemap IN.exr -o OUT.pfm`). Prints the mean of each image, the
largest relative block difference per channel and the median, so a wrong
orientation, field of view or light strength shows as a big number while
noise stays small.

usage: bench/cycles/blocks.py A.pfm B.pfm [BLOCK]
"""
import struct
import sys


def read_pfm(path):
    with open(path, "rb") as f:
        kind = f.readline().strip()
        if kind != b"PF":
            sys.exit("%s: not an RGB PFM" % path)
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        fmt = "<" if scale < 0 else ">"
        data = struct.unpack(fmt + "%df" % (w * h * 3), f.read(w * h * 12))
    # PFM rows run bottom to top; the comparison does not care.
    return w, h, data


def block_means(w, h, data, b):
    out = {}
    for y in range(h):
        for x in range(w):
            k = (y // b, x // b)
            s = out.setdefault(k, [0.0, 0.0, 0.0])
            i = 3 * (y * w + x)
            for c in range(3):
                s[c] += data[i + c]
    n = b * b
    return {k: [v / n for v in s] for k, s in out.items()}


def main():
    a, bpath = sys.argv[1], sys.argv[2]
    b = int(sys.argv[3]) if len(sys.argv) > 3 else 16
    wa, ha, da = read_pfm(a)
    wb, hb, db = read_pfm(bpath)
    if (wa, ha) != (wb, hb):
        sys.exit("sizes differ: %dx%d vs %dx%d" % (wa, ha, wb, hb))
    ma, mb = block_means(wa, ha, da, b), block_means(wb, hb, db, b)
    mean_a = [sum(v[c] for v in ma.values()) / len(ma) for c in range(3)]
    mean_b = [sum(v[c] for v in mb.values()) / len(mb) for c in range(3)]
    rel = []
    for k in ma:
        for c in range(3):
            rel.append(abs(ma[k][c] - mb[k][c]) / (0.5 * (ma[k][c] + mb[k][c]) + 0.01))
    rel.sort()
    print("mean A %.5f %.5f %.5f  mean B %.5f %.5f %.5f  ratio %.4f %.4f %.4f" %
          tuple(mean_a + mean_b + [mean_a[c] / mean_b[c] for c in range(3)]))
    print("block %d: relative difference median %.4f, 90%% %.4f, max %.4f over %d blocks" %
          (b, rel[len(rel) // 2], rel[int(0.9 * len(rel))], rel[-1], len(ma)))


main()
