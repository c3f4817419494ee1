// streetlight-bench networks: forward+backward of whole networks, for the side-by-side with
// PyTorch in scripts/compare_torch_ops.py (--ours-networks-cmd "BENCH networks --json").
//   resnet18: ResNet-18 (BasicBlock, base width 64, a 512 -> 64 linear head), batch 4×3×128×256;
//   unet3d:   UNet3D {in 16, out 8, base 16, depth 2 (16/32/64 channels), batch norm, nearest
//             upsampling + conv}, input 1×16×64×64×16.
// A step is zero_grad, forward, mean(y²), backward, in train mode; the best of 5 (--repeat) after a
// warm-up, in wall time or (--cpu-time) process CPU time.
#include <omp.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "autodiff/ops.h"
#include "nn/modules/resnet.h"
#include "nn/modules/unet.h"
#include "tools/bench/bench.h"
#include "tools/bench/timing.h"

namespace sl::bench {
namespace {

int run_networks(const std::vector<std::string>& args) {
  bool json = false, cpu_time = false;
  int repeat = 5;
  std::string only;  // one network by name (profiling), else both
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "--json") json = true;
    else if (a == "--cpu-time") cpu_time = true;
    else if (a == "--repeat" && i + 1 < args.size()) repeat = std::max(1, std::atoi(args[++i].c_str()));
    else if (a == "--only" && i + 1 < args.size()) only = args[++i];
    else if (a == "--help" || a == "-h") {
      std::printf("usage: streetlight-bench networks [--json] [--repeat N] [--cpu-time] [--only resnet18|unet3d]\n"
                  "  ResNet-18 (4x3x128x256) and UNet3D (1x16x64x64x16) forward+backward, best of N (default 5).\n"
                  "  --only NAME: that network alone (for profiling one of them)\n"
                  "  --cpu-time: process CPU time instead of wall time (with OMP_NUM_THREADS=1, a figure\n"
                  "    that other processes' load distorts far less)\n");
      return 0;
    } else {
      fail("networks: unknown option '", a, "' (try --help)");
    }
  }
  if (!only.empty() && only != "resnet18" && only != "unet3d")
    fail("networks: --only must be resnet18 or unet3d, got '", only, "'");
  auto best_ms = [&](auto&& f) { return cpu_time ? bench::best_cpu_ms(f, repeat) : bench::best_ms(f, repeat); };
  auto report = [&](const char* name, double ms) {
    if (json) std::printf("{\"network\": \"%s\", \"threads\": %d, \"ms\": %.2f}\n", name, omp_get_max_threads(), ms);
    else std::printf("%-10s forward+backward %9.2f ms\n", name, ms);
    std::fflush(stdout);
  };
  if (only.empty() || only == "resnet18") {
    nn::ResNet net(nn::ResNetOptions{.depth = 18, .in_channels = 3, .base_width = 64, .num_classes = 64, .seed = 1});
    net.train();
    const Tensor x = Tensor::normal({4, 3, 128, 256}, 0, 1, 2);
    report("resnet18", best_ms([&] {
             net.zero_grad();
             backward(mean(square(net.forward(x))));
           }));
  }
  if (only.empty() || only == "unet3d") {
    nn::UNetOptions o;
    o.in_channels = 16;
    o.out_channels = 8;
    o.base_channels = 16;
    o.depth = 2;
    o.norm = "batch";
    o.upsample = "nearest";
    nn::UNet net(3, o);
    net.train();
    const Tensor x = Tensor::normal({1, 16, 64, 64, 16}, 0, 1, 3);
    report("unet3d", best_ms([&] {
             net.zero_grad();
             backward(mean(square(net.forward(x))));
           }));
  }
  return 0;
}

const Registrar reg("networks", "ResNet-18 and UNet3D forward+backward (PyTorch side-by-side)", &run_networks);

}  // namespace
}  // namespace sl::bench
