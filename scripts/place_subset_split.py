#!/usr/bin/env python3
"""A split whose train holds a seeded share of the training places, for learning curves over places.

Val and test are copied unchanged, so runs trained on the subset are scored on the same panoramas as
runs trained on all of train. A place is what `places.csv` (file,place) names; a file it does not
name (the first 69 LDR panoramas) counts as its repository's place (the repository part of its
owner__repository__name, so forks of one repository are one place: coarser than
configs/pano_ldr_split_69.json's grouping, so no place is ever cut in two);
without --places every file is its own place (the HDR skies). Places are ordered by a hash of their
name and the seed, and the first round(share x places) are kept; --complement keeps the others, so
the two halves of one seed together are the full train split.

Prints one line: the places and files kept, and how many of the kept files have a known sun
position (`sun_labels.csv` rows with u and v) when --labels is given.

Usage: python3 scripts/place_subset_split.py --split FILE --out FILE [--places places.csv]
           [--labels sun_labels.csv] [--share 0.5] [--seed N] [--complement]
"""
import argparse
import csv
import hashlib
import json
import os
import sys


def fail(message):
    print(f"error: {message}", file=sys.stderr)
    sys.exit(2)


def place_of(name, places):
    if places is None:
        return name
    if name in places:
        return places[name]
    parts = name.split("__")
    return "repository " + parts[1] if len(parts) >= 3 else name


def order_key(place, seed):
    return hashlib.sha256(f"{seed}:{place}".encode()).hexdigest()


def read_csv(path, what):
    try:
        with open(path, newline="") as f:
            return list(csv.DictReader(f))
    except OSError as e:
        fail(f"{path}: cannot read the {what}: {e.strerror}")


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--split", required=True, help="the split JSON (train, val, test lists of file names)")
    p.add_argument("--out", required=True, help="where to write the subset split")
    p.add_argument("--places", help="file,place CSV; without it each file is its own place")
    p.add_argument("--labels", help="sun_labels.csv, to count the kept files with a known sun")
    p.add_argument("--share", type=float, default=0.5, help="share of the training places kept (0-1]")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--complement", action="store_true", help="keep the places the draw leaves out")
    a = p.parse_args()
    if not 0.0 < a.share <= 1.0:
        fail(f"--share {a.share}: must lie in (0, 1]")
    try:
        with open(a.split) as f:
            split = json.load(f)
    except OSError as e:
        fail(f"{a.split}: {e.strerror}")
    except json.JSONDecodeError as e:
        fail(f"{a.split}: not JSON ({e.msg}, line {e.lineno})")
    for key in ("train", "val", "test"):
        if not isinstance(split.get(key), list):
            fail(f"{a.split}: '{key}' must be a list of file names")
    places = None
    if a.places:
        rows = read_csv(a.places, "places")
        if rows and not {"file", "place"} <= set(rows[0]):
            fail(f"{a.places}: expected the columns file,place")
        places = {r["file"]: r["place"] for r in rows}
    by_place = {}
    for name in split["train"]:
        by_place.setdefault(place_of(name, places), []).append(name)
    ordered = sorted(by_place, key=lambda q: order_key(q, a.seed))
    n = max(1, round(a.share * len(ordered)))
    chosen = set(ordered[n:] if a.complement else ordered[:n])
    if not chosen:
        fail(f"--share {a.share} with --complement leaves no training place")
    train = [name for name in split["train"] if place_of(name, places) in chosen]
    out = dict(split)
    out["comment"] = (f"train: {len(chosen)} of the {len(ordered)} training places of {os.path.basename(a.split)} "
                      f"(scripts/place_subset_split.py --share {a.share} --seed {a.seed}"
                      f"{' --complement' if a.complement else ''}); val and test unchanged. "
                      + str(split.get("comment", "")))
    out["train"] = train
    tmp = a.out + ".tmp"
    try:
        with open(tmp, "w") as f:
            json.dump(out, f, indent=1)
            f.write("\n")
        os.replace(tmp, a.out)
    except OSError as e:
        fail(f"{a.out}: cannot write: {e.strerror}")
    line = f"{len(chosen)} of {len(ordered)} places, {len(train)} of {len(split['train'])} files"
    if a.labels:
        known = {r["file"] for r in read_csv(a.labels, "sun labels") if r.get("u") and r.get("v")}
        sunny = [name for name in train if name in known]
        line += (f"; {len(sunny)} with a known sun, from "
                 f"{len({place_of(name, places) for name in sunny})} places")
    print(line)


if __name__ == "__main__":
    main()
