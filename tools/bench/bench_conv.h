// Convolution benchmarks: forward and forward+backward GFLOP/s of nn::conv2d / nn::conv3d on
// the four shapes compared against PyTorch by scripts/compare_torch_ops.py.
#pragma once

namespace sl::bench {

// Prints one line per shape and pass (a JSON object with --json: op, pass, shape, ms, gflops),
// best of several runs after a warm-up. FLOPs = 2·N·Cout·Cin·k^d·(output voxels) per pass;
// forward+backward counts three passes. Returns 0.
int run_conv_benchmarks(bool json);

}  // namespace sl::bench
