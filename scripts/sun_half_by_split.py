#!/usr/bin/env python3
"""Front and back of the shipped estimator, split by split (issue 53).

Each NAME=DIR is a folder that `streetlight-bench sun-features` wrote (its rows.csv: one row per crop
with a known sun and one per its mirror image; the `est_*` columns are the estimator's sun). For
each folder, prints the share of crops (mirror rows left out) whose estimated sun lies in the other
half from the true one (in front of the camera: z < 0), overall and per band of true elevation, the
number of places and how many of them have more than half their crops in the wrong half.

Usage: python3 scripts/sun_half_by_split.py NAME=DIR [NAME=DIR ...]
"""
import csv
import math
import os
import sys

BANDS = (("below 30°", 0.0, 30.0), ("30-50°", 30.0, 50.0), ("50° and up", 50.0, 91.0))


def fail(message):
    print(f"error: {message}", file=sys.stderr)
    sys.exit(2)


def vec(row, prefix, path):
    try:
        v = [float(row[prefix + a]) for a in "xyz"]
    except (KeyError, ValueError):
        fail(f"{path}: a row has no numeric {prefix}x, {prefix}y, {prefix}z")
    if not all(math.isfinite(x) for x in v) or sum(x * x for x in v) == 0.0:
        fail(f"{path}: a row has a zero or non-finite {prefix[:-1]} direction")
    return v


def summarise(path):
    try:
        with open(path, newline="") as f:
            rows = [r for r in csv.DictReader(f) if r.get("flip") == "0"]
    except OSError as e:
        fail(f"{path}: {e.strerror}")
    if not rows:
        fail(f"{path}: no crops (rows with flip 0)")
    wrong, bands, places = 0, {b[0]: [0, 0] for b in BANDS}, {}
    for r in rows:
        sun, est = vec(r, "sun_", path), vec(r, "est_", path)
        bad = (sun[2] < 0) != (est[2] < 0)
        wrong += bad
        elevation = math.degrees(math.asin(max(-1.0, min(1.0, sun[1] / math.sqrt(sum(x * x for x in sun))))))
        for name, lo, hi in BANDS:
            if lo <= max(elevation, 0.0) < hi:
                bands[name][0] += bad
                bands[name][1] += 1
        p = places.setdefault(r.get("place") or r.get("panorama", "?"), [0, 0])
        p[0] += bad
        p[1] += 1
    return len(rows), wrong, bands, places


def main():
    if any(a in ("-h", "--help") for a in sys.argv[1:]):
        print(__doc__.strip())
        sys.exit(0)
    if len(sys.argv) < 2:
        fail("expected one or more NAME=DIR folders (try --help)")
    summaries = []  # every folder is read before anything is printed
    for arg in sys.argv[1:]:
        if "=" not in arg:
            fail(f"'{arg}': expected NAME=DIR")
        name, folder = arg.split("=", 1)
        summaries.append((name, *summarise(os.path.join(folder, "rows.csv"))))
    print("| split | crops | places | wrong half | " + " | ".join(b[0] for b in BANDS) + " | places over half wrong |")
    print("|---|---|---|---|" + "---|" * len(BANDS) + "---|")
    share = lambda k, m: f"{100.0 * k / m:.0f}% ({k})" if m else "—"
    for name, n, wrong, bands, places in summaries:
        over = sum(1 for k, m in places.values() if 2 * k > m)
        print(f"| {name} | {n} | {len(places)} | {share(wrong, n)} | " +
              " | ".join(share(*bands[b[0]]) for b in BANDS) + f" | {over} |")


if __name__ == "__main__":
    main()
