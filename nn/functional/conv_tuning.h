// Cache-derived blocking for the convolution kernels (internal to nn/functional/conv*.cpp).
//
// Contract: every blocking size below is a function of the per-core data cache sizes the OS
// reports (sysconf(_SC_LEVEL1_DCACHE_SIZE) / _SC_LEVEL2_CACHE_SIZE, else
// /sys/devices/system/cpu/cpu0/cache), read once per process, and of nothing else: never of the
// thread count, so a result's bits depend on the machine's caches but are the same for any
// OMP_NUM_THREADS (the project's determinism rule). When the OS reports nothing, the sizes of the
// AMD EPYC (Zen 4) the kernels were first tuned on are assumed: 32 KiB L1d, 1 MiB L2.
// STREETLIGHT_L1D_BYTES / STREETLIGHT_L2_BYTES override the detected sizes (to reproduce another
// machine's blocking and bits, e.g. the Zen 4 sizes on an Intel host).
//
// Where each size is used and why is stated at the function; the measurements are in the commit
// messages and the comments at the call sites.
#pragma once
#include <cstdint>

namespace sl::nn::detail {

struct CacheSizes {
  int64_t l1d = 32 << 10;  // bytes per core
  int64_t l2 = 1 << 20;    // bytes per core (private or the core's share)
};
const CacheSizes& cache_sizes();

// Positions per weight-gradient chunk (conv_implicit_gemm.cpp, weight_grad_outer): a chunk's
// transposed dy (up to 64 channels, 256 B per position) is re-read for every block of taps, so it
// is kept to a quarter of L2: 1024 positions with 1 MiB (Zen 4), 2048 with 2 MiB.
int64_t weight_grad_chunk();

}  // namespace sl::nn::detail
