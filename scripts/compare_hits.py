#!/usr/bin/python3
"""Fraction of rays whose closest-hit distances agree between two HITS.bin files.

HITS.bin: float32 per ray, hit distance or +inf on a miss (see tools/bench/bench_trace.cpp).
Two rays agree when both miss, or both hit with |a - b| <= rel * max(|a|, |b|).
Usage: compare_hits.py A.bin B.bin [--rel 1e-4]   (prints the fraction)
"""
import sys

import numpy as np


def main(argv):
    if len(argv) < 3 or "--help" in argv:
        print(__doc__.strip())
        return 0 if "--help" in argv else 2
    rel = float(argv[argv.index("--rel") + 1]) if "--rel" in argv else 1e-4
    a = np.fromfile(argv[1], dtype="<f4")
    b = np.fromfile(argv[2], dtype="<f4")
    if a.size != b.size or a.size == 0:
        print(f"error: {argv[1]} has {a.size} rays, {argv[2]} has {b.size}", file=sys.stderr)
        return 2
    miss_a, miss_b = np.isinf(a), np.isinf(b)
    both_hit = ~miss_a & ~miss_b
    close = np.zeros(a.size, dtype=bool)
    scale = np.maximum(np.abs(a[both_hit]), np.abs(b[both_hit]))
    close[both_hit] = np.abs(a[both_hit] - b[both_hit]) <= rel * scale
    agree = (miss_a & miss_b) | close
    print(f"{agree.mean():.6f}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
