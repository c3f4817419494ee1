// streetlight-bench ops: throughput of the autodiff engine's core kernels.
// One JSON object per line with --json: {"op", "shape", "pass", "ms", "gflops"}.
// FLOP counts: matmul 2·M·N·K; an elementwise op counts 1 per element (so the chain's figure
// is elementwise ops per second, in G); forward+backward counts the backward's own work.
#include <omp.h>

#include <cstdio>

#include "autodiff/ops.h"
#include "tools/bench/bench.h"
#include "tools/bench/timing.h"

namespace sl::bench {
namespace {

void emit(bool json, const char* op, const std::string& shape, const char* pass, double ms, double flops) {
  const double gflops = flops / (ms * 1e6);
  if (json)
    std::printf("{\"op\": \"%s\", \"shape\": \"%s\", \"pass\": \"%s\", \"threads\": %d, \"ms\": %.3f, \"gflops\": %.2f}\n",
                op, shape.c_str(), pass, omp_get_max_threads(), ms, gflops);
  else
    std::printf("%-28s %-22s %-17s %9.3f ms %9.2f GFLOP/s\n", op, shape.c_str(), pass, ms, gflops);
  std::fflush(stdout);
}

// Runs the core-kernel benchmarks; also used by the conv section of the same command.
int run_ops(const std::vector<std::string>& args) {
  bool json = false;
  for (const auto& a : args) {
    if (a == "--json") json = true;
    else if (a == "--help" || a == "-h") {
      std::printf(
          "usage: streetlight-bench ops [--json]\n"
          "  Times matmul 1024x1024x1024 (f32, forward and forward+backward) and a 16M-element\n"
          "  elementwise chain (forward and forward+backward), best of 5 after a warm-up.\n"
          "  Threads: OMP_NUM_THREADS. Compare with PyTorch: scripts/compare_torch_ops.py.\n");
      return 0;
    } else {
      fail("ops: unknown option '", a, "' (try --help)");
    }
  }
  {
    const int64_t n = 1024;
    Tensor a = Tensor::uniform({n, n}, -1, 1, 1), b = Tensor::uniform({n, n}, -1, 1, 2);
    const double flops = 2.0 * n * n * n;
    double ms = best_ms([&] { matmul(a, b); });
    emit(json, "matmul", "1024x1024x1024", "forward", ms, flops);
    a.set_requires_grad(true);
    b.set_requires_grad(true);
    ms = best_ms([&] {
      backward(sum(matmul(a, b)));
      a.zero_grad();
      b.zero_grad();
    });
    emit(json, "matmul", "1024x1024x1024", "forward_backward", ms, 3 * flops);
  }
  {
    const int64_t n = 16 << 20;
    Tensor x = Tensor::uniform({n}, -2, 2, 3);
    // y = tanh(exp(0.5·x) · sigmoid(x) + x): 5 elementwise ops.
    auto chain = [&] { return tanh(add(mul(exp(mul_scalar(x, 0.5)), sigmoid(x)), x)); };
    double ms = best_ms([&] { chain(); });
    emit(json, "elementwise_chain", "16777216", "forward", ms, 5.0 * n);
    x.set_requires_grad(true);
    ms = best_ms([&] {
      backward(sum(chain()));
      x.zero_grad();
    });
    emit(json, "elementwise_chain", "16777216", "forward_backward", ms, 3 * 5.0 * n);
    x.set_requires_grad(false);
    ms = best_ms([&] { sum(x); });
    emit(json, "sum", "16777216", "forward", ms, 1.0 * n);
  }
  return 0;
}

const Registrar reg("ops", "autodiff kernel throughput: matmul, elementwise chain, sum", &run_ops);

}  // namespace
}  // namespace sl::bench
