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
