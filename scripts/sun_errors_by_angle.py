#!/usr/bin/env python3
"""Breaks a streetlight-eval result's sun errors down by the true sun's elevation and azimuth.

Usage: scripts/sun_errors_by_angle.py RESULTS.json
  RESULTS.json: `streetlight-eval --json` output or its --out DIR/results.json. For every
  checkpoint row of every data set it prints, from "sun_per_image", the median angular error and
  the median elevation and azimuth errors per band of true elevation, and per band of true
  azimuth relative to the camera (0 = straight ahead, positive = to the right), in degrees.
"""
import json
import math
import sys


def median(xs):
    xs = sorted(xs)
    n = len(xs)
    if n == 0:
        return float("nan")
    return xs[n // 2] if n % 2 else 0.5 * (xs[n // 2 - 1] + xs[n // 2])


def elevation(v):
    return math.degrees(math.asin(max(-1.0, min(1.0, v[1] / math.sqrt(sum(x * x for x in v))))))


def azimuth(v):  # canonical frame: the camera looks down -Z, +X is to its right
    return math.degrees(math.atan2(v[0], -v[2]))


def report(name, per):
    rows = []
    for e in per:
        p, t = e["predicted"], e["truth"]
        d_az = (azimuth(p) - azimuth(t) + 180.0) % 360.0 - 180.0
        rows.append((e["sun_error_deg"], elevation(t), abs(elevation(p) - elevation(t)), azimuth(t), abs(d_az)))
    print(f"{name}: {len(rows)} images with a sun label, median error {median([r[0] for r in rows]):.1f}")
    print("  true elevation | images | median error | median elevation error | median azimuth error")
    for lo, hi in [(-90, 15), (15, 30), (30, 45), (45, 60), (60, 91)]:
        s = [r for r in rows if lo <= r[1] < hi]
        print(f"  {max(lo, 0):3d}-{min(hi, 90):2d}         | {len(s):6d} | {median([r[0] for r in s]):12.1f} |"
              f" {median([r[2] for r in s]):22.1f} | {median([r[4] for r in s]):20.1f}")
    print("  true azimuth   | images | median error | median azimuth error")
    for lo, hi in [(-180, -135), (-135, -45), (-45, 45), (45, 135), (135, 181)]:
        s = [r for r in rows if lo <= r[3] < hi]
        print(f"  {lo:4d}..{min(hi, 180):4d}   | {len(s):6d} | {median([r[0] for r in s]):12.1f} | {median([r[4] for r in s]):20.1f}")
    print(f"  errors above 45 deg: {sum(1 for r in rows if r[0] > 45)}, of which azimuth off by more than 135: "
          f"{sum(1 for r in rows if r[0] > 45 and r[4] > 135)}")


def main():
    if len(sys.argv) != 2 or sys.argv[1] in ("-h", "--help"):
        print(__doc__.strip())
        sys.exit(0 if len(sys.argv) == 2 else 2)
    path = sys.argv[1]
    try:
        with open(path) as f:
            doc = json.load(f)
    except (OSError, ValueError) as e:
        print(f"error: {path}: {e}", file=sys.stderr)
        sys.exit(2)
    sets = doc.get("datasets") or [{"data": doc.get("data", path), "results": doc.get("results", [])}]
    found = False
    for ds in sets:
        for r in ds.get("results", []):
            if "sun_per_image" in r:
                found = True
                report(f"{ds.get('data', '?')} / {r.get('name', r.get('checkpoint', '?'))}", r["sun_per_image"])
    if not found:
        print(f"error: {path}: no \"sun_per_image\" (made by a streetlight-eval older than 2026-11-26?)", file=sys.stderr)
        sys.exit(2)


if __name__ == "__main__":
    main()
