#!/usr/bin/python3
"""Fits the tanh polynomial of autodiff/vector_math_kernels.h (needs numpy: Debian python3-numpy).

usage: /usr/bin/python3 scripts/fit_tanh_poly.py [--degree 5]

tanh(x) = x + x^3 P(x^2) on [0, atanh(1/2)], P of `degree` coefficients, fitted for relative error
by iteratively reweighted least squares at Chebyshev nodes (close to minimax). Prints the float32
coefficients, lowest order first, and the max error of a float32 Horner evaluation in ulp.
"""
import argparse
import sys

import numpy as np


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--degree", type=int, default=5)
    args = ap.parse_args()
    if args.degree < 1:
        print(f"error: --degree must be >= 1, got {args.degree}", file=sys.stderr)
        return 2
    a = float(np.arctanh(0.5))
    x = np.cos(np.linspace(0, np.pi, 4000)) * a / 2 + a / 2
    x = x[x > 1e-4]
    t = np.tanh(x)
    z = x * x
    target = (t - x) / x ** 3
    w = x ** 3 / t  # turns the error in P into relative error of tanh
    A = np.vstack([z ** k for k in range(args.degree)]).T
    wts = np.ones_like(x)
    for _ in range(30):
        c, *_ = np.linalg.lstsq(A * (w * wts)[:, None], target * w * wts, rcond=None)
        err = np.abs((A @ c - target) * w)
        wts *= (err / err.max()) ** 0.5 + 1e-3
    c32 = c.astype(np.float32)
    xf = np.linspace(1e-3, a, 200000).astype(np.float32)
    zf = xf * xf
    p = np.zeros_like(xf)
    for k in reversed(range(args.degree)):
        p = (p * zf + c32[k]).astype(np.float32)
    y = (xf + xf * zf * p).astype(np.float32)
    ref = np.tanh(xf.astype(np.float64))
    ulp = np.spacing(np.abs(ref).astype(np.float32)).astype(np.float64)
    print("coefficients (z^0 first):", ", ".join(repr(float(v)) for v in c32))
    print(f"max error of the float32 evaluation: {np.max(np.abs(y - ref) / ulp):.3f} ulp")
    return 0


if __name__ == "__main__":
    sys.exit(main())
