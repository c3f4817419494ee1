#!/usr/bin/env python3
"""Linear probes of front and back on the features `streetlight-bench sun-features` writes (issue 53).

Which features tell whether a real photo's sun is in front of the camera or behind it, on places
the probe never saw? A probe is an L2-regularised logistic regression on standardised features,
fitted on the TRAIN folders' rows (each crop and its mirror image); its strength is chosen on the
VAL folders alone, then read on every --eval folder. A crop's answer is the mean of its own and
its mirror image's probability (the estimator's flip averaging). Accuracy is per crop, with a 95%
interval that resamples panoramas. With --place-curve, probes are refitted on random subsets of the
training places to show how held-out accuracy grows with the number of places.

Usage:
  python3 scripts/probe_sun_features.py --train DIR [DIR ...] --val DIR [DIR ...] \\
      --eval NAME=DIR[@SCENE] ... [--blocks B ...] [--lambdas L ...] [--place-curve] [--json OUT]
(@SCENE keeps the rows of one scene of sun_labels.csv, e.g. @street.)
Blocks: backbone, statistics, glare_azimuth, mobilenet, and sums of them with '+'
(e.g. backbone+glare_azimuth). Needs numpy (Debian's python3-numpy).
"""
import argparse
import csv
import json
import os
import sys

import numpy as np


def load(folder, blocks):
    rows_path = os.path.join(folder, "rows.csv")
    if not os.path.exists(rows_path):
        sys.exit(f"error: {rows_path} does not exist (write it with streetlight-bench sun-features)")
    with open(rows_path, newline="") as f:
        rows = list(csv.DictReader(f))
    feats = {}
    for b in blocks:
        p = os.path.join(folder, b + ".npy")
        if not os.path.exists(p):
            sys.exit(f"error: {p} does not exist (block '{b}')")
        x = np.load(p).astype(np.float64)
        if x.shape[0] != len(rows):
            sys.exit(f"error: {p} has {x.shape[0]} rows, rows.csv {len(rows)}")
        feats[b] = x
    return rows, feats


class Data:
    def __init__(self, folders, blocks):
        self.rows, parts = [], {b: [] for b in blocks}
        for folder in folders:
            r, f = load(folder, blocks)
            tag = os.path.basename(os.path.normpath(folder))
            for row in r:
                row["panorama"] = tag + "/" + row["panorama"]
                row["place"] = tag + "/" + row["place"]
            self.rows += r
            for b in blocks:
                parts[b].append(f[b])
        self.feats = {b: np.concatenate(parts[b]) for b in blocks}
        self.front = np.array([float(r["sun_z"]) < 0 for r in self.rows])
        self.est_front = np.array([float(r["est_z"]) < 0 for r in self.rows])
        self.flip = np.array([int(r["flip"]) for r in self.rows])
        self.panorama = np.array([r["panorama"] for r in self.rows])
        self.place = np.array([r["place"] for r in self.rows])
        self.crop_key = np.array([r["panorama"] + "#" + r["crop"] for r in self.rows])

    def keep(self, mask):
        """Only the rows of mask (e.g. one scene)."""
        self.rows = [r for r, m in zip(self.rows, mask) if m]
        self.feats = {b: f[mask] for b, f in self.feats.items()}
        for name in ("front", "est_front", "flip", "panorama", "place", "crop_key"):
            setattr(self, name, getattr(self, name)[mask])

    def x(self, spec):
        return np.concatenate([self.feats[b] for b in spec.split("+")], axis=1)


def fit_logistic(x, y, lam, iters=50, cg_iters=50):
    """Truncated Newton (conjugate gradients on the Hessian) on the log-loss + lam/2·|w|²
    (the bias not penalised): only matrix-vector products, so it stays fast without an optimised BLAS."""
    n, d = x.shape
    w = np.zeros(d)
    b = 0.0
    for _ in range(iters):
        p = 1.0 / (1.0 + np.exp(-np.clip(x @ w + b, -50, 50)))
        r = p - y
        gw = x.T @ r + lam * w
        gb = r.sum()
        s = p * (1 - p) + 1e-12
        # Solve H [dw, db] = [gw, gb] by conjugate gradients, H = [[XᵀSX + λI, XᵀS1], [1ᵀSX, 1ᵀS1]].
        def hv(vw, vb):
            t = s * (x @ vw + vb)
            return x.T @ t + lam * vw, t.sum()
        dw, db = np.zeros(d), 0.0
        rw, rb = gw.copy(), gb
        pw, pb = rw.copy(), rb
        rr = rw @ rw + rb * rb
        g2 = rr
        for _ in range(cg_iters):
            hw, hb = hv(pw, pb)
            alpha = rr / (pw @ hw + pb * hb)
            dw += alpha * pw
            db += alpha * pb
            rw -= alpha * hw
            rb -= alpha * hb
            rr_new = rw @ rw + rb * rb
            if rr_new < 1e-10 * g2:
                break
            pw = rw + (rr_new / rr) * pw
            pb = rb + (rr_new / rr) * pb
            rr = rr_new
        w -= dw
        b -= db
        if g2 < 1e-12 * n:
            break
    return np.concatenate([w, [b]])


def predict(w, x):
    z = np.concatenate([x, np.ones((x.shape[0], 1))], axis=1) @ w
    return 1.0 / (1.0 + np.exp(-np.clip(z, -50, 50)))


def crop_accuracy(data, prob_front):
    keys, inv = np.unique(data.crop_key, return_inverse=True)
    s = np.bincount(inv, weights=prob_front)
    c = np.bincount(inv)
    truth = np.zeros(len(keys), dtype=bool)
    truth[inv] = data.front
    pan = np.empty(len(keys), dtype=object)
    pan[inv] = data.panorama
    return (s / c >= 0.5) == truth, pan


def interval(correct, pan, resamples=1000, seed=7):
    names, inv = np.unique(pan, return_inverse=True)
    hits = np.bincount(inv, weights=correct.astype(float))
    count = np.bincount(inv)
    rng = np.random.default_rng(seed)
    acc = []
    for _ in range(resamples):
        pick = rng.integers(0, len(names), len(names))
        acc.append(hits[pick].sum() / count[pick].sum())
    return float(correct.mean()), float(np.percentile(acc, 2.5)), float(np.percentile(acc, 97.5))


def fmt(a):
    return f"{a[0]:.3f} [{a[1]:.2f}, {a[2]:.2f}]"


def standardise(train_x, *others):
    mu = train_x.mean(0)
    sd = train_x.std(0) + 1e-6
    return [(train_x - mu) / sd] + [(o - mu) / sd for o in others]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--train", nargs="+", required=True)
    ap.add_argument("--val", nargs="+", required=True)
    ap.add_argument("--eval", nargs="*", default=[], metavar="NAME=DIR")
    ap.add_argument("--blocks", nargs="+", default=["statistics", "backbone", "glare_azimuth", "mobilenet",
                                                    "backbone+glare_azimuth", "backbone+glare_azimuth+mobilenet+statistics"])
    ap.add_argument("--lambdas", nargs="+", type=float, default=[1, 10, 100, 1000, 10000])
    ap.add_argument("--place-curve", action="store_true")
    ap.add_argument("--json")
    a = ap.parse_args()
    needed = sorted({b for spec in a.blocks for b in spec.split("+")} | {"glare_azimuth_p"})
    train = Data(a.train, needed)
    val = Data(a.val, needed)
    evals = []
    for e in a.eval:
        if "=" not in e:
            sys.exit(f"error: --eval '{e}': expected NAME=DIR")
        name, folder = e.split("=", 1)
        scene = None
        if "@" in folder:
            folder, scene = folder.split("@", 1)
        d = Data([folder], needed)
        if scene:
            d.keep(np.array([r["scene"] == scene for r in d.rows]))
        evals.append((name, d))
    sets = [("val (all)", val)] + evals
    out = {"train_rows": len(train.rows), "train_places": int(len(np.unique(train.place))), "rows": []}
    print(f"train: {len(train.rows)} rows, {len(np.unique(train.panorama))} panoramas, "
          f"{len(np.unique(train.place))} places; front share {train.front.mean():.2f}")
    header = "| features | λ (val) | train | " + " | ".join(n for n, _ in sets) + " |"
    print(header)
    print("|" + "---|" * (3 + len(sets)))
    # Reference rows: the constant, the shipped estimator, the detector's azimuth head.
    const = float(train.front.mean() >= 0.5)
    for label, prob in [("the constant (train's majority)", lambda d: np.full(len(d.rows), const)),
                        ("the shipped estimator's sun", lambda d: d.est_front.astype(float)),
                        ("the detector's azimuth head", lambda d: front_mass(d.feats["glare_azimuth_p"]))]:
        cells = [fmt(interval(*crop_accuracy(d, prob(d)))) for _, d in sets]
        tr = interval(*crop_accuracy(train, prob(train)))[0]
        print(f"| {label} | — | {tr:.3f} | " + " | ".join(cells) + " |")
        out["rows"].append({"features": label, "train": tr, "sets": dict(zip([n for n, _ in sets], cells))})
    fitted = {}
    for spec in a.blocks:
        xs = standardise(train.x(spec), val.x(spec), *[d.x(spec) for _, d in evals])
        best = None
        for lam in a.lambdas:
            w = fit_logistic(xs[0], train.front.astype(float), lam)
            acc = crop_accuracy(val, predict(w, xs[1]))[0].mean()
            if best is None or acc > best[0]:
                best = (acc, lam, w)
        _, lam, w = best
        fitted[spec] = lam
        tr = interval(*crop_accuracy(train, predict(w, xs[0])))[0]
        cells = [fmt(interval(*crop_accuracy(d, predict(w, x)))) for (_, d), x in zip(sets, xs[1:])]
        print(f"| {spec} ({xs[0].shape[1]}) | {lam:g} | {tr:.3f} | " + " | ".join(cells) + " |")
        out["rows"].append({"features": spec, "lambda": lam, "train": tr, "sets": dict(zip([n for n, _ in sets], cells))})
    if a.place_curve:
        places = np.unique(train.place)
        sizes = [n for n in (4, 8, 16, 32, 64) if n < len(places)] + [len(places)]
        rng = np.random.default_rng(11)
        held = [("val (all)", val)] + evals
        print("\nheld-out accuracy against the number of training places (mean of 5 draws of places; λ from above)")
        print("| features | " + " | ".join(f"{n} places" for n in sizes) + " |")
        print("|" + "---|" * (1 + len(sizes)))
        curve = {}
        for spec in a.blocks:
            cells = []
            for n in sizes:
                accs = []
                for draw in range(5 if n < len(places) else 1):
                    keep = np.isin(train.place, rng.choice(places, n, replace=False))
                    xs = standardise(train.x(spec)[keep], *[d.x(spec) for _, d in held])
                    w = fit_logistic(xs[0], train.front[keep].astype(float), fitted[spec])
                    hits = np.concatenate([crop_accuracy(d, predict(w, x))[0] for (_, d), x in zip(held, xs[1:])])
                    accs.append(hits.mean())
                cells.append(f"{np.mean(accs):.3f}")
            curve[spec] = dict(zip(map(str, sizes), cells))
            print(f"| {spec} | " + " | ".join(cells) + " |")
        out["place_curve"] = {"sizes": sizes, "held_out": [n for n, _ in held], "accuracy": curve}
    if a.json:
        with open(a.json, "w") as f:
            json.dump(out, f, indent=1)


def front_mass(p):
    """The azimuth head's probability that the sun is in front: its sectors whose centre is within 90° of 0."""
    bins = p.shape[1]
    centre = -np.pi + (np.arange(bins) + 0.5) * 2 * np.pi / bins
    return p[:, np.abs(centre) < np.pi / 2].sum(1)


if __name__ == "__main__":
    main()
