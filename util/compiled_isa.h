// The instruction set that the compile-time SIMD kernels of this build use.
//
// Contract: compiled_isa() names the path that the convolution micro-kernels, Winograd and the
// BVH traversal were compiled for, from the -march of this build (CMake's STREETLIGHT_ARCH):
// "avx512" (AVX-512F), "avx2" (AVX2 and FMA) or "scalar" (neither). Every translation unit of one
// build uses the same -march, so the answer is the same wherever it is asked. The float32
// transcendental functions are not covered: they choose their path at run time
// (autodiff/vector_math.h, STREETLIGHT_SIMD).
#pragma once

namespace sl {

constexpr const char* compiled_isa() {
#if defined(__AVX512F__)
  return "avx512";
#elif defined(__AVX2__) && defined(__FMA__)
  return "avx2";
#else
  return "scalar";
#endif
}

}  // namespace sl
