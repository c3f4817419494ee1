#!/usr/bin/env python3
"""Front and back from several sun-glare detectors' azimuth heads at once (issue 53).

Each NAME=DIR is a folder that `streetlight-bench sun-features --sun-glare FILE` wrote for one
detector, on the same split and crops. For each detector, and for the mean of the heads'
probabilities that the sun is in front over every subset of two or more, prints the share of
crops put in the right half (a crop's answer: the mean over it and its mirror image, as the
estimator flip-averages), with a 95% interval that resamples panoramas. The first folder's
`est_*` columns give the shipped estimator's own row.

Usage: python3 scripts/ensemble_azimuth_heads.py NAME=DIR NAME=DIR [...]
Needs numpy (Debian's python3-numpy).
"""
import itertools
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from probe_sun_features import Data, crop_accuracy, fmt, front_mass, interval  # noqa: E402


def fail(message):
    print(f"error: {message}", file=sys.stderr)
    sys.exit(2)


def main():
    if any(a in ("-h", "--help") for a in sys.argv[1:]):
        print(__doc__.strip())
        sys.exit(0)
    if len(sys.argv) < 3:
        fail("expected two or more NAME=DIR folders (try --help)")
    heads = {}
    first = None
    for arg in sys.argv[1:]:
        if "=" not in arg:
            fail(f"'{arg}': expected NAME=DIR")
        name, folder = arg.split("=", 1)
        d = Data([folder], ["glare_azimuth_p"])
        if first is None:
            first = d
        elif [k.split("/", 1)[1] for k in d.crop_key] != [k.split("/", 1)[1] for k in first.crop_key] or \
                list(d.flip) != list(first.flip):
            fail(f"{folder}: its rows are not the same crops as {sys.argv[1].split('=', 1)[1]}'s")
        heads[name] = front_mass(d.feats["glare_azimuth_p"])
    print(f"{len(np.unique(first.crop_key))} crops of {len(np.unique(first.panorama))} panoramas")
    print("| azimuth heads | right half |")
    print("|---|---|")
    print(f"| the shipped estimator (the first folder's) | {fmt(interval(*crop_accuracy(first, first.est_front.astype(float))))} |")
    names = list(heads)
    for k in range(1, len(names) + 1):
        for combo in itertools.combinations(names, k):
            p = np.mean([heads[c] for c in combo], axis=0)
            label = combo[0] if k == 1 else "mean of " + " + ".join(combo)
            print(f"| {label} | {fmt(interval(*crop_accuracy(first, p)))} |")


if __name__ == "__main__":
    main()
