#!/usr/bin/env python3
"""Where in the view a visible sun falls when the real-sky benchmark draws its crops (issue 53).

The benchmark's views (train/real_sky_benchmark.h, data/augment.h CropRanges) have a horizontal
fov uniform in [50°, 80°], a 2:1 image, a pitch uniform in ±10° and a random yaw. This draws such
views at random around the labelled visible suns of the given splits of
../shared/data/pano_ldr (sun_labels.csv, the label frame's v → elevation) and reports, of the
views with the sun in them, the share whose sun lies in the outer tenth of the view (|x| or |y|
beyond 0.8 of the half-width or half-height), where the sun-glare detector's aimed training
crops (the middle 80%) never put it.

Usage: python3 scripts/sun_in_view_positions.py [--splits train val] [--views N] [--seed S]
Needs numpy (Debian's python3-numpy).
"""
import argparse
import csv
import json
import os

import numpy as np


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", default=os.path.join(here, "..", "..", "shared", "data", "pano_ldr"))
    ap.add_argument("--split-file", default=os.path.join(here, "..", "configs", "pano_ldr_split.json"))
    ap.add_argument("--splits", nargs="+", default=["train", "val"])
    ap.add_argument("--views", type=int, default=400000)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    with open(os.path.join(a.data, "sun_labels.csv"), newline="") as f:
        labels = {r["file"]: r for r in csv.DictReader(f)}
    with open(a.split_file) as f:
        split = json.load(f)
    files = [n for s in a.splits for n in split[s]]
    el = np.radians([90.0 - 180.0 * float(labels[n]["v"]) / 1024.0 for n in files
                     if n in labels and labels[n]["sun"] == "visible" and labels[n]["v"]])
    rng = np.random.default_rng(a.seed)
    n = a.views
    e = rng.choice(el, n)
    az = rng.uniform(-np.pi, np.pi, n)
    fov = np.radians(rng.uniform(50, 80, n))
    pitch = np.radians(rng.uniform(-10, 10, n))
    d = np.stack([np.cos(e) * np.sin(az), np.sin(e), -np.cos(e) * np.cos(az)], 1)
    forward = np.stack([np.zeros(n), np.sin(pitch), -np.cos(pitch)], 1)
    up = np.stack([np.zeros(n), np.cos(pitch), np.sin(pitch)], 1)
    z = (d * forward).sum(1)
    x = d[:, 0] / z / np.tan(fov / 2)
    y = (d * up).sum(1) / z / (0.5 * np.tan(fov / 2))
    seen = (z > 0) & (np.abs(x) < 1) & (np.abs(y) < 1)
    x, y = x[seen], y[seen]
    print(f"{len(el)} visible suns of {' + '.join(a.splits)}; {seen.mean():.4f} of {n} views show the sun")
    print(f"of those: outer tenth {((np.abs(x) > 0.8) | (np.abs(y) > 0.8)).mean():.2f} "
          f"(top {(y > 0.8).mean():.2f}, sides {(np.abs(x) > 0.8).mean():.2f}); "
          f"median elevation {np.degrees(np.median(e[seen])):.1f}°")


if __name__ == "__main__":
    main()
