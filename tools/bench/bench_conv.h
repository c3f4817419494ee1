// Convolution benchmarks: forward and forward+backward GFLOP/s of nn::conv2d / nn::conv3d on
// the four shapes compared against PyTorch by scripts/compare_torch_ops.py, and of
// nn::depthwise_conv2d on a MobileNetV2's layers.
#pragma once
#include <string>

namespace sl::bench {

// Which shapes: the four PyTorch comparison shapes, the distinct convolutions of the `networks`
// ResNet-18, or the depthwise 3×3 layers of a MobileNetV2 on the same 128×256 input.
enum class ConvSet { Comparison, ResNet18Layers, MobileNetV2Depthwise };

// Prints one line per shape and pass (a JSON object with --json: op, pass, shape, ms, gflops),
// best of several runs after a warm-up. FLOPs = 2·(output elements)·Cin·k^d per pass, with Cin = 1
// for depthwise; forward+backward counts three passes. only: just the case of that name when
// not empty; repeat: runs per figure (best kept); cpu_time: process CPU time instead of wall
// time. Returns 0.
int run_conv_benchmarks(bool json, ConvSet set = ConvSet::Comparison, const std::string& only = "", int repeat = 5,
                        bool cpu_time = false);

}  // namespace sl::bench
