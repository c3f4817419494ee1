#!/usr/bin/python3
"""Lighting inference part by part: Streetlight vs PyTorch 1.13 (CPU, eval mode, no_grad), same threads.

usage: /usr/bin/python3 scripts/compare_torch_inference.py BUILD_DIR [--threads 2] [--runs 7] [--rounds 3]
                                                          [--allocator jemalloc|system]

PyTorch runs the released model's layers at their sizes (models/streetlight.safetensors: ResNet-18 of
width 32 on 1x3x128x256, sky head MLP 256-256-64, the frozen sky decoder 32x128, volume MLP
256-256-(8*8*8*2) with trilinear x8 and the RGBa concatenation, UNet3D base 8 depth 3 on
1x12x64x64x16, the VSG activation; mirrors of scripts/compare_torch_train.py), in eval mode under
torch.no_grad() with random weights (time does not depend on them). Its batch norms are PyTorch's
eval batch norms (not folded). Ours: BUILD_DIR/tools/streetlight-bench inference --json (the real
model and KITTI 000008). The two sides alternate for --rounds rounds; each keeps its best.
"""
import argparse
import json
import math
import os
import subprocess
import sys
import time

import torch
import torch.nn.functional as F

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from torch_mirrors import ResNet18  # noqa: E402
from compare_torch_train import SkyDecoder, UNet3D  # noqa: E402
import anchor_allocator  # noqa: E402


def best_ms(f, runs):
    f()
    best = math.inf
    for _ in range(runs):
        t0 = time.perf_counter()
        f()
        best = min(best, (time.perf_counter() - t0) * 1e3)
    return best


def torch_parts(runs):
    torch.manual_seed(0)
    backbone = ResNet18(width=32).eval()
    sky_head = torch.nn.Sequential(torch.nn.Linear(256, 256), torch.nn.ReLU(), torch.nn.Linear(256, 64)).eval()
    decoder = SkyDecoder().eval()
    volume_mlp = torch.nn.Sequential(torch.nn.Linear(256, 256), torch.nn.ReLU(), torch.nn.Linear(256, 8 * 8 * 8 * 2)).eval()
    unet = UNet3D().eval()
    image, rgba = torch.rand(1, 3, 128, 256), torch.rand(1, 4, 64, 64, 16)
    out = {}
    with torch.no_grad():
        g = backbone(image)
        raw = sky_head(g)
        li, d, lat = raw[:, :3] + 5.0, F.normalize(raw[:, 3:6], dim=1, eps=1e-8), raw[:, 6:]
        coarse = F.interpolate(volume_mlp(g).reshape(1, 8, 8, 8, 2), scale_factor=8, mode="trilinear", align_corners=False)
        x = torch.cat([coarse, rgba], 1)
        r = unet(x)
        out["backbone"] = best_ms(lambda: backbone(image), runs)
        out["sky_head"] = best_ms(lambda: sky_head(g), runs)
        out["sky_decoder"] = best_ms(lambda: decoder(li, d, lat), runs)
        out["volume_mlp"] = best_ms(lambda: torch.cat([F.interpolate(volume_mlp(g).reshape(1, 8, 8, 8, 2), scale_factor=8,
                                                                      mode="trilinear", align_corners=False), rgba], 1), runs)
        out["unet3d"] = best_ms(lambda: unet(x), runs)
        out["vsg_activate"] = best_ms(lambda: torch.cat([F.softplus(r[:, 0:3]), r[:, 3:6],
                                                          F.softplus(r[:, 6:7]) + 1e-3, torch.sigmoid(r[:, 7:8])], 1), runs)
    return out


def ours_parts(build, threads, runs):
    env = dict(os.environ, OMP_NUM_THREADS=str(threads))
    res = subprocess.run([f"{build}/tools/streetlight-bench", "inference", "--json", "--runs", str(runs)], check=True,
                         capture_output=True, text=True, env=env).stdout
    return {r["part"]: r["ms"] for r in (json.loads(l) for l in res.splitlines() if l.startswith("{"))}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("build")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--runs", type=int, default=7)
    ap.add_argument("--rounds", type=int, default=3)
    anchor_allocator.add_argument(ap)
    a = ap.parse_args()
    allocator = anchor_allocator.use(a.allocator)
    torch.set_num_threads(a.threads)
    theirs, ours = {}, {}
    for _ in range(a.rounds):
        for k, v in torch_parts(a.runs).items():
            theirs[k] = min(theirs.get(k, math.inf), v)
        for k, v in ours_parts(a.build, a.threads, a.runs).items():
            ours[k] = min(ours.get(k, math.inf), v)
    print(f"lighting inference parts, {a.threads} threads, allocator {allocator}, best of {a.rounds} rounds x {a.runs} runs (ms; ratio = torch / ours)")
    for k in theirs:
        o = ours.get(k, math.nan)
        print(f"  {k:14s} torch {theirs[k]:8.2f}   ours {o:8.2f}   ratio {theirs[k] / o:5.2f}")
    for k in ours:
        if k not in theirs:
            print(f"  {k:32s} ours {ours[k]:8.2f}")


if __name__ == "__main__":
    main()
