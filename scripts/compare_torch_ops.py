#!/usr/bin/python3
"""Side-by-side convolution speed: Streetlight vs PyTorch 1.13 (CPU, oneDNN), same machine and threads.

Usage (Debian's python3-torch; the pyenv `python3` on PATH has no torch):
  /usr/bin/python3 scripts/compare_torch_ops.py [build/tools/streetlight-bench] [--threads 2]
      [--repeat 5] [--rounds 3] [--skip-networks] [--skip-train] [--ours-networks-cmd "CMD"] [--cpu-time]
      [--allocator jemalloc|system]

Runs the four benchmark convolutions in PyTorch with torch.set_num_threads(threads), then
`streetlight-bench conv --json` with OMP_NUM_THREADS=threads in the same invocation, and prints
GFLOP/s of both with per-shape ratios (ours / torch) and their geometric mean. FLOPs =
2·N·Cout·Cin·k^d·(output voxels) per pass; forward+backward (input, weight and bias gradients)
counts three passes. Both sides report the best of `repeat` runs after a warm-up, and the two
sides alternate for `rounds` rounds (best kept), so that a burst of load from other processes
does not fall on one side only.

The same for a MobileNetV2's six depthwise 3x3 layers (`streetlight-bench conv --depthwise --json`
against F.conv2d with groups = channels); their ratio is torch ms / ours ms.

Then the autodiff core (`streetlight-bench ops`: matmul, the elementwise chain
tanh(exp(x/2)·σ(x)+x) on 16M floats forward and forward+backward), the networks (a ResNet-18,
BasicBlock, batch 4×3×128×256, and a UNet3D, base 16, 3 levels, 1×16×64×64×16, forward+backward;
ours from `streetlight-bench networks --json` or --ours-networks-cmd) and the default lighting
predictor's AdamW training step (scripts/compare_torch_train.py's two sides). Every part runs in
each round, torch and ours back to back, and the last lines print every PyTorch row of the README's
table with its ratio.

--cpu-time (with --threads 1): both sides are timed in process CPU time instead of wall time
(time.process_time; `conv --cpu-time`, `networks --cpu-time`), a figure that other processes' load
on a shared machine distorts far less; the core ops and the training step, which have no CPU-time
mode on our side, are left out.

--allocator: both sides run with jemalloc that never returns memory (the default when Debian's
libjemalloc2 is installed) or with glibc's malloc; scripts/anchor_allocator.py says why.
"""
import argparse
import json
import math
import os
import shlex
import subprocess
import sys
import time

import torch
import torch.nn as nn
import torch.nn.functional as F

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from torch_mirrors import ResNet18  # noqa: E402
import anchor_allocator  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# name, x shape, weight shape, stride, padding — must match tools/bench/bench_conv.cpp.
SHAPES = [
    ("conv2d_n8_c64_64x64_k3", (8, 64, 64, 64), (64, 64, 3, 3), 1, 1),
    ("conv3d_n2_c32_32x32x32_k3", (2, 32, 32, 32, 32), (32, 32, 3, 3, 3), 1, 1),
    ("conv2d_n4_c3_128x256_k7s2", (4, 3, 128, 256), (64, 3, 7, 7), 2, 3),
    ("conv3d_n1_c16_64x64x16_k3", (1, 16, 64, 64, 16), (16, 16, 3, 3, 3), 1, 1),
]

# A MobileNetV2's depthwise 3x3 layers on the 128x256 input, batch 4 (groups = channels) — must
# match tools/bench/bench_conv.cpp's mobilenet_v2_depthwise_cases (`conv --depthwise`).
DEPTHWISE_SHAPES = [
    ("mnv2_dw_c32_64x128", (4, 32, 64, 128), (32, 1, 3, 3), 1, 1),
    ("mnv2_dw_c96_64x128_s2", (4, 96, 64, 128), (96, 1, 3, 3), 2, 1),
    ("mnv2_dw_c144_32x64", (4, 144, 32, 64), (144, 1, 3, 3), 1, 1),
    ("mnv2_dw_c144_32x64_s2", (4, 144, 32, 64), (144, 1, 3, 3), 2, 1),
    ("mnv2_dw_c384_8x16", (4, 384, 8, 16), (384, 1, 3, 3), 1, 1),
    ("mnv2_dw_c960_4x8", (4, 960, 4, 8), (960, 1, 3, 3), 1, 1),
]


CLOCK = time.perf_counter  # time.process_time with --cpu-time


def cpu_model_name():
    """lscpu's model name (from /proc/cpuinfo), so that every figure names its machine."""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return "unknown CPU"


def best_ms(fn, repeat):
    fn()  # warm-up (oneDNN primitive creation, allocator)
    best = float("inf")
    for _ in range(repeat):
        t0 = CLOCK()
        fn()
        best = min(best, (CLOCK() - t0) * 1e3)
    return best


def torch_conv(repeat, shapes=SHAPES, depthwise=False):
    rows = {}
    for name, xs, ws, stride, pad in shapes:
        base = F.conv2d if len(xs) == 4 else F.conv3d
        groups = xs[1] if depthwise else 1

        def conv(x, w, b, stride, pad, base=base, groups=groups):
            return base(x, w, b, stride, pad, 1, groups)
        x = torch.randn(*xs, requires_grad=True)
        w = (torch.randn(*ws) * 0.1).requires_grad_(True)
        b = torch.zeros(ws[0], requires_grad=True)
        with torch.no_grad():
            y0 = conv(x, w, b, stride, pad)
        flops = 2.0 * y0.numel() * math.prod(ws[1:])
        dy = torch.randn_like(y0)

        def forward():
            with torch.no_grad():
                conv(x, w, b, stride, pad)

        def forward_backward():
            x.grad = w.grad = b.grad = None
            conv(x, w, b, stride, pad).backward(dy)

        for pass_name, fn, passes in (("forward", forward, 1), ("forward_backward", forward_backward, 3)):
            ms = best_ms(fn, repeat)
            rows[(name, pass_name)] = {"ms": ms, "gflops": passes * flops / (ms * 1e6)}
    return rows


def ours_conv(bench, threads, cpu_time=False, depthwise=False):
    env = dict(os.environ, OMP_NUM_THREADS=str(threads))
    cmd = [bench, "conv", "--json"] + (["--cpu-time"] if cpu_time else []) + (["--depthwise"] if depthwise else [])
    out = subprocess.run(cmd, env=env, check=True, capture_output=True, text=True).stdout
    rows = {}
    for line in out.splitlines():
        if line.strip().startswith("{"):
            r = json.loads(line)
            rows[(r["op"], r["pass"])] = r
    return rows


# ---------------------------------------------------------------- networks (PyTorch side)
def conv_block3d(cin, cout):
    """nn/modules/unet.h ConvBlock: (conv 3x3x3 without bias, BatchNorm, ReLU) twice."""
    return nn.Sequential(nn.Conv3d(cin, cout, 3, 1, 1, bias=False), nn.BatchNorm3d(cout), nn.ReLU(),
                         nn.Conv3d(cout, cout, 3, 1, 1, bias=False), nn.BatchNorm3d(cout), nn.ReLU())


class UNet3D(nn.Module):
    """Mirrors sl::nn::UNet(3, {in 16, out 8, base 16, depth 2, norm batch, upsample nearest}): three
    levels (16, 32, 64 channels); a decoder level is Upsample x2 + conv 3x3x3, then a ConvBlock over
    [up, skip]; a 1x1x1 head."""

    def __init__(self, cin=16, cout=8, base=16):
        super().__init__()
        self.enc = nn.ModuleList([conv_block3d(cin, base), conv_block3d(base, 2 * base), conv_block3d(2 * base, 4 * base)])
        self.up = nn.ModuleList([nn.Conv3d(4 * base, 2 * base, 3, 1, 1), nn.Conv3d(2 * base, base, 3, 1, 1)])
        self.dec = nn.ModuleList([conv_block3d(4 * base, 2 * base), conv_block3d(2 * base, base)])
        self.head = nn.Conv3d(base, cout, 1)

    def forward(self, x):
        skips, y = [], x
        for i, block in enumerate(self.enc):
            y = block(F.max_pool3d(y, 2) if i > 0 else y)
            skips.append(y)
        for j in range(2):
            y = self.up[j](F.interpolate(y, scale_factor=2, mode="nearest"))
            y = self.dec[j](torch.cat([y, skips[-2 - j]], 1))
        return self.head(y)


def torch_networks(repeat):
    torch.manual_seed(0)
    nets = {"resnet18": (ResNet18(head=64), torch.randn(4, 3, 128, 256)),
            "unet3d": (UNet3D(), torch.randn(1, 16, 64, 64, 16))}
    rows = {}
    for name, (net, x) in nets.items():
        net.train()

        def step():
            net.zero_grad(set_to_none=True)
            net(x).square().mean().backward()

        rows[name] = best_ms(step, max(2, repeat // 2))
    return rows


def ours_networks(cmd):
    out = subprocess.run(shlex.split(cmd), check=True, capture_output=True, text=True).stdout
    rows = {}
    for line in out.splitlines():
        if line.strip().startswith("{"):
            r = json.loads(line)
            if "network" in r:
                rows[r["network"]] = r["ms"]
    return rows


def torch_core_ops(repeat):
    """The autodiff kernels of `streetlight-bench ops`: matmul 1024^3 and the elementwise chain
    y = tanh(exp(0.5 x) * sigmoid(x) + x) over 16M elements, forward and forward+backward."""
    rows = {}
    a, b = torch.rand(1024, 1024) * 2 - 1, torch.rand(1024, 1024) * 2 - 1
    flops = 2.0 * 1024 ** 3
    ms = best_ms(lambda: a @ b, repeat)
    rows[("matmul", "forward")] = flops / (ms * 1e6), ms
    a.requires_grad_(True)
    b.requires_grad_(True)

    def mm_step():
        a.grad = b.grad = None
        (a @ b).sum().backward()
    ms = best_ms(mm_step, repeat)
    rows[("matmul", "forward_backward")] = 3 * flops / (ms * 1e6), ms
    x = torch.rand(16 << 20) * 4 - 2
    chain = lambda: torch.tanh(torch.exp(0.5 * x) * torch.sigmoid(x) + x)
    n = float(16 << 20)
    ms = best_ms(chain, repeat)
    rows[("elementwise_chain", "forward")] = 5 * n / (ms * 1e6), ms
    x.requires_grad_(True)

    def chain_step():
        x.grad = None
        chain().sum().backward()
    ms = best_ms(chain_step, repeat)
    rows[("elementwise_chain", "forward_backward")] = 15 * n / (ms * 1e6), ms
    x.requires_grad_(False)
    ms = best_ms(lambda: x.sum(), repeat)
    rows[("sum", "forward")] = n / (ms * 1e6), ms
    return rows


def ours_core_ops(bench, threads):
    env = dict(os.environ, OMP_NUM_THREADS=str(threads))
    out = subprocess.run([bench, "ops", "--json"], env=env, check=True, capture_output=True, text=True).stdout
    rows = {}
    for line in out.splitlines():
        if line.startswith("{"):
            r = json.loads(line)
            rows[(r["op"], r["pass"])] = (r["gflops"], r["ms"])
    return rows


def best_rows(rows_list, key_ms):
    """Per key, the row with the smallest time over all rounds."""
    best = {}
    for rows in rows_list:
        for key, r in rows.items():
            if key not in best or key_ms(r) < key_ms(best[key]):
                best[key] = r
    return best


def geomean(named_ratios):
    """Geometric mean of the ratios of [(name, ratio)], or None when empty."""
    rs = [r for _, r in named_ratios]
    return math.exp(sum(math.log(r) for r in rs) / len(rs)) if rs else None


def conv_table(title, shapes, theirs, ours):
    """Prints one row per shape and pass (ratio = torch ms / ours ms, the GFLOP/s ratio) and each
    pass's geometric mean; returns {pass: [(name, ratio)]}."""
    print(f"{title:28s} {'pass':17s} {'torch ms':>9s} {'torch GF/s':>10s} {'ours ms':>9s} {'ours GF/s':>10s} {'ratio':>6s}")
    ratios = {"forward": [], "forward_backward": []}
    for name, *_ in shapes:
        for pass_name in ratios:
            t, o = theirs[(name, pass_name)], ours.get((name, pass_name))
            if o is None:
                print(f"{name:28s} {pass_name:17s} {t['ms']:9.2f} {t['gflops']:10.1f} {'missing':>9s}")
                continue
            ratio = t["ms"] / o["ms"]
            ratios[pass_name].append((name, ratio))
            print(f"{name:28s} {pass_name:17s} {t['ms']:9.2f} {t['gflops']:10.1f} {o['ms']:9.2f} "
                  f"{o['gflops']:10.1f} {ratio:6.2f}")
    for pass_name, rs in ratios.items():
        if rs:
            print(f"geometric mean ratio ({pass_name}): {geomean(rs):.2f}   min {min(r for _, r in rs):.2f}")
    return ratios


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("bench", nargs="?", default=os.path.join(ROOT, "build", "tools", "streetlight-bench"))
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--rounds", type=int, default=3, help="alternating torch/ours rounds; best of all kept")
    ap.add_argument("--skip-networks", action="store_true")
    ap.add_argument("--skip-train", action="store_true", help="leave out the predictor training step")
    ap.add_argument("--ours-networks-cmd", default=None,
                    help="command printing JSON lines {\"network\": ..., \"ms\": ...} for our networks "
                         "(default: BENCH networks --json)")
    ap.add_argument("--cpu-time", action="store_true",
                    help="process CPU time on both sides (needs --threads 1); leaves out core ops and training")
    anchor_allocator.add_argument(ap)
    args = ap.parse_args()
    allocator = anchor_allocator.use(args.allocator)
    if args.cpu_time and args.threads != 1:
        print("error: --cpu-time needs --threads 1 (CPU time of several threads counts their waiting)", file=sys.stderr)
        return 2
    if args.cpu_time:
        global CLOCK
        CLOCK = time.process_time
        args.skip_train = True
    if not os.path.exists(args.bench):
        print(f"error: benchmark executable not found: {args.bench}", file=sys.stderr)
        return 2
    if args.threads < 1 or args.rounds < 1 or args.repeat < 1:
        print("error: --threads, --rounds and --repeat must be >= 1", file=sys.stderr)
        return 2
    torch.set_num_threads(args.threads)
    networks_cmd = args.ours_networks_cmd or (f"env OMP_NUM_THREADS={args.threads} {shlex.quote(args.bench)} networks --json"
                                              + (" --cpu-time" if args.cpu_time else ""))
    build = os.path.dirname(os.path.dirname(os.path.abspath(args.bench)))
    print(f"# torch {torch.__version__}, {args.threads} threads, {args.rounds} interleaved rounds, "
          f"{'process CPU' if args.cpu_time else 'wall'} time; allocator {allocator}; ours: {args.bench}; CPU: {cpu_model_name()}",
          file=sys.stderr)
    # Alternate the two sides for several rounds and keep each side's best, so that load from
    # other processes during one side's turn does not bias the ratio.
    rounds = {k: [] for k in ("tconv", "oconv", "tdw", "odw", "tcore", "ocore", "tnet", "onet", "ttrain", "otrain")}
    for _ in range(args.rounds):
        rounds["tconv"].append(torch_conv(args.repeat))
        rounds["oconv"].append(ours_conv(args.bench, args.threads, args.cpu_time))
        rounds["tdw"].append(torch_conv(args.repeat, DEPTHWISE_SHAPES, depthwise=True))
        rounds["odw"].append(ours_conv(args.bench, args.threads, args.cpu_time, depthwise=True))
        if not args.cpu_time:
            rounds["tcore"].append(torch_core_ops(args.repeat))
            rounds["ocore"].append(ours_core_ops(args.bench, args.threads))
        if not args.skip_networks:
            rounds["tnet"].append(torch_networks(args.repeat))
            rounds["onet"].append(ours_networks(networks_cmd))
        if not args.skip_train:
            import compare_torch_train as ctt  # noqa: E402 (imports torch mirrors of the predictor)
            rounds["ttrain"].append({"step": ctt.torch_step_ms(2, 1)})
            rounds["otrain"].append({"step": ctt.ours_step(build, 2, args.threads)["ms"]})
    theirs = best_rows(rounds["tconv"], lambda r: r["ms"])
    ours = best_rows(rounds["oconv"], lambda r: r["ms"])

    summary = []  # (issue table row, ratio)
    ratios = conv_table("op", SHAPES, theirs, ours)
    summary += [(f"conv forward+backward, {name}", r) for name, r in ratios["forward_backward"]]
    gm = geomean(ratios["forward_backward"])
    if gm:
        summary.insert(0, ("conv forward+backward, geomean of the 4 shapes", gm))
    print()
    ratios = conv_table("depthwise conv (groups = C)", DEPTHWISE_SHAPES, best_rows(rounds["tdw"], lambda r: r["ms"]),
                        best_rows(rounds["odw"], lambda r: r["ms"]))
    gm = geomean(ratios["forward_backward"])
    if gm:
        summary.append((f"depthwise conv forward+backward, geomean of the {len(ratios['forward_backward'])} MobileNetV2 shapes", gm))

    print(f"\n{'autodiff op':28s} {'pass':17s} {'torch ms':>9s} {'torch G/s':>10s} {'ours ms':>9s} {'ours G/s':>10s} {'ratio':>6s}")
    tc = best_rows(rounds["tcore"], lambda r: r[1])
    oc = best_rows(rounds["ocore"], lambda r: r[1])
    for key, (tg, tms) in tc.items():
        if key in oc:
            og, oms = oc[key]
            print(f"{key[0]:28s} {key[1]:17s} {tms:9.2f} {tg:10.2f} {oms:9.2f} {og:10.2f} {og / tg:6.2f}")
            if key[0] == "elementwise_chain":
                summary.append((f"elementwise chain tanh(exp(x/2)*sigmoid(x)+x), {key[1].replace('_', '+')}", og / tg))

    if not args.skip_networks:
        nets = best_rows(rounds["tnet"], lambda ms: ms)
        mine = best_rows(rounds["onet"], lambda ms: ms)
        print(f"\n{'network (fwd+bwd)':28s} {'torch ms':>9s} {'ours ms':>9s} {'ratio':>6s}")
        for name, ms in nets.items():
            if name in mine:
                print(f"{name:28s} {ms:9.1f} {mine[name]:9.1f} {ms / mine[name]:6.2f}")
                summary.append((f"{name} forward+backward", ms / mine[name]))
            else:
                print(f"{name:28s} {ms:9.1f} {'-':>9s}   (ours missing)")
    if not args.skip_train:
        t = min(r["step"] for r in rounds["ttrain"])
        o = min(r["step"] for r in rounds["otrain"])
        print(f"\n{'predictor AdamW step (b=2)':28s} {'torch ms':>9s} {'ours ms':>9s} {'ratio':>6s}")
        print(f"{'lighting predictor':28s} {t:9.1f} {o:9.1f} {t / o:6.2f}")
        summary.append(("default predictor AdamW step", t / o))

    print(f"\nissue table (ours against PyTorch {torch.__version__}, {args.threads} threads, best of {args.rounds} "
          f"interleaved rounds; > 1 means ours is faster)")
    for row, ratio in summary:
        print(f"  {row:62s} {ratio:5.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
