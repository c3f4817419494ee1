// Pooling: float64 gradchecks (stride, padding, size-1 dims, non-contiguous), PyTorch's
// conventions for padding and ties, and errors.
#include "nn/functional/pooling.h"

#include <gtest/gtest.h>

#include <cmath>

#include "support/test_util.h"

namespace sl::test {
using nn::avg_pool2d;
using nn::avg_pool3d;
using nn::global_avg_pool;
using nn::max_pool2d;
using nn::max_pool3d;

namespace {

// Distinct values spaced far more than the gradcheck eps apart, so no window has a tie.
Tensor distinct64(const Shape& shape, uint64_t seed) {
  const int64_t n = shape_numel(shape);
  std::vector<double> v(static_cast<size_t>(n));
  for (int64_t i = 0; i < n; ++i) v[i] = 0.01 * static_cast<double>((i * 7919 + seed * 31) % (n + 7));
  return Tensor::from_vector(v, shape, DType::F64);
}

TEST(MaxPool, Gradcheck2dAnd3dWithStrideAndPadding) {
  EXPECT_GRADCHECK([](const TensorList& in) { return max_pool2d(in[0], {3, 2}, {2, 1}, {1, 1}); },
                   {distinct64({2, 2, 5, 6}, 1)});
  EXPECT_GRADCHECK([](const TensorList& in) { return max_pool3d(in[0], {2, 2, 2}, {2, 2, 2}); },
                   {distinct64({1, 2, 4, 4, 5}, 2)});
  EXPECT_GRADCHECK([](const TensorList& in) { return max_pool3d(in[0], {3, 1, 3}, {1, 1, 2}, {1, 0, 1}); },
                   {distinct64({1, 1, 3, 1, 4}, 3)});
}

TEST(MaxPool, PaddingIsNeverSelectedEvenForNegativeInputs) {
  const Tensor x = Tensor::full({1, 1, 2, 2}, -5.0);
  const Tensor y = max_pool2d(x, {2, 2}, {1, 1}, {1, 1});
  for (double v : y.to_vector()) EXPECT_EQ(v, -5.0);
}

TEST(MaxPool, TiesSendTheGradientToTheFirstMaximum) {
  Tensor x = Tensor::ones({1, 1, 2, 2});
  x.set_requires_grad(true);
  backward(sum(max_pool2d(x, {2, 2}, {2, 2})));
  EXPECT_EQ(x.grad().to_vector(), (std::vector<double>{1, 0, 0, 0}));
}

TEST(MaxPool, NanInAWindowPropagatesAsInPyTorch) {
  Tensor x = Tensor::from_vector({1, NAN, 3, 2}, {1, 1, 2, 2});
  EXPECT_TRUE(std::isnan(max_pool2d(x, {2, 2}, {2, 2}).item()));
}

// A naive reference: every window scanned tap by tap in (z, y, x) order with PyTorch's rule.
// `wins[i]` counts the windows whose gradient goes to input i (the first maximum).
std::vector<double> reference_max_pool3d(const Tensor& x, std::array<int64_t, 3> k, std::array<int64_t, 3> s,
                                         std::array<int64_t, 3> p, Shape* out_shape, std::vector<double>* wins) {
  const std::vector<double> v = x.to_vector();
  const int64_t planes = x.size(0) * x.size(1), D = x.size(2), H = x.size(3), W = x.size(4);
  const int64_t od = (D + 2 * p[0] - k[0]) / s[0] + 1, oh = (H + 2 * p[1] - k[1]) / s[1] + 1,
                ow = (W + 2 * p[2] - k[2]) / s[2] + 1;
  *out_shape = {x.size(0), x.size(1), od, oh, ow};
  std::vector<double> out;
  wins->assign(v.size(), 0.0);
  for (int64_t q = 0; q < planes; ++q)
    for (int64_t a = 0; a < od; ++a)
      for (int64_t b = 0; b < oh; ++b)
        for (int64_t c = 0; c < ow; ++c) {
          double best = 0;
          int64_t at = 0;
          bool any = false;
          for (int64_t i = 0; i < k[0]; ++i)
            for (int64_t j = 0; j < k[1]; ++j)
              for (int64_t l = 0; l < k[2]; ++l) {
                const int64_t z = a * s[0] - p[0] + i, y = b * s[1] - p[1] + j, xx = c * s[2] - p[2] + l;
                if (z < 0 || z >= D || y < 0 || y >= H || xx < 0 || xx >= W) continue;
                const int64_t idx = ((q * D + z) * H + y) * W + xx;
                const double t = v[idx];
                if (!any || (!std::isnan(best) && (std::isnan(t) || t > best))) best = t, at = idx;
                any = true;
              }
          out.push_back(best);
          (*wins)[at] += 1;
        }
  return out;
}

TEST(MaxPool, WideRowsMatchANaiveWindowScanWithTiesAndNans) {
  // Rows wide enough for the whole-row path of max_pool_plane, values from a small set (many
  // ties) with a few NaNs, over strides 1-3, with and without padding, in 2-D and 3-D.
  Tensor x = Tensor::uniform({2, 3, 3, 7, 37}, 0, 4, 11, DType::F64);
  std::vector<double> v = x.to_vector();
  for (size_t i = 0; i < v.size(); ++i) v[i] = i % 97 == 5 ? NAN : std::floor(v[i]);
  x = Tensor::from_vector(v, x.shape(), DType::F64);
  const std::array<std::array<int64_t, 3>, 4> kernels = {{{1, 3, 3}, {1, 2, 2}, {2, 3, 5}, {3, 3, 3}}};
  for (const auto& k : kernels)
    for (int64_t st = 1; st <= 3; ++st)
      for (int64_t pad = 0; pad <= k[2] / 2; ++pad) {
        const std::array<int64_t, 3> s = {1, st, st}, p = {0, std::min(pad, k[1] / 2), pad};
        Shape shape;
        std::vector<double> wins;
        const std::vector<double> want = reference_max_pool3d(x, k, s, p, &shape, &wins);
        Tensor xg = x.detach().set_requires_grad(true);
        const Tensor y = max_pool3d(xg, k, s, p);
        ASSERT_EQ(y.shape(), shape);
        backward(y, Tensor::ones(y.shape(), DType::F64));
        EXPECT_EQ(xg.grad().to_vector(), wins) << "kernel " << k[2] << " stride " << st << " pad " << pad;
        const std::vector<double> got = y.to_vector();
        for (size_t i = 0; i < got.size(); ++i) {
          if (std::isnan(want[i])) EXPECT_TRUE(std::isnan(got[i])) << i;
          else EXPECT_EQ(got[i], want[i]) << "kernel " << k[2] << " stride " << st << " pad " << pad << " at " << i;
        }
      }
}

TEST(AvgPool, Gradcheck2dAnd3dNonContiguous) {
  EXPECT_GRADCHECK([](const TensorList& in) { return avg_pool2d(in[0], {3, 3}, {2, 2}, {1, 1}); },
                   {rand64({2, 3, 5, 4}, 4)});
  const Tensor x = permute(rand64({1, 4, 3, 5, 2}, 5), {0, 4, 2, 3, 1});  // [1, 2, 3, 5, 4]
  EXPECT_GRADCHECK([](const TensorList& in) { return avg_pool3d(in[0], {2, 3, 2}, {1, 2, 2}, {1, 1, 0}); }, {x});
}

TEST(AvgPool, PaddedPositionsCountInTheDivisor) {
  const Tensor y = avg_pool2d(Tensor::ones({1, 1, 2, 2}), {2, 2}, {2, 2}, {1, 1});
  for (double v : y.to_vector()) EXPECT_DOUBLE_EQ(v, 0.25);  // each corner window holds one 1 of 4 taps
}

TEST(GlobalAvgPool, MeansOverEverySpatialPositionAndGradchecks) {
  const Tensor y = global_avg_pool(reshape(Tensor::arange(16, DType::F64), {2, 2, 2, 2}));
  EXPECT_EQ(y.shape(), (Shape{2, 2}));
  EXPECT_EQ(y.to_vector(), (std::vector<double>{1.5, 5.5, 9.5, 13.5}));
  EXPECT_GRADCHECK([](const TensorList& in) { return global_avg_pool(in[0]); }, {rand64({2, 3, 2, 1, 3}, 6)});
}

TEST(Pooling, ErrorsNameOpAndShapes) {
  const Tensor x = Tensor::zeros({1, 1, 4, 4});
  EXPECT_THROW(max_pool2d(x, {5, 5}, {1, 1}), Error);
  EXPECT_THROW(max_pool2d(x, {2, 2}, {1, 1}, {2, 2}), Error);  // padding > kernel / 2
  EXPECT_THROW(avg_pool3d(x, {1, 1, 1}, {1, 1, 1}), Error);
  EXPECT_THROW(global_avg_pool(Tensor::zeros({2, 3})), Error);
  try {
    avg_pool2d(x, {2, 0}, {1, 1});
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("avg_pool2d"), std::string::npos);
  }
}

}  // namespace
}  // namespace sl::test
