#!/usr/bin/env python3
"""The confidence halves of a streetlight-eval results.json, per data set and per scene.

For each model and each real or generated data set, the scored images are sorted by a confidence
measure (default: sun_probability, the sun head's probability within 20 degrees of its mode; the
higher, the more confident) and cut into two halves, as streetlight-eval does for the whole set.
Printed: each half's median sun error with a 95% interval that resamples panoramas (an image's
panorama is its id before '#'), for the whole set and for each scene label (street, other) of the
LDR panoramas, which streetlight-eval does not split by confidence.

Usage: scripts/confidence_halves.py RESULTS_JSON [--measure sun_probability] [--resamples 2000] [--seed 1]
Only the standard library; exit 2 with a one-line message on a missing or malformed file.
"""
import argparse
import json
import random
import statistics
import sys


def percentile(values, q):
    s = sorted(values)
    k = (len(s) - 1) * q
    lo, hi = int(k), min(int(k) + 1, len(s) - 1)
    return s[lo] + (s[hi] - s[lo]) * (k - lo)


def halves(items, measure, resamples, seed):
    """(confident median, its CI, rest median, its CI, count per half) or None when too few."""
    items = [it for it in items if it.get("sun_error_deg") is not None and it.get(measure) is not None]
    if len(items) < 4:
        return None
    order = sorted(range(len(items)), key=lambda i: -items[i][measure])
    confident = set(order[: len(items) // 2])
    panos = {}
    for i, it in enumerate(items):
        panos.setdefault(it["id"].split("#")[0], []).append(i)
    names = sorted(panos)
    rng = random.Random(seed)
    a_meds, b_meds = [], []
    for _ in range(resamples):
        drawn = [i for _ in names for i in panos[rng.choice(names)]]
        a = [items[i]["sun_error_deg"] for i in drawn if i in confident]
        b = [items[i]["sun_error_deg"] for i in drawn if i not in confident]
        if a and b:
            a_meds.append(statistics.median(a))
            b_meds.append(statistics.median(b))
    a = [items[i]["sun_error_deg"] for i in confident]
    b = [items[i]["sun_error_deg"] for i in range(len(items)) if i not in confident]
    ci = lambda m: (percentile(m, 0.025), percentile(m, 0.975))
    return statistics.median(a), ci(a_meds), statistics.median(b), ci(b_meds), len(a), len(b)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("results")
    p.add_argument("--measure", default="sun_probability")
    p.add_argument("--resamples", type=int, default=2000)
    p.add_argument("--seed", type=int, default=1)
    a = p.parse_args()
    try:
        with open(a.results) as f:
            data = json.load(f)
        datasets = data["datasets"]
    except (OSError, ValueError, KeyError, TypeError) as e:
        print(f"error: {a.results}: not a streetlight-eval results.json ({e})", file=sys.stderr)
        sys.exit(2)
    print("| data | model | subset | confident half (n) | the rest (n) | apart |")
    print("|---|---|---|---|---|---|")
    for ds in datasets:
        for r in ds.get("results", []):
            items = r.get("sun_per_image") or []
            subsets = [("all", items)]
            scenes = sorted({it.get("scene") for it in items if it.get("scene")})
            subsets += [(s, [it for it in items if it.get("scene") == s]) for s in scenes]
            for name, sub in subsets:
                h = halves(sub, a.measure, a.resamples, a.seed)
                if h is None:
                    continue
                am, (alo, ahi), bm, (blo, bhi), na, nb = h
                apart = "yes" if ahi < blo or bhi < alo else "no"
                print(f"| {ds.get('kind', '?')} | {r.get('name', '?')} | {name} | {am:.1f} [{alo:.1f}, {ahi:.1f}] ({na}) "
                      f"| {bm:.1f} [{blo:.1f}, {bhi:.1f}] ({nb}) | {apart} |")


if __name__ == "__main__":
    main()
