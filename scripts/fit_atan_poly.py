#!/usr/bin/python3
"""Fits the arctangent polynomial of render/equirect_lanes.cpp (pure Python, no packages).

usage: /usr/bin/python3 scripts/fit_atan_poly.py [--terms 12]

atan(t) = t P(t^2) on [0, 1], P of `terms` coefficients, fitted for absolute error by the Remez
exchange (minimax). Prints the coefficients, lowest order first, and the max error of a double
Horner evaluation over a dense grid (the kernel reduces atan2 to this interval; u and v of a
panorama take the error over 2 pi and pi).
"""
import argparse
import math
import sys


def solve(a, b):
    """Gaussian elimination with partial pivoting (a small dense system)."""
    n = len(b)
    m = [row[:] + [rhs] for row, rhs in zip(a, b)]
    for col in range(n):
        piv = max(range(col, n), key=lambda r: abs(m[r][col]))
        m[col], m[piv] = m[piv], m[col]
        for r in range(col + 1, n):
            f = m[r][col] / m[col][col]
            for c in range(col, n + 1):
                m[r][c] -= f * m[col][c]
    x = [0.0] * n
    for r in reversed(range(n)):
        x[r] = (m[r][n] - sum(m[r][c] * x[c] for c in range(r + 1, n))) / m[r][r]
    return x


def horner(c, s):
    p = 0.0
    for k in reversed(range(len(c))):
        p = p * s + c[k]
    return p


def error(c, t):
    return t * horner(c, t * t) - math.atan(t)


def remez(terms, iterations=30):
    n = terms + 1  # equioscillation points
    # Start from Chebyshev extrema in t on (0, 1].
    ts = [0.5 - 0.5 * math.cos(math.pi * (i + 1) / (n + 1)) for i in range(n)]
    grid = [0.5 - 0.5 * math.cos(math.pi * i / 200000) for i in range(1, 200001)]
    c = None
    for _ in range(iterations):
        # t_i P(t_i^2) + (-1)^i E = atan(t_i)
        rows = [[t * (t * t) ** k for k in range(terms)] + [(-1) ** i] for i, t in enumerate(ts)]
        sol = solve(rows, [math.atan(t) for t in ts])
        c = sol[:terms]
        errs = [error(c, t) for t in grid]
        # One extremum per run of equal sign, then the n largest alternating ones.
        ext = []
        i = 0
        while i < len(grid):
            j = i
            best = i
            while j < len(grid) and (errs[j] > 0) == (errs[i] > 0):
                if abs(errs[j]) > abs(errs[best]):
                    best = j
                j += 1
            ext.append(best)
            i = j
        while len(ext) > n:
            ext.pop(0 if abs(errs[ext[0]]) < abs(errs[ext[-1]]) else -1)
        if len(ext) < n:
            break
        ts = [grid[k] for k in ext]
    return c


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--terms", type=int, default=12)
    args = ap.parse_args()
    if args.terms < 2:
        print(f"error: --terms must be >= 2, got {args.terms}", file=sys.stderr)
        return 2
    c = remez(args.terms)
    worst = max(abs(error(c, i / 1000000)) for i in range(1000001))
    print("coefficients (t^1 first, then t^3, ...):")
    for v in c:
        print(f"  {v!r},")
    print(f"max |t P(t^2) - atan(t)| on [0, 1]: {worst:.3e} rad "
          f"(u: {worst / (2 * math.pi):.3e}, v: {worst / math.pi:.3e})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
