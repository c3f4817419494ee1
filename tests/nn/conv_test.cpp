// conv2d / conv3d: float64 gradchecks over stride, padding, dilation, bias, size-1 dims and
// non-contiguous inputs; a direct-loop reference; determinism across thread counts; errors.
#include "nn/functional/conv.h"

#include <cmath>
#include <cstring>
#include <limits>

#include <gtest/gtest.h>
#include <omp.h>

#include "autodiff/buffer_cache.h"
#include "nn/functional/conv_implicit_gemm.h"
#include "nn/functional/conv_microkernel.h"
#include "nn/functional/conv_winograd.h"
#include "support/test_util.h"

namespace sl::test {
using nn::conv2d;
using nn::conv3d;

namespace {

// Direct 2-D convolution by its definition, in double.
std::vector<double> conv2d_reference(const Tensor& x, const Tensor& w, const Tensor& b, int64_t sh, int64_t sw,
                                     int64_t ph, int64_t pw, int64_t dh, int64_t dw, Shape& out_shape) {
  const int64_t N = x.size(0), C = x.size(1), H = x.size(2), W = x.size(3);
  const int64_t O = w.size(0), KH = w.size(2), KW = w.size(3);
  const int64_t Ho = (H + 2 * ph - dh * (KH - 1) - 1) / sh + 1, Wo = (W + 2 * pw - dw * (KW - 1) - 1) / sw + 1;
  out_shape = {N, O, Ho, Wo};
  std::vector<double> y;
  for (int64_t n = 0; n < N; ++n)
    for (int64_t o = 0; o < O; ++o)
      for (int64_t i = 0; i < Ho; ++i)
        for (int64_t j = 0; j < Wo; ++j) {
          double acc = b.defined() ? b.at({o}) : 0.0;
          for (int64_t c = 0; c < C; ++c)
            for (int64_t u = 0; u < KH; ++u)
              for (int64_t v = 0; v < KW; ++v) {
                const int64_t yy = i * sh - ph + u * dh, xx = j * sw - pw + v * dw;
                if (yy >= 0 && yy < H && xx >= 0 && xx < W) acc += x.at({n, c, yy, xx}) * w.at({o, c, u, v});
              }
          y.push_back(acc);
        }
  return y;
}

TEST(Conv2d, MatchesDirectLoopForStridePaddingDilation) {
  struct Case { int64_t s, p, d; };
  for (Case cs : {Case{1, 0, 1}, Case{1, 1, 1}, Case{2, 1, 1}, Case{2, 3, 1}, Case{1, 2, 2}, Case{3, 0, 2}}) {
    const Tensor x = rand64({2, 3, 9, 11}, 1), w = rand64({4, 3, 3, 3}, 2), b = rand64({4}, 3);
    Shape ref_shape;
    const auto ref = conv2d_reference(x, w, b, cs.s, cs.s, cs.p, cs.p, cs.d, cs.d, ref_shape);
    const Tensor y = conv2d(x, w, b, {cs.s, cs.s}, {cs.p, cs.p}, {cs.d, cs.d});
    ASSERT_EQ(y.shape(), ref_shape);
    const auto got = y.to_vector();
    for (size_t i = 0; i < ref.size(); ++i) ASSERT_NEAR(got[i], ref[i], 1e-12) << "stride " << cs.s;
  }
}

TEST(Conv2d, GradcheckStridePaddingDilation) {
  struct Case { std::array<int64_t, 2> s, p, d; };
  for (Case cs : {Case{{1, 1}, {0, 0}, {1, 1}}, Case{{1, 1}, {1, 1}, {1, 1}}, Case{{2, 1}, {1, 0}, {1, 1}},
                  Case{{2, 2}, {2, 1}, {2, 1}}, Case{{1, 3}, {0, 2}, {1, 2}}}) {
    EXPECT_GRADCHECK([&](const TensorList& in) { return conv2d(in[0], in[1], in[2], cs.s, cs.p, cs.d); },
                     {rand64({2, 2, 5, 6}, 1), rand64({2, 2, 3, 2}, 2), rand64({2}, 3)});
  }
}

TEST(Conv2d, GradcheckWithoutBiasAndPointwiseKernel) {
  EXPECT_GRADCHECK([](const TensorList& in) { return conv2d(in[0], in[1], Tensor()); },
                   {rand64({2, 3, 4, 5}, 4), rand64({5, 3, 1, 1}, 5)});
}

TEST(Conv2d, GradcheckSizeOneDimsAndNonContiguousInput) {
  // x is a permuted (non-contiguous) view; H = 1, batch 1, one output channel.
  const Tensor base = rand64({1, 5, 1, 3}, 6);
  const Tensor x = permute(base, {0, 3, 2, 1});  // [1, 3, 1, 5]
  ASSERT_FALSE(x.is_contiguous());
  EXPECT_GRADCHECK([](const TensorList& in) { return conv2d(in[0], in[1], in[2], {1, 1}, {1, 1}); },
                   {x, rand64({1, 3, 3, 3}, 7), rand64({1}, 8)});
}

TEST(Conv3d, GradcheckStridePaddingDilation) {
  struct Case { std::array<int64_t, 3> s, p, d; };
  for (Case cs : {Case{{1, 1, 1}, {1, 1, 1}, {1, 1, 1}}, Case{{2, 1, 2}, {1, 0, 1}, {1, 1, 1}},
                  Case{{1, 1, 1}, {0, 2, 1}, {1, 2, 1}}}) {
    EXPECT_GRADCHECK([&](const TensorList& in) { return conv3d(in[0], in[1], in[2], cs.s, cs.p, cs.d); },
                     {rand64({1, 2, 4, 5, 4}, 9), rand64({2, 2, 3, 3, 2}, 10), rand64({2}, 11)});
  }
}

TEST(Conv3d, GradcheckNonContiguousInputWithSizeOneDepth) {
  const Tensor base = rand64({2, 4, 3, 1, 2}, 12);
  const Tensor x = transpose(base, 1, 2);  // [2, 3, 4, 1, 2]
  ASSERT_FALSE(x.is_contiguous());
  EXPECT_GRADCHECK([](const TensorList& in) { return conv3d(in[0], in[1], in[2], {1, 1, 1}, {1, 0, 1}); },
                   {x, rand64({2, 3, 3, 1, 2}, 13), rand64({2}, 14)});
}

TEST(Conv3d, Float32MatchesFloat64) {
  const Tensor x = rand64({2, 5, 6, 7, 5}, 15), w = rand64({4, 5, 3, 3, 3}, 16), b = rand64({4}, 17);
  const Tensor y64 = conv3d(x, w, b, {1, 2, 1}, {1, 1, 0});
  const Tensor y32 = conv3d(x.to(DType::F32), w.to(DType::F32), b.to(DType::F32), {1, 2, 1}, {1, 1, 0});
  const auto a = y64.to_vector(), c = y32.to_vector();
  for (size_t i = 0; i < a.size(); ++i) ASSERT_NEAR(a[i], c[i], 1e-4);
}

// The output and all three gradients of one convolution in float32 against float64, within
// 1e-4 relative (plus 1e-4 absolute). 2-D shapes take the last two entries of s, p and d.
void expect_float32_matches_float64(const Shape& xs, const Shape& ws, const std::array<int64_t, 3>& s,
                                    const std::array<int64_t, 3>& p, const std::array<int64_t, 3>& d, uint64_t seed) {
  std::vector<std::vector<double>> results[2];
  for (int f32 = 0; f32 < 2; ++f32) {
    const DType dt = f32 ? DType::F32 : DType::F64;
    Tensor x = rand64(xs, seed).to(dt), w = rand64(ws, seed + 1).to(dt), b = rand64({ws[0]}, seed + 2).to(dt);
    for (Tensor* t : {&x, &w, &b}) t->set_requires_grad(true);
    Tensor y = xs.size() == 4 ? conv2d(x, w, b, {s[1], s[2]}, {p[1], p[2]}, {d[1], d[2]}) : conv3d(x, w, b, s, p, d);
    backward(y, rand64(y.shape(), seed + 3).to(dt));
    results[f32] = {y.to_vector(), x.grad().to_vector(), w.grad().to_vector(), b.grad().to_vector()};
  }
  for (size_t k = 0; k < 4; ++k) {
    ASSERT_EQ(results[0][k].size(), results[1][k].size());
    for (size_t i = 0; i < results[0][k].size(); ++i)
      ASSERT_NEAR(results[1][k][i], results[0][k][i], 1e-4 * (1 + std::abs(results[0][k][i])))
          << "tensor " << k << " (y, dx, dw, db) element " << i;
  }
}

// The float32 kernels (implicit GEMM on padded windows for stride 1, im2col panels otherwise)
// against the float64 path, for the output and all three gradients.
TEST(Conv, Float32KernelsMatchFloat64ForwardAndBackward) {
  struct Case { Shape x, w; std::array<int64_t, 3> s, p, d; };
  const std::vector<Case> cases = {
      // >= 96 output positions per image: the AVX-512 kernels (implicit GEMM, panels).
      {{2, 5, 36, 40}, {9, 5, 3, 3}, {1, 1, 1}, {0, 1, 1}, {1, 1, 1}},        // "same" 3×3: fused backward
      {{1, 3, 30, 50}, {17, 3, 3, 5}, {1, 1, 1}, {0, 0, 2}, {1, 1, 2}},       // dilation, 17 channels
      {{2, 4, 32, 32}, {3, 4, 1, 1}, {1, 1, 1}, {0, 1, 1}, {1, 1, 1}},        // 1×1 with padding
      {{1, 3, 8, 12, 12}, {10, 3, 3, 3, 3}, {1, 1, 1}, {1, 1, 1}, {1, 1, 1}},  // 3-D
      {{1, 2, 12, 40, 20}, {4, 2, 3, 3, 3}, {2, 1, 2}, {1, 1, 1}, {1, 1, 1}},  // 3-D strided
      // A shallow last axis: the implicit GEMM stores the volume with a long axis innermost.
      {{2, 3, 40, 6, 5}, {5, 3, 3, 3, 3}, {1, 1, 1}, {1, 1, 1}, {1, 1, 1}},   // "same": fused backward
      {{1, 2, 8, 40, 4}, {3, 2, 3, 3, 3}, {1, 1, 1}, {1, 0, 2}, {1, 1, 2}},   // not "same", dilated
      // Few positions per image: batch items folded side by side into one GEMM.
      {{3, 16, 4, 8}, {24, 16, 3, 3}, {1, 1, 1}, {0, 1, 1}, {1, 1, 1}},
      {{3, 8, 8, 8}, {16, 8, 3, 3}, {1, 2, 2}, {0, 1, 1}, {1, 1, 1}},
      // Folded panels holding the end of one item and the start of the next; odd channel counts.
      {{5, 7, 5, 7}, {13, 7, 3, 3}, {1, 1, 1}, {0, 1, 1}, {1, 1, 1}},
      {{1, 9, 9, 11}, {20, 9, 3, 3}, {1, 2, 2}, {0, 1, 1}, {1, 1, 1}},
      {{4, 6, 7, 9}, {33, 6, 3, 3}, {1, 2, 2}, {0, 0, 1}, {1, 1, 1}},
      {{2, 3, 3, 4, 5}, {11, 3, 3, 3, 3}, {1, 1, 1}, {1, 1, 1}, {1, 1, 1}},
      // More columns than one 16 MiB round of folded panels (2304 taps × 1800 positions).
      {{20, 256, 9, 10}, {8, 256, 3, 3}, {1, 1, 1}, {0, 1, 1}, {1, 1, 1}},
      // Strided, >= 96 positions but all items in one weight-gradient block (rows split over threads).
      {{3, 5, 24, 20}, {12, 5, 3, 3}, {1, 2, 2}, {0, 1, 1}, {1, 1, 1}},
      // Strided 1×1 (a ResNet downsample): the input gradient scattered without a phased copy.
      {{2, 5, 24, 22}, {7, 5, 1, 1}, {1, 2, 2}, {0, 0, 0}, {1, 1, 1}},
      // A 7×7 stride-2 stem: im2col runs of several panels read as windows by the micro-kernel.
      {{2, 3, 40, 52}, {10, 3, 7, 7}, {1, 2, 2}, {0, 3, 3}, {1, 1, 1}},
      // Strided 2-D, >= 96 positions: forward and weight gradient on the windows of a phase-split
      // copy (odd sizes, stride 3, a kernel wider than the stride without padding).
      {{2, 6, 25, 31}, {10, 6, 3, 3}, {1, 2, 2}, {0, 1, 1}, {1, 1, 1}},
      {{1, 4, 30, 33}, {8, 4, 5, 5}, {1, 3, 3}, {0, 2, 2}, {1, 1, 1}},
      {{1, 3, 26, 30}, {5, 3, 4, 4}, {1, 2, 2}, {0, 0, 0}, {1, 1, 1}},
      // Stride-1 items shorter than a weight-gradient chunk, summed on shared accumulators.
      {{5, 6, 10, 12}, {9, 6, 3, 3}, {1, 1, 1}, {0, 1, 1}, {1, 1, 1}},
      // The outer-product weight gradient's register tiles: 3 vectors of channels (40 = 48 with
      // 8 zero channels), and 4 + 1 vectors (72) with a tap count no tile divides (3·5·5 = 75).
      {{2, 4, 20, 24}, {40, 4, 3, 3}, {1, 1, 1}, {0, 1, 1}, {1, 1, 1}},
      {{1, 3, 14, 18}, {72, 3, 5, 5}, {1, 1, 1}, {0, 2, 2}, {1, 1, 1}},
  };

  for (const Case& c : cases) {
    SCOPED_TRACE(shape_str(c.x));
    expect_float32_matches_float64(c.x, c.w, c.s, c.p, c.d, 31);
  }
}

// Forward and all three gradients with 1 and with 2 threads, compared bit for bit, on every
// kernel path: implicit GEMM (2-D, reordered 3-D; short items summed together in the weight
// gradient; Winograd in 2-D and along a reordered 3-D axis, and on gathered row pairs in 48- and
// 32-column panels), the phase-split windows of stride 2 (2-D), panels and reference (3-D stride 2; one
// weight-gradient block split by rows), and the batch-folded panels (few positions per image).
TEST(Conv, ForwardBackwardBitwiseIdenticalWithOneAndTwoThreads) {
  struct Run { std::vector<double> y, gx, gw, gb; };
  auto run = [](int threads, const Shape& xs, int64_t stride) {
    const int saved = omp_get_max_threads();
    omp_set_num_threads(threads);
    const bool three_d = xs.size() == 5;
    Tensor x = Tensor::normal(xs, 0, 1, 21);
    Tensor w = Tensor::normal(three_d ? Shape{16, 8, 3, 3, 3} : Shape{16, 8, 3, 3}, 0, 0.2, 22);
    Tensor b = Tensor::normal({16}, 0, 0.2, 23);
    for (Tensor* t : {&x, &w, &b}) t->set_requires_grad(true);
    Tensor y = three_d ? conv3d(x, w, b, {stride, stride, stride}, {1, 1, 1})
                       : conv2d(x, w, b, {stride, stride}, {1, 1});
    backward(y, Tensor::normal(y.shape(), 0, 1, 24));
    Run r{y.to_vector(), x.grad().to_vector(), w.grad().to_vector(), b.grad().to_vector()};
    omp_set_num_threads(saved);
    return r;
  };
  for (const Shape& xs : {Shape{3, 8, 40, 33}, Shape{2, 8, 34, 12, 4}, Shape{6, 8, 6, 7}, Shape{5, 8, 24, 20},
                          Shape{3, 8, 10, 12}, Shape{2, 8, 40, 64}, Shape{1, 8, 34, 12, 12}, Shape{4, 8, 4, 8}})
    for (int64_t stride : {1, 2}) {
      const Run a = run(1, xs, stride), c = run(2, xs, stride);
      EXPECT_EQ(a.y, c.y) << shape_str(xs) << " stride " << stride;
      EXPECT_EQ(a.gx, c.gx) << shape_str(xs) << " stride " << stride;
      EXPECT_EQ(a.gw, c.gw) << shape_str(xs) << " stride " << stride;
      EXPECT_EQ(a.gb, c.gb) << shape_str(xs) << " stride " << stride;
    }
}

// The weight gradient's outer-product tiles for wider layers (40 and 72 output channels: 3 and
// 4 + 1 vectors of 16), split by blocks of taps over the threads: the same bits with 1 and 2.
TEST(Conv, WideWeightGradientBitwiseIdenticalWithOneAndTwoThreads) {
  auto run = [](int threads, const Shape& xs, const Shape& ws) {
    const int saved = omp_get_max_threads();
    omp_set_num_threads(threads);
    Tensor x = Tensor::normal(xs, 0, 1, 31), w = Tensor::normal(ws, 0, 0.2, 32);
    x.set_requires_grad(true);
    w.set_requires_grad(true);
    Tensor y = xs.size() == 5 ? conv3d(x, w, Tensor(), {1, 1, 1}, {1, 1, 1}) : conv2d(x, w, Tensor(), {1, 1}, {1, 1});
    backward(y, Tensor::normal(y.shape(), 0, 1, 33));
    std::vector<double> r = w.grad().to_vector();
    omp_set_num_threads(saved);
    return r;
  };
  for (const auto& [xs, ws] : {std::pair<Shape, Shape>{{3, 6, 40, 33}, {40, 6, 3, 3}},
                               std::pair<Shape, Shape>{{1, 5, 20, 30}, {72, 5, 3, 3}},
                               std::pair<Shape, Shape>{{1, 4, 34, 12, 12}, {40, 4, 3, 3, 3}}})
    EXPECT_EQ(run(1, xs, ws), run(2, xs, ws)) << shape_str(xs) << " * " << shape_str(ws);
}

// The implicit GEMM's padded input copy is large and the same size on every call, so it comes
// from the buffer cache (autodiff/buffer_cache.h). Otherwise its fresh pages fault and are zeroed
// on every call, which cost a quarter of this forward's time at 2 threads. A repeated forward
// (Winograd here) therefore serves three large blocks from the cache (the output, the padded copy
// and its transform) and allocates none, and it gives the same bits.
TEST(Conv, RepeatedForwardTakesItsPaddedCopyFromTheBufferCache) {
  if (buffer_cache_limit_bytes() == 0) GTEST_SKIP() << "buffer cache disabled (STREETLIGHT_BUFFER_CACHE_MB=0)";
  const Tensor x = Tensor::normal({2, 32, 96, 96}, 0, 1, 31).to(DType::F32);  // padded copy 2.4 MB
  const Tensor w = Tensor::normal({32, 32, 3, 3}, 0, 0.1, 32).to(DType::F32);
  if (!nn::detail::gemm_kernel_available()) GTEST_SKIP() << "no implicit-GEMM kernels on this CPU";
  NoGradGuard ng;
  const std::vector<double> first = conv2d(x, w, Tensor(), {1, 1}, {1, 1}).to_vector();
  const BufferCacheStats before = buffer_cache_stats();
  const Tensor y = conv2d(x, w, Tensor(), {1, 1}, {1, 1});
  const BufferCacheStats after = buffer_cache_stats();
  EXPECT_EQ(after.misses, before.misses);
  EXPECT_EQ(after.hits - before.hits, 3) << "the output, the padded copy and its Winograd transform";
  EXPECT_EQ(first, y.to_vector());
}

// The weight gradient reads the reordered padded copy the forward kept (conv_implicit_gemm.h):
// the same bits as a fresh copy, and x itself is not read again (a NaN-filled x changes
// nothing), through both backward entry points. A plain 2-D copy is not kept.
TEST(Conv, WeightGradientFromTheForwardsKeptCopyHasTheSameBitsAndDoesNotReadX) {
  if (!nn::detail::gemm_kernel_available()) GTEST_SKIP() << "no implicit-GEMM kernels on this CPU";
  for (const std::array<int64_t, 3> in : {std::array<int64_t, 3>{40, 36, 16}, std::array<int64_t, 3>{1, 48, 40}}) {
    nn::detail::ConvGeometry g;
    g.N = 2, g.C = 3, g.O = 5, g.in = in;
    const bool volume = in[0] > 1;
    for (int a = 0; a < 3; ++a) {
      g.k[a] = volume || a > 0 ? 3 : 1;
      g.pad[a] = volume || a > 0 ? 1 : 0;
      g.stride[a] = g.dil[a] = 1;
      g.out[a] = in[a];
    }
    SCOPED_TRACE(volume ? "3-D, reordered copy" : "2-D");
    const std::vector<double> xd = Tensor::normal({g.N * g.C * g.in_plane()}, 0, 1, 41).to_vector();
    const std::vector<double> wd = Tensor::normal({g.O * g.rows()}, 0, 0.2, 42).to_vector();
    const std::vector<double> dyd = Tensor::normal({g.N * g.O * g.out_plane()}, 0, 1, 43).to_vector();
    const std::vector<float> x(xd.begin(), xd.end()), w(wd.begin(), wd.end()), dy(dyd.begin(), dyd.end());
    const std::vector<float> nan_x(x.size(), std::numeric_limits<float>::quiet_NaN());
    std::vector<float> y(static_cast<size_t>(g.N * g.O * g.out_plane()));
    nn::detail::KeptInput kept;
    nn::detail::direct_forward(g, x.data(), nn::detail::pack_rows(w.data(), g.O, g.rows()).data(), nullptr,
                               y.data(), &kept);
    if (!volume) {  // a plain copy is made again rather than kept
      EXPECT_FALSE(kept);
      continue;
    }
    ASSERT_TRUE(kept);
    std::vector<float> fresh(w.size()), from_kept(w.size());
    nn::detail::direct_backward_weight(g, x.data(), dy.data(), fresh.data());
    nn::detail::direct_backward_weight(g, nan_x.data(), dy.data(), from_kept.data(), kept.get());
    EXPECT_EQ(fresh, from_kept);
    std::vector<float> dx_fresh(x.size()), dx_kept(x.size()), dw_fused(w.size()), dw_fused_kept(w.size());
    ASSERT_TRUE(nn::detail::direct_backward_fused(g, x.data(), w.data(), dy.data(), dx_fresh.data(), dw_fused.data()));
    ASSERT_TRUE(nn::detail::direct_backward_fused(g, nan_x.data(), w.data(), dy.data(), dx_kept.data(),
                                                  dw_fused_kept.data(), kept.get()));
    EXPECT_EQ(dw_fused, dw_fused_kept);
    EXPECT_EQ(dx_fresh, dx_kept);
    double max_diff = 0;  // and both are the weight gradient: against the fused path's independent sum
    for (size_t i = 0; i < w.size(); ++i) max_diff = std::max(max_diff, double(std::abs(fresh[i] - dw_fused[i])));
    EXPECT_LT(max_diff, 1e-3);
  }
}

// The two ways the implicit-GEMM forward walks its outputs (conv_implicit_gemm.h, ForwardPanels):
// each output row's panels stored straight into y, and panels along the padded pitch copied into y
// without the dropped positions, give the same bits, with and without a bias, on the strided
// phase-split copy (the ResNet stem's 7×7/2) and on stride-1 2-D and 3-D copies; row widths with
// a narrow last tile (≤ 32), a full one, and none. And both agree with float64.
TEST(Conv, ForwardByRowsHasTheBitsOfPanelsAlongThePitch) {
  if (!nn::detail::gemm_kernel_available()) GTEST_SKIP() << "no implicit-GEMM kernels on this CPU";
  using nn::detail::ForwardPanels;
  struct Case { std::array<int64_t, 3> in, k; int64_t stride, pad, O; };
  const std::vector<Case> cases = {
      {{1, 30, 256}, {1, 7, 7}, 2, 3, 10},   // stem: 128 = 48 + 48 + 32 per row, 10 channels (a partial row block)
      {{1, 20, 120}, {1, 5, 5}, 2, 2, 9},    // 60 = 48 + 12
      {{1, 17, 141}, {1, 5, 5}, 1, 2, 8},    // 141 = 2·48 + 45 (a full last tile)
      {{1, 9, 96}, {1, 3, 3}, 1, 1, 16},     // 96 = 2·48: no partial tile
      {{5, 12, 40}, {3, 3, 3}, 1, 1, 6},     // 3-D: rows of several planes
  };
  for (const Case& c : cases) {
    nn::detail::ConvGeometry g;
    g.N = 2, g.C = 3, g.O = c.O, g.in = c.in, g.k = c.k;
    for (int a = 0; a < 3; ++a) {
      const bool image_axis = a > 0 || c.in[0] > 1;
      g.pad[a] = image_axis ? c.pad : 0;
      g.stride[a] = image_axis ? c.stride : 1;
      g.dil[a] = 1;
      g.out[a] = (g.in[a] + 2 * g.pad[a] - g.k[a]) / g.stride[a] + 1;
    }
    const bool strided = c.stride > 1;
    SCOPED_TRACE(shape_str(Shape{g.N, g.C, c.in[0], c.in[1], c.in[2]}) + (strided ? " strided" : ""));
    if (strided) {
      ASSERT_TRUE(nn::detail::direct_strided_supported(g));
    }
    const std::vector<double> xd = Tensor::normal({g.N * g.C * g.in_plane()}, 0, 1, 51).to_vector();
    const std::vector<double> wd = Tensor::normal({g.O * g.rows()}, 0, 0.2, 52).to_vector();
    const std::vector<double> bd = Tensor::normal({g.O}, 0, 1, 53).to_vector();
    const std::vector<float> x(xd.begin(), xd.end()), w(wd.begin(), wd.end()), b(bd.begin(), bd.end());
    const nn::detail::PackedRows packed = nn::detail::pack_rows(w.data(), g.O, g.rows());
    auto forward = [&](ForwardPanels how, const float* bias) {
      std::vector<float> y(static_cast<size_t>(g.N * g.O * g.out_plane()), -7.0f);
      if (strided)
        nn::detail::direct_forward_strided(g, x.data(), packed.data(), bias, y.data(), how);
      else
        nn::detail::direct_forward(g, x.data(), packed.data(), bias, y.data(), nullptr, how);
      return y;
    };
    for (const float* bias : {static_cast<const float*>(nullptr), b.data()}) {
      const std::vector<float> rows = forward(ForwardPanels::kRows, bias);
      EXPECT_EQ(rows, forward(ForwardPanels::kPitch, bias)) << (bias ? "with" : "without") << " bias";
      EXPECT_EQ(rows, forward(ForwardPanels::kChoose, bias));
      if (!bias) continue;
      // Against float64 (every output written, none left at the fill value): rows() FMAs and the
      // bias's addition, one rounding each, so |ŷ − y| ≤ γ_{K+1}·(Σ|x||w| + |b|) (Higham §3.1,
      // u = 2⁻²⁴), Σ|x||w| + |b| from the same convolution of the absolute values.
      const Shape xs{g.N, g.C, c.in[0], c.in[1], c.in[2]}, ws{g.O, g.C, c.k[0], c.k[1], c.k[2]};
      const std::array<int64_t, 3> st{g.stride[0], g.stride[1], g.stride[2]}, pd{g.pad[0], g.pad[1], g.pad[2]};
      const Tensor x64 = Tensor::from_vector(xd, xs), w64 = Tensor::from_vector(wd, ws), b64 = Tensor::from_vector(bd, {g.O});
      const std::vector<double> ref = conv3d(x64, w64, b64, st, pd).to_vector();
      const std::vector<double> mag = conv3d(abs(x64), abs(w64), abs(b64), st, pd).to_vector();
      const double u = std::ldexp(1.0, -24), K1 = static_cast<double>(g.rows() + 1), gamma = K1 * u / (1.0 - K1 * u);
      ASSERT_EQ(ref.size(), rows.size());
      for (size_t i = 0; i < ref.size(); ++i) ASSERT_LE(std::abs(rows[i] - ref[i]), gamma * mag[i]) << i;
    }
  }
#if defined(__AVX512F__)
  // With the 8 × 32 tile a 128-wide stem row costs 2⅔ tiles by rows against 131/48 · 1.09 along
  // its pitch: the stem is computed by rows. A 64-wide stride-1 row (66-pitch) stays on the pitch.
  nn::detail::ConvGeometry stem;
  stem.N = 4, stem.C = 3, stem.O = 64, stem.in = {1, 128, 256}, stem.k = {1, 7, 7};
  stem.pad = {0, 3, 3}, stem.stride = {1, 2, 2}, stem.dil = {1, 1, 1}, stem.out = {1, 64, 128};
  EXPECT_EQ(nn::detail::chosen_forward_panels(stem, true), ForwardPanels::kRows);
  nn::detail::ConvGeometry block = stem;
  block.C = 64, block.in = {1, 32, 64}, block.k = {1, 3, 3}, block.pad = {0, 1, 1}, block.stride = {1, 1, 1};
  block.out = {1, 32, 64};
  EXPECT_EQ(nn::detail::chosen_forward_panels(block, false), ForwardPanels::kPitch);
#endif
}

// Winograd F(2, 3) (conv_winograd.h): the forward and all three gradients against float64, on
// shapes that take it (checked). On the implicit GEMM's windows: 2-D with an even and an odd row
// (the padded pitch gets one more zero column), a dilated other axis, a 3-D volume, one stored with
// its first axis innermost (the taps transformed are then not the weights' last axis), a kernel of
// 1 on the other axes, and a convolution that is not "same" (its input gradient pads by 2 and is
// not fused). On gathered row pairs (small 2-D images): a ResNet-like 8 × 16 stage, one panel
// exactly, a 4 × 8 stage on narrow 32-column panels, an odd row (the last pair's second output dropped), and a dilated, not "same" one whose
// input gradient (flipped kernel) pads differently. Then a sun: a few inputs 10^5 times the rest,
// where the transforms' differences of large and small values must cost no more than float
// rounding of Σ|x|·Σ|g| (the row sums of the kernel along the transformed axis: Winograd's error
// bound, looser than the direct sum's Σ|x|·|g| where one tap is near zero).
TEST(Conv, WinogradForwardAndGradientsMatchFloat64) {
  if (!nn::detail::gemm_kernel_available()) GTEST_SKIP() << "no implicit-GEMM kernels on this CPU";
  struct Case { Shape x, w; std::array<int64_t, 3> p, d; bool windows; };
  const std::vector<Case> cases = {
      {{2, 5, 36, 64}, {9, 5, 3, 3}, {0, 1, 1}, {1, 1, 1}, true},
      {{2, 5, 36, 63}, {9, 5, 3, 3}, {0, 1, 1}, {1, 1, 1}, true},
      {{2, 3, 40, 64}, {4, 3, 5, 3}, {0, 4, 1}, {1, 2, 1}, true},
      {{1, 3, 6, 20, 40}, {4, 3, 3, 3, 3}, {1, 1, 1}, {1, 1, 1}, true},
      {{1, 2, 40, 36, 4}, {3, 2, 3, 3, 3}, {1, 1, 1}, {1, 1, 1}, true},
      {{1, 2, 4, 40, 40}, {3, 2, 1, 1, 3}, {0, 0, 1}, {1, 1, 1}, true},
      {{1, 4, 50, 90}, {6, 4, 3, 3}, {0, 0, 0}, {1, 1, 1}, true},
      {{4, 16, 8, 16}, {24, 16, 3, 3}, {0, 1, 1}, {1, 1, 1}, false},
      {{3, 16, 4, 8}, {8, 16, 3, 3}, {0, 1, 1}, {1, 1, 1}, false},
      {{4, 16, 4, 8}, {12, 16, 3, 3}, {0, 1, 1}, {1, 1, 1}, false},  // 64 pairs: two 32-column panels
      {{2, 5, 9, 15}, {7, 5, 3, 3}, {0, 1, 1}, {1, 1, 1}, false},
      {{2, 3, 12, 24}, {4, 3, 3, 3}, {0, 2, 0}, {1, 2, 1}, false},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(shape_str(c.x));
    const bool two_d = c.x.size() == 4;
    nn::detail::ConvGeometry g;
    g.N = c.x[0], g.C = c.x[1], g.O = c.w[0];
    for (int a = 0; a < 3; ++a) {
      const size_t i = two_d ? a + 1 : a + 2;  // 2-D: depth 1
      g.in[a] = two_d && a == 0 ? 1 : c.x[i];
      g.k[a] = two_d && a == 0 ? 1 : c.w[i];
      g.stride[a] = 1, g.pad[a] = c.p[a], g.dil[a] = c.d[a];
      g.out[a] = g.in[a] + 2 * g.pad[a] - g.dil[a] * (g.k[a] - 1);
    }
    if (c.windows) {
      ASSERT_TRUE(nn::detail::direct_winograd_supported(g));
    } else {
      ASSERT_FALSE(nn::detail::direct_winograd_supported(g) && g.out_plane() >= 96);
      ASSERT_TRUE(nn::detail::winograd_rows_supported(g));
      ASSERT_TRUE(nn::detail::winograd_rows_supported(nn::detail::input_grad_geometry(g)));
    }
    expect_float32_matches_float64(c.x, c.w, {1, 1, 1}, c.p, c.d, 51);
  }

  // The sun: x ~ U(0, 1) with 10^5 at a few pixels, and the error bound from |w| * |x| in float64.
  std::vector<double> xv = rand64({2, 4, 40, 64}, 55, 0, 1).to_vector();
  for (size_t i = 0; i < xv.size(); i += 997) xv[i] = 1e5;
  const Tensor x64 = Tensor::from_vector(xv, {2, 4, 40, 64}, DType::F64), w64 = rand64({6, 4, 3, 3}, 56);
  Tensor x32 = x64.to(DType::F32), w32 = w64.to(DType::F32);
  x32.set_requires_grad(true);
  const Tensor dy64 = rand64({2, 6, 40, 64}, 57, 0, 1);
  Tensor y32 = conv2d(x32, w32, Tensor(), {1, 1}, {1, 1});
  backward(y32, dy64.to(DType::F32));
  const std::vector<double> y = y32.to_vector(), dx = x32.grad().to_vector();
  const std::vector<double> y_ref = conv2d(x64, w64, Tensor(), {1, 1}, {1, 1}).to_vector();
  // Winograd's bound: a tap's error scales with its row's Σ|g| (the transformed weights mix the
  // three taps), not with its own |g|, so |w| is replaced by each 3-tap row's sum of magnitudes.
  std::vector<double> wrow = w64.to_vector();
  for (size_t r = 0; r < wrow.size(); r += 3) {
    const double m = std::abs(wrow[r]) + std::abs(wrow[r + 1]) + std::abs(wrow[r + 2]);
    wrow[r] = wrow[r + 1] = wrow[r + 2] = m;
  }
  const std::vector<double> y_abs =
      conv2d(abs(x64), Tensor::from_vector(wrow, w64.shape(), DType::F64), Tensor(), {1, 1}, {1, 1}).to_vector();
  Tensor x64g = x64.detach();
  x64g.set_requires_grad(true);
  backward(conv2d(x64g, w64, Tensor(), {1, 1}, {1, 1}), dy64);
  const std::vector<double> dx_ref = x64g.grad().to_vector();
  double worst = 0;
  for (size_t i = 0; i < y.size(); ++i) {
    ASSERT_TRUE(std::isfinite(y[i]));
    worst = std::max(worst, std::abs(y[i] - y_ref[i]) / y_abs[i]);
  }
  EXPECT_LT(worst, 8 * std::ldexp(1.0, -24)) << "forward error / (row sums of |w| * |x|)";
  double worst_dx = 0, scale = 0;
  for (size_t i = 0; i < dx.size(); ++i) {
    ASSERT_TRUE(std::isfinite(dx[i]));
    worst_dx = std::max(worst_dx, std::abs(dx[i] - dx_ref[i]));
    scale = std::max(scale, std::abs(dx_ref[i]));
  }
  EXPECT_LT(worst_dx, 1e-5 * scale) << "input gradient";
}

// winograd_weights equals its definition bit for bit: V_0 = g0, V_1 = (g0 + g1 + g2) / 2,
// V_2 = (g0 − g1 + g2) / 2, V_3 = g2, rows past O zero, with g_m the taps of the transformed axis of
// row r = (c, the other axes' taps) of channel o: w[o][c][k + m·s] or, flipped (an input
// gradient's kernel, w [C][O][taps]), w[c][o][taps − 1 − k − m·s]. Covers the AVX-512 path
// (unflipped innermost axis: 32 rows deinterleaved per step) and the scalar loop (flipped
// kernels, the other axes, the last rows), with partial channel blocks.
TEST(Conv, WinogradWeightsEqualTheirDefinitionBitForBit) {
  for (const auto& [O, C, k0] : {std::array<int64_t, 3>{13, 21, 1}, std::array<int64_t, 3>{16, 11, 3},
                                 std::array<int64_t, 3>{8, 5, 3}, std::array<int64_t, 3>{3, 7, 1}})
    for (const bool flipped : {false, true})
      for (int axis = 0; axis < 3; ++axis) {
        nn::detail::ConvGeometry g;
        g.N = 1, g.C = C, g.O = O;
        for (int a = 0; a < 3; ++a) g.in[a] = 8, g.k[a] = 3, g.stride[a] = 1, g.pad[a] = 1, g.dil[a] = 1, g.out[a] = 8;
        g.k[0] = k0;
        if (g.k[axis] != 3) continue;
        SCOPED_TRACE("O " + std::to_string(O) + " C " + std::to_string(C) + " k0 " + std::to_string(k0) + " axis " +
                     std::to_string(axis) + (flipped ? " flipped" : ""));
        const int64_t taps = g.taps(), R = g.rows() / 3;
        const std::vector<double> wd = rand64({O, C * taps}, 61).to_vector();
        const std::vector<float> w(wd.begin(), wd.end());
        const nn::detail::WinogradWeights v = nn::detail::winograd_weights(g, axis, w.data(), flipped);
        const std::array<int64_t, 3> ws = {g.k[1] * g.k[2], g.k[2], 1};
        size_t mismatches = 0;
        for (int64_t o = 0; o < (O + 7) / 8 * 8; ++o) {
          int64_t r = 0;
          for (int64_t c = 0; c < C; ++c)
            for (int64_t a0 = 0; a0 < (axis == 0 ? 1 : g.k[0]); ++a0)
              for (int64_t a1 = 0; a1 < (axis == 1 ? 1 : g.k[1]); ++a1)
                for (int64_t a2 = 0; a2 < (axis == 2 ? 1 : g.k[2]); ++a2, ++r) {
                  const int64_t k = a0 * ws[0] + a1 * ws[1] + a2 * ws[2];
                  float t[3] = {0.0f, 0.0f, 0.0f};
                  for (int64_t m = 0; m < 3 && o < O; ++m)
                    t[m] = flipped ? w[(c * O + o) * taps + taps - 1 - (k + m * ws[axis])]
                                   : w[(o * C + c) * taps + k + m * ws[axis]];
                  const float expect[4] = {t[0], (t[0] + t[1] + t[2]) * 0.5f, (t[0] - t[1] + t[2]) * 0.5f, t[2]};
                  for (int i = 0; i < 4; ++i) {
                    const float got = v.data(i)[(o / 8 * R + r) * 8 + o % 8];
                    mismatches += std::memcmp(&got, &expect[i], sizeof(float)) != 0;
                  }
                }
          ASSERT_EQ(r, R);
        }
        EXPECT_EQ(mismatches, 0u);
      }
}

TEST(Conv, FlippedWeightPackingIsTheTransposedReversedKernel) {
  // pack_weights_flipped by its definition: row block b, packed column k = o·taps + t, lane i holds
  // w[o][8b + i][taps − 1 − t], and 0 for channels past C. Full blocks go through 8 × 8 register
  // transposes (8 source taps at a time) and the rest through the scalar loop; both must give
  // exactly these bits, NaN payloads and signed zeros included.
  for (const std::array<int64_t, 3> s : {std::array<int64_t, 3>{3, 8, 9}, {2, 16, 27}, {2, 13, 9}, {1, 8, 1},
                                          {4, 24, 8}, {2, 8, 17}, {5, 3, 49}, {2, 7, 3}}) {
    const int64_t O = s[0], C = s[1], taps = s[2], K = O * taps, blocks = (C + 7) / 8;
    SCOPED_TRACE("O " + std::to_string(O) + " C " + std::to_string(C) + " taps " + std::to_string(taps));
    const std::vector<double> wd = Tensor::normal({O * C * taps}, 0, 1, 7).to_vector();
    std::vector<float> w(wd.begin(), wd.end());
    w[0] = -0.0f, w[w.size() - 1] = std::numeric_limits<float>::quiet_NaN();
    const nn::detail::PackedRows packed = nn::detail::pack_weights_flipped(w.data(), O, C, taps);
    size_t mismatches = 0;
    for (int64_t b = 0; b < blocks; ++b)
      for (int64_t o = 0; o < O; ++o)
        for (int64_t t = 0; t < taps; ++t)
          for (int64_t i = 0; i < 8; ++i) {
            const int64_t c = 8 * b + i;
            const float want = c < C ? w[(o * C + c) * taps + taps - 1 - t] : 0.0f;
            const float got = packed.data()[(b * K + o * taps + t) * 8 + i];
            mismatches += std::memcmp(&want, &got, sizeof(float)) != 0;
          }
    EXPECT_EQ(mismatches, 0u);
  }
}

TEST(Conv, ErrorsNameOpAndShapes) {
  const Tensor x = Tensor::zeros({8, 3, 16, 16}), w = Tensor::zeros({64, 4, 3, 3});
  try {
    conv2d(x, w, Tensor());
    FAIL() << "expected sl::Error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "conv2d: input [8, 3, 16, 16] has 3 channels, weight [64, 4, 3, 3] expects 4");
  }
  EXPECT_THROW(conv3d(x, Tensor::zeros({4, 3, 3, 3}), Tensor()), Error);                      // rank
  EXPECT_THROW(conv2d(x, Tensor::zeros({4, 3, 17, 17}), Tensor()), Error);                    // too large
  EXPECT_THROW(conv2d(x, Tensor::zeros({4, 3, 3, 3}), Tensor::zeros({5})), Error);            // bias
  EXPECT_THROW(conv2d(x, Tensor::zeros({4, 3, 3, 3}), Tensor(), {0, 1}), Error);              // stride
  EXPECT_THROW(conv2d(x, Tensor::zeros({4, 3, 3, 3}, DType::F64), Tensor()), Error);          // dtype
}

TEST(Conv, OutputsAndGradientsFiniteForLargeFiniteInputs) {
  Tensor x = Tensor::full({1, 2, 5, 5}, 1e30), w = Tensor::full({2, 2, 3, 3}, 1e-30);
  x.set_requires_grad(true);
  w.set_requires_grad(true);
  Tensor y = conv2d(x, w, Tensor(), {1, 1}, {1, 1});
  backward(sum(y));
  EXPECT_TRUE(sl::test::all_finite(y));
  EXPECT_TRUE(sl::test::all_finite(x.grad()));
}

}  // namespace
}  // namespace sl::test
