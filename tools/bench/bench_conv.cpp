// streetlight-bench conv [--json]: see bench_conv.h.
#include "tools/bench/bench_conv.h"

#include <omp.h>

#include <algorithm>
#include <cstdlib>
#include <ctime>
#include <cstdio>
#include <string>
#include <vector>

#include "autodiff/ops.h"
#include "nn/functional/conv.h"
#include "nn/functional/depthwise_conv.h"
#include "tools/bench/bench.h"
#include "tools/bench/timing.h"

namespace sl::bench {
namespace {

struct ConvCase {
  const char* name;
  Shape x, w;
  int64_t stride, pad;
  bool depthwise = false;  // nn::depthwise_conv2d, w [C, 1, k, k]
};

// The shapes the method's networks spend their time in: a ResNet 3×3 block, the 3D UNet's
// levels, and the ResNet stem.
const std::vector<ConvCase>& conv_cases() {
  static const std::vector<ConvCase> cases = {
      {"conv2d_n8_c64_64x64_k3", {8, 64, 64, 64}, {64, 64, 3, 3}, 1, 1},
      {"conv3d_n2_c32_32x32x32_k3", {2, 32, 32, 32, 32}, {32, 32, 3, 3, 3}, 1, 1},
      {"conv2d_n4_c3_128x256_k7s2", {4, 3, 128, 256}, {64, 3, 7, 7}, 2, 3},
      {"conv3d_n1_c16_64x64x16_k3", {1, 16, 64, 64, 16}, {16, 16, 3, 3, 3}, 1, 1},
  };
  return cases;
}

// The distinct convolutions of the ResNet-18 benchmarked by `networks` (batch 4×3×128×256), with
// how many times each runs per forward pass: for attributing the network's time to its layers.
const std::vector<ConvCase>& resnet18_layer_cases() {
  static const std::vector<ConvCase> cases = {
      {"r18_stem_x1", {4, 3, 128, 256}, {64, 3, 7, 7}, 2, 3},
      {"r18_l1_3x3_x4", {4, 64, 32, 64}, {64, 64, 3, 3}, 1, 1},
      {"r18_l2_3x3s2_x1", {4, 64, 32, 64}, {128, 64, 3, 3}, 2, 1},
      {"r18_l2_1x1s2_x1", {4, 64, 32, 64}, {128, 64, 1, 1}, 2, 0},
      {"r18_l2_3x3_x3", {4, 128, 16, 32}, {128, 128, 3, 3}, 1, 1},
      {"r18_l3_3x3s2_x1", {4, 128, 16, 32}, {256, 128, 3, 3}, 2, 1},
      {"r18_l3_1x1s2_x1", {4, 128, 16, 32}, {256, 128, 1, 1}, 2, 0},
      {"r18_l3_3x3_x3", {4, 256, 8, 16}, {256, 256, 3, 3}, 1, 1},
      {"r18_l4_3x3s2_x1", {4, 256, 8, 16}, {512, 256, 3, 3}, 2, 1},
      {"r18_l4_1x1s2_x1", {4, 256, 8, 16}, {512, 256, 1, 1}, 2, 0},
      {"r18_l4_3x3_x3", {4, 512, 4, 8}, {512, 512, 3, 3}, 1, 1},
  };
  return cases;
}

// The depthwise 3×3 layers of a MobileNetV2 on the 128×256 input, batch 4 (input sizes; the
// stride-2 layers halve them).
const std::vector<ConvCase>& mobilenet_v2_depthwise_cases() {
  static const std::vector<ConvCase> cases = {
      {"mnv2_dw_c32_64x128", {4, 32, 64, 128}, {32, 1, 3, 3}, 1, 1, true},
      {"mnv2_dw_c96_64x128_s2", {4, 96, 64, 128}, {96, 1, 3, 3}, 2, 1, true},
      {"mnv2_dw_c144_32x64", {4, 144, 32, 64}, {144, 1, 3, 3}, 1, 1, true},
      {"mnv2_dw_c144_32x64_s2", {4, 144, 32, 64}, {144, 1, 3, 3}, 2, 1, true},
      {"mnv2_dw_c384_8x16", {4, 384, 8, 16}, {384, 1, 3, 3}, 1, 1, true},
      {"mnv2_dw_c960_4x8", {4, 960, 4, 8}, {960, 1, 3, 3}, 1, 1, true},
  };
  return cases;
}

Tensor run_conv(const ConvCase& c, const Tensor& x, const Tensor& w, const Tensor& b) {
  if (c.depthwise) return nn::depthwise_conv2d(x, w, b, {c.stride, c.stride}, {c.pad, c.pad});
  if (c.x.size() == 4) return nn::conv2d(x, w, b, {c.stride, c.stride}, {c.pad, c.pad});
  return nn::conv3d(x, w, b, {c.stride, c.stride, c.stride}, {c.pad, c.pad, c.pad});
}

int run_conv_command(const std::vector<std::string>& args) {
  bool json = false, resnet_layers = false, depthwise = false;
  std::string only;
  int repeat = 5;
  bool cpu_time = false;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "--only" && i + 1 < args.size()) {
      only = args[++i];
    } else if (a == "--cpu-time") {
      cpu_time = true;
    } else if (a == "--repeat" && i + 1 < args.size()) {
      repeat = std::max(1, std::atoi(args[++i].c_str()));
    } else if (a == "--json") {
      json = true;
    } else if (a == "--resnet18-layers") {
      resnet_layers = true;
    } else if (a == "--depthwise") {
      depthwise = true;
    } else if (a == "--help" || a == "-h") {
      std::printf("usage: streetlight-bench conv [--json] [--resnet18-layers | --depthwise]\n  forward and forward+backward GFLOP/s of "
                  "conv2d/conv3d on the PyTorch comparison shapes (OMP_NUM_THREADS threads)\n"
                  "  --resnet18-layers: the distinct convolutions of the `networks` ResNet-18 instead\n"
                  "  --depthwise: a MobileNetV2's depthwise 3x3 layers (depthwise_conv2d) instead\n"
                  "  --only NAME: just the case NAME (for profiling)\n  --repeat N: best of N runs (default 5)\n"
                  "  --cpu-time: process CPU time instead of wall time (with OMP_NUM_THREADS=1, a figure\n"
                  "    that other processes' load on the machine disturbs less)\n");
      return 0;
    } else {
      std::fprintf(stderr, "error: conv: unknown option '%s' (try --help)\n", a.c_str());
      return 2;
    }
  }
  const ConvSet set = depthwise ? ConvSet::MobileNetV2Depthwise
                                : resnet_layers ? ConvSet::ResNet18Layers : ConvSet::Comparison;
  return run_conv_benchmarks(json, set, only, repeat, cpu_time);
}

const Registrar reg("conv", "conv2d/conv3d forward and forward+backward GFLOP/s", &run_conv_command);

}  // namespace

int run_conv_benchmarks(bool json, ConvSet set, const std::string& only, int repeat, bool cpu_time) {
  auto best_ms = [cpu_time](auto&& f, int runs) {
    if (!cpu_time) return bench::best_ms(f, runs);
    auto cpu_ms = [] {
      timespec ts{};
      clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
      return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
    };
    f();
    double best = 1e300;
    for (int i = 0; i < runs; ++i) {
      const double t0 = cpu_ms();
      f();
      best = std::min(best, cpu_ms() - t0);
    }
    return best;
  };
  const std::vector<ConvCase>& cases = set == ConvSet::ResNet18Layers         ? resnet18_layer_cases()
                                       : set == ConvSet::MobileNetV2Depthwise ? mobilenet_v2_depthwise_cases()
                                                                              : conv_cases();
  for (const ConvCase& c : cases) {
    if (!only.empty() && only != c.name) continue;
    Tensor x = Tensor::normal(c.x, 0, 1, 1);
    Tensor w = Tensor::normal(c.w, 0, 0.1, 2);
    Tensor b = Tensor::normal({c.w[0]}, 0, 0.1, 3);
    x.set_requires_grad(true);
    w.set_requires_grad(true);
    b.set_requires_grad(true);
    Tensor y0;
    {
      NoGradGuard ng;
      y0 = run_conv(c, x, w, b);
    }
    int64_t macs_per_out = c.w[1];
    for (size_t d = 2; d < c.w.size(); ++d) macs_per_out *= c.w[d];
    const double flops = 2.0 * static_cast<double>(y0.numel()) * static_cast<double>(macs_per_out);
    const Tensor dy = Tensor::normal(y0.shape(), 0, 1, 4);
    y0 = Tensor();
    const double fwd = best_ms(
        [&] {
          NoGradGuard ng;
          Tensor y = run_conv(c, x, w, b);
        },
        repeat);
    const double fb = best_ms(
        [&] {
          Tensor y = run_conv(c, x, w, b);
          backward(y, dy);
          x.zero_grad();
          w.zero_grad();
          b.zero_grad();
        },
        repeat);
    const std::string shape = cat(shape_str(c.x), " * ", shape_str(c.w), " stride ", c.stride, " pad ", c.pad);
    for (int pass = 0; pass < 2; ++pass) {
      const double ms = pass == 0 ? fwd : fb;
      const double gflops = (pass == 0 ? flops : 3 * flops) / (ms * 1e6);
      const char* pname = pass == 0 ? "forward" : "forward_backward";
      if (json)
        std::printf("{\"op\": \"%s\", \"pass\": \"%s\", \"shape\": \"%s\", \"threads\": %d, \"ms\": %.3f, "
                    "\"gflops\": %.2f}\n",
                    c.name, pname, shape.c_str(), omp_get_max_threads(), ms, gflops);
      else
        std::printf("%-28s %-17s %9.3f ms %8.1f GFLOP/s\n", c.name, pname, ms, gflops);
      std::fflush(stdout);
    }
  }
  return 0;
}

}  // namespace sl::bench
