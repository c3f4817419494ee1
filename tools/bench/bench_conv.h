// Convolution benchmarks: forward and forward+backward GFLOP/s of nn::conv2d / nn::conv3d on
// the four shapes compared against PyTorch by scripts/compare_torch_ops.py.
#pragma once
#include <string>

namespace sl::bench {

// Prints one line per shape and pass (a JSON object with --json: op, pass, shape, ms, gflops),
// best of several runs after a warm-up. FLOPs = 2·N·Cout·Cin·k^d·(output voxels) per pass;
// forward+backward counts three passes. resnet18_layers: the distinct convolutions of the
// `networks` ResNet-18 instead of the four comparison shapes; only: just the case of that name
// when not empty; repeat: runs per figure (best kept); cpu_time: process CPU time instead of
// wall time. Returns 0.
int run_conv_benchmarks(bool json, bool resnet18_layers = false, const std::string& only = "", int repeat = 5,
                        bool cpu_time = false);

}  // namespace sl::bench
