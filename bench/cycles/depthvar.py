#!/usr/bin/env python3
"""depthvar.py - relative variance of a renderer's image and of one depth's
increment, from two renders with independent seeds (no depth-limited
reference needed). Images are linear .pfm files of one size; REF (a
converged full image) only normalises, as in relMSE.

  var(A)     = mean((A1 - A2)^2 / (ref^2 + 0.01)) / 2
  var(A - B) = mean(((A1 - B1) - (A2 - B2))^2 / (ref^2 + 0.01)) / 2
where A1, A2 are renders of depth limit d with seeds 1, 2, and B1, B2 renders
of limit d - 1 with the same seeds: A1 - B1 is then exactly the light carried
by the paths of d segments (a path's random numbers do not depend on the
limit), and var(A - B) its relative variance at this sample count. For an
unbiased image, E[(A1 - A2)^2] / 2 is the variance of one image, so var(A) is
what relMSE against a converged depth-limited reference would converge to.

usage: depthvar.py REF A1 A2 [B1 B2]
prints: mean_of_A1 var(A) [var(A - B)]
"""
import struct
import sys


def read_pfm(path):
    with open(path, "rb") as f:
        if f.readline().strip() != b"PF":
            sys.exit("%s: not an RGB PFM" % path)
        w, h = map(int, f.readline().split())
        fmt = "<" if float(f.readline()) < 0 else ">"
        return (w, h), struct.unpack(fmt + "%df" % (w * h * 3), f.read(w * h * 12))


def main():
    if len(sys.argv) not in (4, 6):
        sys.exit(__doc__)
    imgs = [read_pfm(p) for p in sys.argv[1:]]
    if len({size for size, _ in imgs}) != 1:
        sys.exit("depthvar.py: images differ in size")
    ref, a1, a2 = (d for _, d in imgs[:3])
    n = len(ref)
    den = [r * r + 0.01 for r in ref]
    var_a = sum((x - y) ** 2 / q for x, y, q in zip(a1, a2, den)) / n / 2
    out = "%.6g %.6g" % (sum(a1) / n, var_a)
    if len(imgs) == 5:
        b1, b2 = imgs[3][1], imgs[4][1]
        var_inc = sum(((x - u) - (y - v)) ** 2 / q for x, y, u, v, q in zip(a1, a2, b1, b2, den)) / n / 2
        out += " %.6g" % var_inc
    print(out)


main()
