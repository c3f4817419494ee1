#!/usr/bin/python3
"""Side-by-side training step of the lighting predictor: Streetlight vs PyTorch 1.13 (CPU).

usage: /usr/bin/python3 scripts/compare_torch_train.py BUILD_DIR [--threads 2] [--batch 2] [--rounds 3]
                                                   [--allocator jemalloc|system]

Runs BUILD_DIR/tools/streetlight-bench predictor-step --json and the same step in PyTorch, with
the same thread count, in one invocation, and prints both and the ratio. Use Debian's
/usr/bin/python3 (python3-torch); the renderer is left out because PyTorch has no equivalent.

The PyTorch network mirrors train/lighting_predictor.h at its defaults, layer for layer:
  ResNet-18 (BasicBlock, width 64) on 128x256 -> pooled 512
  sky head MLP 512-256-64 -> sky code (log intensity + 5, normalised direction, latent)
  FROZEN sky decoder (train/sky_autoencoder.h): MLP 64-256-(128*4*16) with LeakyReLU 0.2, three
    (bilinear x2, conv+GN+LReLU, conv+GN+LReLU) levels fed 9 conditioning maps (direction, SG
    maps at sharpness 2/16/128, log intensity / 8), a 3x3 head, and logaddexp with the analytic
    sun lobe
  volume MLP 512-256-(8*8*8*2) -> [8, 8, 8, 2] -> trilinear x8 -> concat RGBa -> UNet3D (in 12,
    out 8, base 8, depth 3, GroupNorm(4), LeakyReLU 0.2, nearest upsample + conv) -> VSG activation
A step: zero_grad, forward on a batch, loss = mean(log_env^2) + mean(vsg^2), backward, AdamW.
"""
import argparse
import json
import math
import subprocess
import sys
import time

import torch
import torch.nn as nn
import torch.nn.functional as F

import os
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from torch_mirrors import ResNet18  # noqa: E402
import anchor_allocator  # noqa: E402


def lrelu():
    return nn.LeakyReLU(0.2)


def panorama_directions(h, w):
    """render/equirect.h: texel centres, row 0 at the zenith, azimuth 0 looking down -Z."""
    v = (torch.arange(h, dtype=torch.float32) + 0.5) / h
    u = (torch.arange(w, dtype=torch.float32) + 0.5) / w
    el = (0.5 - v) * math.pi
    az = (u - 0.5) * 2 * math.pi
    el, az = torch.meshgrid(el, az, indexing="ij")
    return torch.stack([el.cos() * az.sin(), el.sin(), -el.cos() * az.cos()], 0)[None]  # [1, 3, h, w]


def conv_gn_act(cin, cout, stride=1):
    return nn.Sequential(nn.Conv2d(cin, cout, 3, stride, 1, bias=False), nn.GroupNorm(8, cout), lrelu())


class SkyDecoder(nn.Module):
    SHARP = (2.0, 16.0, 128.0)

    def __init__(self, h=32, w=128, d=64, base=16, hidden=256):
        super().__init__()
        levels = 0
        while (h >> levels) > 4:
            levels += 1
        self.levels, self.h0, self.w0 = max(levels, 1), h >> levels, w >> levels
        lc = lambda l: base * (1 << min(l, 3))
        self.c0 = lc(self.levels)
        self.fc = nn.Sequential(nn.Linear(d, hidden), lrelu(), nn.Linear(hidden, self.c0 * self.h0 * self.w0), lrelu())
        self.blocks = nn.ModuleList()
        for k in range(self.levels):
            level = self.levels - 1 - k
            self.blocks.append(nn.Sequential(conv_gn_act(lc(level + 1) + 9, lc(level)), conv_gn_act(lc(level), lc(level))))
        self.head = nn.Conv2d(base + 9, 3, 3, 1, 1)
        for level in range(self.levels + 1):
            self.register_buffer(f"dirs{level}", panorama_directions(h >> level, w >> level))
        fwhm = math.pi / h
        self.sun_sharpness = 8 * math.log(2) / (fwhm * fwhm)

    def conditioning(self, log_int, direction, level):
        dirs = getattr(self, f"dirs{level}")
        n, (h, w) = direction.shape[0], dirs.shape[2:]
        cos = (dirs * direction[:, :, None, None]).sum(1, keepdim=True)
        maps = [dirs.expand(n, 3, h, w)] + [torch.exp((cos - 1) * s) for s in self.SHARP]
        maps.append((log_int / 8)[:, :, None, None].expand(n, 3, h, w))
        return torch.cat(maps, 1)

    def forward(self, log_int, direction, latent):
        f = torch.cat([log_int, direction, latent], 1)
        x = self.fc(f).reshape(f.shape[0], self.c0, self.h0, self.w0)
        for k, block in enumerate(self.blocks):
            x = F.interpolate(x, scale_factor=2, mode="bilinear", align_corners=False)
            x = block(torch.cat([x, self.conditioning(log_int, direction, self.levels - 1 - k)], 1))
        log_net = self.head(torch.cat([x, self.conditioning(log_int, direction, 0)], 1))
        cos = (self.dirs0 * direction[:, :, None, None]).sum(1, keepdim=True)
        log_sun = log_int[:, :, None, None] + (cos - 1) * self.sun_sharpness
        return torch.logsumexp(torch.stack([log_net, log_sun], 0), 0)


def conv_block3d(cin, cout):
    return nn.Sequential(nn.Conv3d(cin, cout, 3, 1, 1, bias=False), nn.GroupNorm(4, cout), lrelu(),
                         nn.Conv3d(cout, cout, 3, 1, 1, bias=False), nn.GroupNorm(4, cout), lrelu())


class UNet3D(nn.Module):
    def __init__(self, cin=12, cout=8, base=8, depth=3):
        super().__init__()
        ch = [base << i for i in range(depth + 1)]
        self.enc = nn.ModuleList([conv_block3d(cin if i == 0 else ch[i - 1], ch[i]) for i in range(depth + 1)])
        self.up = nn.ModuleList([nn.Conv3d(ch[i + 1], ch[i], 3, 1, 1) for i in reversed(range(depth))])
        self.dec = nn.ModuleList([conv_block3d(2 * ch[i], ch[i]) for i in reversed(range(depth))])
        self.head = nn.Conv3d(base, cout, 1)

    def forward(self, x):
        skips, y = [], x
        for i, block in enumerate(self.enc):
            y = block(F.max_pool3d(y, 2) if i > 0 else y)
            skips.append(y)
        for j in range(len(self.dec)):
            y = self.up[j](F.interpolate(y, scale_factor=2, mode="nearest"))
            y = self.dec[j](torch.cat([y, skips[-2 - j]], 1))
        return self.head(y)


class LightingPredictor(nn.Module):
    def __init__(self):
        super().__init__()
        self.backbone = ResNet18()
        self.sky_head = nn.Sequential(nn.Linear(512, 256), nn.ReLU(), nn.Linear(256, 64))
        self.sky_decoder = SkyDecoder()
        for p in self.sky_decoder.parameters():
            p.requires_grad_(False)
        self.volume_mlp = nn.Sequential(nn.Linear(512, 256), nn.ReLU(), nn.Linear(256, 8 * 8 * 8 * 2))
        self.volume_unet = UNet3D()

    def forward(self, image, rgba):
        g = self.backbone(image)
        raw = self.sky_head(g)
        log_env = self.sky_decoder(raw[:, :3] + 5.0, F.normalize(raw[:, 3:6], dim=1, eps=1e-8), raw[:, 6:])
        coarse = self.volume_mlp(g).reshape(g.shape[0], 8, 8, 8, 2)
        coarse = F.interpolate(coarse, scale_factor=8, mode="trilinear", align_corners=False)
        r = self.volume_unet(torch.cat([coarse, rgba], 1))
        vsg = torch.cat([F.softplus(r[:, 0:3]), r[:, 3:6], F.softplus(r[:, 6:7]) + 1e-3, torch.sigmoid(r[:, 7:8])], 1)
        return log_env, vsg


def torch_step_ms(batch, rounds):
    torch.manual_seed(0)
    net = LightingPredictor()
    net.train()
    net.sky_decoder.eval()
    opt = torch.optim.AdamW([p for p in net.parameters() if p.requires_grad], lr=1e-4, weight_decay=1e-4)
    image, rgba = torch.rand(batch, 3, 128, 256), torch.rand(batch, 4, 64, 64, 16)

    def step():
        opt.zero_grad(set_to_none=True)
        log_env, vsg = net(image, rgba)
        (log_env.square().mean() + vsg.square().mean()).backward()
        opt.step()

    step()
    best = math.inf
    for _ in range(rounds * 5):
        t0 = time.perf_counter()
        step()
        best = min(best, (time.perf_counter() - t0) * 1e3)
    return best


def ours_step(build, batch, threads):
    env = {"OMP_NUM_THREADS": str(threads), "PATH": "/usr/bin:/bin"}
    out = subprocess.run([f"{build}/tools/streetlight-bench", "predictor-step", "--batch", str(batch), "--json"],
                         check=True, capture_output=True, text=True, env=env).stdout
    return json.loads(out.strip().splitlines()[-1])


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("build")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--batch", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=3, help="alternate ours and PyTorch this many times")
    anchor_allocator.add_argument(ap)
    args = ap.parse_args()
    allocator = anchor_allocator.use(args.allocator)
    torch.set_num_threads(args.threads)
    best_t, best_o = math.inf, None
    for _ in range(args.rounds):
        o = ours_step(args.build, args.batch, args.threads)
        if best_o is None or o["ms"] < best_o["ms"]:
            best_o = o
        best_t = min(best_t, torch_step_ms(args.batch, 1))
    n_params = sum(p.numel() for p in LightingPredictor().parameters() if p.requires_grad)
    print(f"lighting predictor training step, batch {args.batch}, {args.threads} threads, allocator {allocator}; trainable parameters: "
          f"PyTorch mirror {n_params}, ours {best_o.get('trainable_params')}")
    print(f"{'':10s} {'ms/step':>10s}")
    print(f"{'pytorch':10s} {best_t:10.1f}")
    print(f"{'ours':10s} {best_o['ms']:10.1f}   (peak tensors {best_o['peak_tensor_mb']:.0f} MB)")
    print(f"speed ratio ours/pytorch (time_pytorch / time_ours): {best_t / best_o['ms']:.2f}")


if __name__ == "__main__":
    sys.exit(main())
