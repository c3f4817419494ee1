#!/usr/bin/python3
"""Writes PyTorch reference fixtures for the nn ops and grid_sample (tests/fixtures/torch/).

Run with Debian's python3-torch (1.13):  /usr/bin/python3 scripts/make_torch_fixtures.py
Each family of ops goes to one safetensors file. A case `name` stores its inputs (`name.x`,
`name.w`, ...), the output `name.out`, a fixed random weight `name.R`, and the gradients
`name.grad.<input>` of sum(out * R). The JSON list of cases (op and parameters) is in the file's
`__metadata__` under "cases". Seeded, float32, small shapes: the files total well under 2 MB.
Safetensors is written by hand (Debian has no python3-safetensors): an 8-byte little-endian
header length, the JSON header, then the raw little-endian bytes.
"""
import json
import os
import struct
import sys

import torch
import torch.nn.functional as F

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OUT_DIR = os.path.join(ROOT, "tests", "fixtures", "torch")


def write_safetensors(path, tensors, metadata):
    header, blobs, offset = {}, [], 0
    for name in sorted(tensors):
        t = tensors[name].detach().contiguous().to(torch.float32)
        data = t.numpy().astype("<f4").tobytes()
        header[name] = {"dtype": "F32", "shape": list(t.shape), "data_offsets": [offset, offset + len(data)]}
        blobs.append(data)
        offset += len(data)
    header["__metadata__"] = metadata
    text = json.dumps(header, separators=(",", ":")).encode()
    text += b" " * ((8 - len(text) % 8) % 8)
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(struct.pack("<Q", len(text)))
        f.write(text)
        for b in blobs:
            f.write(b)
    os.replace(tmp, path)


class Family:
    """Collects the cases of one fixture file."""

    def __init__(self, seed):
        self.gen = torch.Generator().manual_seed(seed)
        self.tensors, self.cases = {}, []

    def randn(self, *shape, scale=1.0):
        return torch.randn(*shape, generator=self.gen) * scale

    def uniform(self, lo, hi, *shape):
        return lo + (hi - lo) * torch.rand(*shape, generator=self.gen)

    def add(self, name, op, params, inputs, fn, extra=None, constants=()):
        """inputs: ordered dict name -> tensor (None = absent); fn(*inputs) -> output. Inputs named
        in `constants` (labels, targets) get no gradient."""
        leaves = {k: (v.clone().requires_grad_(k not in constants) if v is not None else None)
                  for k, v in inputs.items()}
        out = fn(*leaves.values())
        R = torch.randn(tuple(out.shape), generator=self.gen)  # a 0-d R for a scalar loss
        (out * R).sum().backward()
        for k, v in leaves.items():
            if v is None:
                continue
            self.tensors[f"{name}.{k}"] = v.detach()
            if v.grad is not None:
                self.tensors[f"{name}.grad.{k}"] = v.grad
        self.tensors[f"{name}.out"] = out.detach()
        self.tensors[f"{name}.R"] = R
        for k, v in (extra or {}).items():
            self.tensors[f"{name}.{k}"] = v.detach()
        self.cases.append({"name": name, "op": op, **params})

    def write(self, filename):
        write_safetensors(os.path.join(OUT_DIR, filename), self.tensors,
                          {"cases": json.dumps(self.cases), "torch": torch.__version__})


def conv_family():
    fam = Family(1)
    cases2d = [  # name, x, w, stride, padding, dilation, bias
        ("c2_s1_p1", (2, 3, 7, 8), (4, 3, 3, 3), (1, 1), (1, 1), (1, 1), True),
        ("c2_s2_p0", (2, 3, 9, 8), (5, 3, 3, 3), (2, 2), (0, 0), (1, 1), True),
        ("c2_d2_p2", (1, 2, 8, 9), (3, 2, 3, 3), (1, 1), (2, 2), (2, 2), True),
        ("c2_mixed", (2, 3, 8, 10), (4, 3, 3, 2), (2, 1), (1, 2), (1, 2), True),
        ("c2_k7s2p3", (1, 3, 12, 14), (4, 3, 7, 7), (2, 2), (3, 3), (1, 1), True),
        ("c2_1x1_nobias", (2, 4, 5, 6), (3, 4, 1, 1), (1, 1), (0, 0), (1, 1), False),
    ]
    for name, xs, ws, s, p, d, bias in cases2d:
        inputs = {"x": fam.randn(*xs), "w": fam.randn(*ws, scale=0.3), "b": fam.randn(ws[0]) if bias else None}
        fam.add(name, "conv2d", {"stride": s, "padding": p, "dilation": d}, inputs,
                lambda x, w, b, s=s, p=p, d=d: F.conv2d(x, w, b, s, p, d))
    cases3d = [
        ("c3_s1_p1", (1, 2, 5, 6, 4), (3, 2, 3, 3, 3), (1, 1, 1), (1, 1, 1), (1, 1, 1), True),
        ("c3_s2_p1", (2, 2, 6, 5, 7), (3, 2, 3, 3, 3), (2, 2, 2), (1, 1, 1), (1, 1, 1), True),
        ("c3_mixed", (1, 3, 6, 7, 5), (2, 3, 2, 3, 3), (1, 2, 1), (0, 2, 1), (2, 2, 1), False),
    ]
    for name, xs, ws, s, p, d, bias in cases3d:
        inputs = {"x": fam.randn(*xs), "w": fam.randn(*ws, scale=0.3), "b": fam.randn(ws[0]) if bias else None}
        fam.add(name, "conv3d", {"stride": s, "padding": p, "dilation": d}, inputs,
                lambda x, w, b, s=s, p=p, d=d: F.conv3d(x, w, b, s, p, d))
    fam.write("conv.safetensors")


def upsample_family():
    fam = Family(2)
    for scale in (2, 3):
        fam.add(f"nearest2d_s{scale}", "upsample_nearest2d", {"scale": scale}, {"x": fam.randn(2, 3, 4, 5)},
                lambda x, s=scale: F.interpolate(x, scale_factor=s, mode="nearest"))
        for ac in (False, True):
            fam.add(f"bilinear2d_s{scale}_ac{int(ac)}", "upsample_bilinear2d", {"scale": scale, "align_corners": ac},
                    {"x": fam.randn(2, 3, 4, 5)},
                    lambda x, s=scale, ac=ac: F.interpolate(x, scale_factor=s, mode="bilinear", align_corners=ac))
    fam.add("nearest3d_s2", "upsample_nearest3d", {"scale": 2}, {"x": fam.randn(1, 2, 3, 4, 5)},
            lambda x: F.interpolate(x, scale_factor=2, mode="nearest"))
    for ac in (False, True):
        fam.add(f"trilinear3d_s2_ac{int(ac)}", "upsample_trilinear3d", {"scale": 2, "align_corners": ac},
                {"x": fam.randn(1, 2, 3, 4, 5)},
                lambda x, ac=ac: F.interpolate(x, scale_factor=2, mode="trilinear", align_corners=ac))
    fam.write("upsample.safetensors")


def pool_family():
    fam = Family(3)
    cases = [  # name, op, x, kernel, stride, padding
        ("max2d_k3s2p1", "max_pool2d", (2, 3, 9, 8), (3, 3), (2, 2), (1, 1)),
        ("max2d_k2s2", "max_pool2d", (1, 2, 6, 7), (2, 2), (2, 2), (0, 0)),
        ("max2d_k3s1p1_mixed", "max_pool2d", (1, 2, 5, 6), (3, 2), (1, 2), (1, 1)),
        ("avg2d_k3s2p1", "avg_pool2d", (2, 3, 9, 8), (3, 3), (2, 2), (1, 1)),
        ("avg2d_k2s1", "avg_pool2d", (1, 2, 5, 6), (2, 2), (1, 1), (0, 0)),
        ("max3d_k2s2", "max_pool3d", (1, 2, 4, 6, 5), (2, 2, 2), (2, 2, 2), (0, 0, 0)),
        ("max3d_k3s1p1", "max_pool3d", (1, 2, 4, 5, 3), (3, 3, 3), (1, 1, 1), (1, 1, 1)),
        ("avg3d_k3s2p1", "avg_pool3d", (2, 2, 5, 4, 6), (3, 3, 3), (2, 2, 2), (1, 1, 1)),
    ]
    for name, op, xs, k, s, p in cases:
        fn = getattr(F, op)
        fam.add(name, op, {"kernel": k, "stride": s, "padding": p}, {"x": fam.randn(*xs)},
                lambda x, fn=fn, k=k, s=s, p=p: fn(x, k, s, p))
    fam.add("global_avg_3d", "global_avg_pool", {}, {"x": fam.randn(2, 3, 3, 4, 2)},
            lambda x: x.mean(dim=(2, 3, 4)))
    fam.write("pool.safetensors")


def norm_family():
    fam = Family(4)
    for name, xs in (("bn2d", (4, 3, 5, 5)), ("bn3d", (2, 3, 3, 4, 5)), ("bn1d", (6, 4))):
        C = xs[1]
        for training in (True, False):
            rm, rv = fam.randn(C, scale=0.5), fam.uniform(0.5, 2.0, C)
            rm_after, rv_after = rm.clone(), rv.clone()
            inputs = {"x": fam.randn(*xs, scale=2.0) + 1.0, "w": fam.uniform(0.5, 1.5, C), "b": fam.randn(C)}
            fam.add(f"{name}_{'train' if training else 'eval'}", "batch_norm",
                    {"training": training, "momentum": 0.1, "eps": 1e-5}, inputs,
                    lambda x, w, b, t=training, rm=rm_after, rv=rv_after: F.batch_norm(x, rm, rv, w, b, t, 0.1, 1e-5),
                    extra={"running_mean": rm, "running_var": rv, "running_mean_after": rm_after,
                           "running_var_after": rv_after})
    fam.add("gn_g2", "group_norm", {"groups": 2, "eps": 1e-5},
            {"x": fam.randn(2, 4, 5, 5), "w": fam.uniform(0.5, 1.5, 4), "b": fam.randn(4)},
            lambda x, w, b: F.group_norm(x, 2, w, b, 1e-5))
    fam.add("gn_g3_3d_noaffine", "group_norm", {"groups": 3, "eps": 1e-5}, {"x": fam.randn(2, 6, 3, 2, 4)},
            lambda x: F.group_norm(x, 3, None, None, 1e-5))
    fam.add("in_2d", "instance_norm", {"eps": 1e-5},
            {"x": fam.randn(2, 3, 6, 6), "w": fam.uniform(0.5, 1.5, 3), "b": fam.randn(3)},
            lambda x, w, b: F.instance_norm(x, weight=w, bias=b, eps=1e-5))
    fam.add("in_3d_noaffine", "instance_norm", {"eps": 1e-5}, {"x": fam.randn(1, 2, 3, 4, 5)},
            lambda x: F.instance_norm(x, eps=1e-5))
    fam.write("norm.safetensors")


def linear_family():
    fam = Family(5)
    fam.add("linear_3d", "linear", {}, {"x": fam.randn(3, 5, 7), "w": fam.randn(4, 7, scale=0.3), "b": fam.randn(4)},
            lambda x, w, b: F.linear(x, w, b))
    fam.add("linear_nobias", "linear", {}, {"x": fam.randn(6, 9), "w": fam.randn(5, 9, scale=0.3)},
            lambda x, w: F.linear(x, w))
    fam.write("linear.safetensors")


def grid_sample_family():
    fam = Family(6)
    for padding in ("zeros", "border"):
        for ac in (False, True):
            fam.add(f"gs2d_{padding}_ac{int(ac)}", "grid_sample_2d", {"padding": padding, "align_corners": ac},
                    {"x": fam.randn(2, 3, 5, 6), "grid": fam.uniform(-1.2, 1.2, 2, 4, 7, 2)},
                    lambda x, g, p=padding, ac=ac: F.grid_sample(x, g, "bilinear", p, ac))
            fam.add(f"gs3d_{padding}_ac{int(ac)}", "grid_sample_3d", {"padding": padding, "align_corners": ac},
                    {"x": fam.randn(1, 2, 4, 5, 3), "grid": fam.uniform(-1.2, 1.2, 1, 3, 4, 2, 3)},
                    lambda x, g, p=padding, ac=ac: F.grid_sample(x, g, "bilinear", p, ac))
    fam.write("grid_sample.safetensors")


def depthwise_conv_family():
    fam = Family(7)
    cases = [  # name, x, kernel (kh, kw), stride, padding, bias
        ("dw_s1_p1", (2, 4, 7, 8), (3, 3), (1, 1), (1, 1), True),
        ("dw_s2_p1", (2, 3, 9, 8), (3, 3), (2, 2), (1, 1), True),
        ("dw_s2_p0_nobias", (1, 5, 8, 9), (3, 3), (2, 2), (0, 0), False),
        ("dw_mixed", (2, 3, 8, 10), (3, 2), (2, 1), (1, 0), True),
        ("dw_k5_p2", (1, 2, 10, 9), (5, 5), (1, 1), (2, 2), True),
    ]
    for name, xs, k, s, p, bias in cases:
        C = xs[1]
        inputs = {"x": fam.randn(*xs), "w": fam.randn(C, 1, *k, scale=0.3), "b": fam.randn(C) if bias else None}
        fam.add(name, "depthwise_conv2d", {"stride": s, "padding": p}, inputs,
                lambda x, w, b, s=s, p=p, C=C: F.conv2d(x, w, b, s, p, 1, C))
    fam.write("depthwise_conv.safetensors")


def pointwise_family():
    """The autodiff library's unary, binary (broadcasting) and reducing ops, over the ranges the
    networks and losses reach: exp to ±20, softplus and sigmoid to ±40, log over 14 decades, expm1
    and log1p near 0. Widths of 37 leave a tail after every SIMD lane count."""
    fam = Family(8)
    def log_uniform(lo, hi, *shape):
        return torch.exp(fam.uniform(torch.log(torch.tensor(lo)).item(), torch.log(torch.tensor(hi)).item(), *shape))
    unary = [  # name, op, params, x, torch function
        ("neg", "neg", {}, fam.randn(3, 37), torch.neg),
        ("exp", "exp", {}, fam.uniform(-20, 20, 3, 37), torch.exp),
        ("log", "log", {}, log_uniform(1e-7, 1e7, 3, 37), torch.log),
        ("log1p", "log1p", {}, torch.cat([fam.uniform(-0.9, 50, 2, 37), fam.uniform(-1e-4, 1e-4, 1, 37)]), torch.log1p),
        ("expm1", "expm1", {}, torch.cat([fam.uniform(-10, 10, 2, 37), fam.uniform(-1e-4, 1e-4, 1, 37)]), torch.expm1),
        ("sqrt", "sqrt", {}, log_uniform(1e-6, 1e4, 3, 37), torch.sqrt),
        ("square", "square", {}, fam.randn(3, 37, scale=3), torch.square),
        ("abs", "abs", {}, fam.randn(3, 37), torch.abs),
        ("pow_2.2", "pow_scalar", {"p": 2.2}, fam.uniform(0.01, 5, 3, 37), lambda x: torch.pow(x, 2.2)),
        ("pow_1_over_2.2", "pow_scalar", {"p": 1 / 2.2}, fam.uniform(0.01, 5, 3, 37), lambda x: torch.pow(x, 1 / 2.2)),
        ("clamp", "clamp", {"lo": -0.5, "hi": 0.7}, fam.randn(3, 37), lambda x: torch.clamp(x, -0.5, 0.7)),
        ("relu", "relu", {}, fam.randn(3, 37, scale=3), F.relu),
        ("leaky_relu_0.2", "leaky_relu", {"slope": 0.2}, fam.randn(3, 37, scale=3), lambda x: F.leaky_relu(x, 0.2)),
        ("elu_1", "elu", {"alpha": 1.0}, fam.randn(3, 37, scale=3), lambda x: F.elu(x, 1.0)),
        ("elu_0.7", "elu", {"alpha": 0.7}, fam.randn(3, 37, scale=3), lambda x: F.elu(x, 0.7)),
        ("sigmoid", "sigmoid", {}, fam.uniform(-40, 40, 3, 37), torch.sigmoid),
        ("softplus", "softplus", {}, fam.uniform(-40, 40, 3, 37), F.softplus),
        ("tanh", "tanh", {}, fam.uniform(-10, 10, 3, 37), torch.tanh),
        ("sin", "sin", {}, fam.uniform(-10, 10, 3, 37), torch.sin),
        ("cos", "cos", {}, fam.uniform(-10, 10, 3, 37), torch.cos),
        ("acos", "acos", {}, fam.uniform(-0.99, 0.99, 3, 37), torch.acos),
    ]
    for name, op, params, x, fn in unary:
        fam.add(name, op, params, {"x": x}, fn)
    sign = lambda t: torch.where(fam.uniform(0, 1, *t.shape) < 0.5, -t, t)
    binary = [  # name, op, x, y, torch function
        ("add_broadcast", "add", fam.randn(2, 3, 37), fam.randn(3, 1), torch.add),
        ("sub_broadcast", "sub", fam.randn(2, 1, 37), fam.randn(3, 37), torch.sub),
        ("mul_broadcast", "mul", fam.randn(2, 3, 37), fam.randn(37), torch.mul),
        ("div", "div", fam.randn(3, 37), sign(fam.uniform(0.5, 3, 3, 37)), torch.div),
        ("pow", "pow", fam.uniform(0.1, 4, 3, 37), fam.uniform(-2, 3, 3, 37), torch.pow),
        ("minimum", "minimum", fam.randn(3, 37), fam.randn(3, 37), torch.minimum),
        ("maximum", "maximum", fam.randn(3, 37), fam.randn(3, 37), torch.maximum),
        ("atan2", "atan2", fam.randn(3, 37), fam.randn(3, 37), torch.atan2),
    ]
    for name, op, x, y, fn in binary:
        fam.add(name, op, {}, {"x": x, "y": y}, fn)
    reducing = [  # name, op, params, x, torch function
        ("sum_02", "sum", {"axes": [0, 2], "keepdim": False}, fam.randn(2, 3, 37), lambda x: x.sum(dim=(0, 2))),
        ("mean_1_keep", "mean", {"axes": [1], "keepdim": True}, fam.randn(2, 3, 37), lambda x: x.mean(dim=1, keepdim=True)),
        ("max_1", "max", {"axes": [1], "keepdim": False}, fam.randn(2, 37, 5), lambda x: x.amax(dim=1)),
        ("min_2_keep", "min", {"axes": [2], "keepdim": True}, fam.randn(2, 3, 37), lambda x: x.amin(dim=2, keepdim=True)),
        ("logsumexp_1", "logsumexp", {"axis": 1, "keepdim": False}, fam.randn(4, 37, scale=50),
         lambda x: torch.logsumexp(x, dim=1)),
        ("logsumexp_0_keep", "logsumexp", {"axis": 0, "keepdim": True}, fam.randn(37, 3, scale=3),
         lambda x: torch.logsumexp(x, dim=0, keepdim=True)),
        ("normalize_1", "normalize", {"axis": 1}, fam.randn(37, 3), lambda x: F.normalize(x, dim=1)),
    ]
    for name, op, params, x, fn in reducing:
        fam.add(name, op, params, {"x": x}, fn)
    fam.write("pointwise.safetensors")


def loss_family():
    """The training losses that PyTorch also has: binary cross-entropy on logits (the domain
    classifier), the cross-entropy against a soft target weighted per row (the sun distribution's
    loss, train/sun_distribution.h) and L1. Labels and targets get no gradient."""
    fam = Family(9)
    z = torch.cat([fam.uniform(-30, 30, 38), torch.tensor([-1e4, 1e4])])
    y = torch.cat([(fam.uniform(0, 1, 20) < 0.5).float(), fam.uniform(0, 1, 18), torch.tensor([1.0, 0.0])])
    fam.add("bce_with_logits", "bce_with_logits", {}, {"x": z, "y": y},
            lambda x, y: F.binary_cross_entropy_with_logits(x, y), constants=("y",))
    for name, scale in (("soft_ce", 3.0), ("soft_ce_large_logits", 80.0)):
        logits = fam.randn(5, 48, scale=scale)
        target = torch.softmax(fam.randn(5, 48, scale=2.0), dim=1)
        weights = fam.uniform(0.5, 2.0, 5)
        fam.add(name, "soft_cross_entropy", {}, {"x": logits, "y": target, "w": weights},
                lambda x, y, w: (F.cross_entropy(x, y, reduction="none") * w).mean(), constants=("y", "w"))
    fam.add("l1", "l1", {}, {"x": fam.randn(4, 37), "y": fam.randn(4, 37)}, F.l1_loss)
    fam.write("losses.safetensors")


def main():
    torch.manual_seed(0)
    torch.set_num_threads(1)
    os.makedirs(OUT_DIR, exist_ok=True)
    for family in (conv_family, upsample_family, pool_family, norm_family, linear_family, grid_sample_family,
                   depthwise_conv_family, pointwise_family, loss_family):
        family()
    total = sum(os.path.getsize(os.path.join(OUT_DIR, f)) for f in os.listdir(OUT_DIR))
    print(f"wrote {len(os.listdir(OUT_DIR))} files, {total} bytes, to {OUT_DIR}", file=sys.stderr)


if __name__ == "__main__":
    main()
