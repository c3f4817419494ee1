#!/usr/bin/env python3
"""Writes configs/pano_ldr_split.json: a place-disjoint train/val/test split of ../shared/data/pano_ldr.

Usage: scripts/make_pano_ldr_split.py [--data DIR] [--seed-split FILE] [--out FILE] [--check]

- The 69 panoramas of the first split (configs/pano_ldr_split_69.json, grouped by place as its
  comment says) keep their split, so that figures on its test split stay comparable.
- Every other panorama takes its place from places.csv (file,place); one place goes to one split.
- The three largest places (one sunny afternoon of 75 panoramas, a mostly overcast campus of 63,
  a campus of 49) go to train: in test they would weigh one place as much as thirty small ones.
- The other places are visited in an order fixed by a hash of their name and each goes to the
  split furthest below its share of panoramas (train 60%, val 15%, test 25%), places of more than
  30 panoramas to train. Deterministic: the same data gives the same split.
--check recomputes the split and exits 1 when the committed file differs.
"""
import argparse
import csv
import hashlib
import json
import os
import sys

SHARES = {"train": 0.60, "val": 0.15, "test": 0.25}
LARGEST_TO_TRAIN = 3
MAX_HELD_OUT_PLACE = 30


def place_order(name):
    return hashlib.sha256(("pano_ldr_split/" + name).encode()).hexdigest()


def build(data, previous):
    labels = list(csv.DictReader(open(os.path.join(data, "sun_labels.csv"), newline="")))
    places = {r["file"]: r["place"] for r in csv.DictReader(open(os.path.join(data, "places.csv"), newline=""))}
    images = sorted(f for f in os.listdir(data) if f.lower().endswith(".jpg"))
    labelled = {r["file"] for r in labels}
    missing = [f for f in images if f not in labelled]
    if missing:
        sys.exit(f"error: {data}/sun_labels.csv has no row for {missing[0]} ({len(missing)} images without one)")
    split = {f: s for s in ("train", "val", "test") for f in previous.get(s, [])}
    unplaced = [f for f in images if f not in split and f not in places]
    if unplaced:
        sys.exit(f"error: {data}/places.csv names no place for {unplaced[0]} ({len(unplaced)} files)")
    by_place = {}
    for f in images:
        if f not in split:
            by_place.setdefault(places[f], []).append(f)
    count = {s: sum(1 for v in split.values() if v == s) for s in SHARES}
    total = len(images)
    largest = sorted(by_place, key=lambda p: (-len(by_place[p]), p))[:LARGEST_TO_TRAIN]
    for p in largest:
        for f in by_place[p]:
            split[f] = "train"
        count["train"] += len(by_place[p])
    for p in sorted((p for p in by_place if p not in largest), key=place_order):
        files = by_place[p]
        if len(files) > MAX_HELD_OUT_PLACE:
            target = "train"
        else:
            target = max(SHARES, key=lambda s: SHARES[s] * total - count[s])
        for f in files:
            split[f] = target
        count[target] += len(files)
    return {s: sorted(f for f, v in split.items() if v == s) for s in ("train", "val", "test")}, labels


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default="../shared/data/pano_ldr")
    ap.add_argument("--seed-split", default="configs/pano_ldr_split_69.json")
    ap.add_argument("--out", default="configs/pano_ldr_split.json")
    ap.add_argument("--check", action="store_true")
    a = ap.parse_args()
    if not os.path.isdir(a.data):
        sys.exit(f"error: --data {a.data}: no such folder")
    split, labels = build(a.data, json.load(open(a.seed_split)))
    rows = {r["file"]: r for r in labels}
    stats = {}
    for s, files in split.items():
        sun = [rows[f] for f in files]
        stats[s] = dict(panoramas=len(files),
                        visible=sum(r["sun"] == "visible" for r in sun),
                        street=sum(r["scene"] == "street" for r in sun),
                        street_visible=sum(r["scene"] == "street" and r["sun"] == "visible" for r in sun))
    out = {
        "comment": "Place-disjoint split of ../shared/data/pano_ldr (873 panoramas), written by "
                   "scripts/make_pano_ldr_split.py: the 69 panoramas of the first split keep theirs "
                   "(configs/pano_ldr_split_69.json, grouped by place as its comment says), the others follow places.csv, one place to one split, "
                   "the three largest places in train. " +
                   "; ".join(f"{s}: {v['panoramas']} panoramas, {v['visible']} visible suns, {v['street']} streets, "
                             f"{v['street_visible']} streets with a visible sun" for s, v in stats.items()) + ".",
        "train": split["train"], "val": split["val"], "test": split["test"],
    }
    text = json.dumps(out, indent=1) + "\n"
    if a.check:
        same = os.path.exists(a.out) and open(a.out).read() == text
        print("pano_ldr split: " + ("up to date" if same else "differs from " + a.out))
        sys.exit(0 if same else 1)
    tmp = a.out + ".tmp"
    open(tmp, "w").write(text)
    os.replace(tmp, a.out)
    for s, v in stats.items():
        print(s, v)


if __name__ == "__main__":
    main()
