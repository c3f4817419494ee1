// depthwise_conv2d and DepthwiseConv2d: float64 gradchecks over stride, padding, non-square
// kernels and non-contiguous inputs; agreement with conv2d on a block-diagonal dense weight;
// determinism across thread counts; errors; extreme inputs.
#include "nn/functional/depthwise_conv.h"

#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <string>

#include "nn/functional/conv.h"
#include "nn/modules/depthwise_conv.h"
#include "support/test_util.h"

namespace sl::test {
using nn::conv2d;
using nn::depthwise_conv2d;

namespace {

struct Geometry {
  std::array<int64_t, 2> stride, padding;
};

TEST(DepthwiseConv2d, GradcheckStridePaddingAndNonSquareKernels) {
  struct Case { Shape w; Geometry g; };
  for (const Case& cs : {Case{{3, 1, 3, 3}, {{1, 1}, {0, 0}}}, Case{{3, 1, 3, 3}, {{1, 1}, {1, 1}}},
                         Case{{3, 1, 3, 3}, {{2, 2}, {1, 1}}}, Case{{3, 1, 3, 3}, {{2, 2}, {0, 0}}},
                         Case{{3, 1, 2, 3}, {{2, 1}, {1, 0}}}, Case{{3, 1, 3, 2}, {{1, 2}, {0, 1}}},
                         Case{{3, 1, 1, 1}, {{1, 1}, {1, 1}}},  // padding past the kernel: scattered dx
                         Case{{3, 1, 5, 4}, {{3, 2}, {2, 3}}}}) {
    SCOPED_TRACE(shape_str(cs.w) + " stride " + std::to_string(cs.g.stride[0]) + "," +
                 std::to_string(cs.g.stride[1]) + " padding " + std::to_string(cs.g.padding[0]) + "," +
                 std::to_string(cs.g.padding[1]));
    EXPECT_GRADCHECK(
        [&](const TensorList& in) { return depthwise_conv2d(in[0], in[1], in[2], cs.g.stride, cs.g.padding); },
        {rand64({2, 3, 6, 7}, 1), rand64(cs.w, 2), rand64({3}, 3)});
  }
}

TEST(DepthwiseConv2d, GradcheckWithoutBias) {
  EXPECT_GRADCHECK([](const TensorList& in) { return depthwise_conv2d(in[0], in[1], Tensor(), {2, 2}, {1, 1}); },
                   {rand64({1, 4, 5, 8}, 4), rand64({4, 1, 3, 3}, 5)});
}

TEST(DepthwiseConv2d, GradcheckNonContiguousInput) {
  const Tensor base = rand64({2, 7, 4, 3}, 6);
  const Tensor x = permute(base, {0, 3, 2, 1});  // [2, 3, 4, 7]
  ASSERT_FALSE(x.is_contiguous());
  for (int64_t s : {1, 2}) {
    EXPECT_GRADCHECK([&](const TensorList& in) { return depthwise_conv2d(in[0], in[1], in[2], {s, s}, {1, 1}); },
                     {x, rand64({3, 1, 3, 3}, 7), rand64({3}, 8)});
  }
}

// w [C, 1, kh, kw] as the dense [C, C, kh, kw] weight that is zero off the channel diagonal.
Tensor block_diagonal(const Tensor& w) {
  const int64_t C = w.size(0), taps = w.size(2) * w.size(3);
  const std::vector<double> v = w.to_vector();
  std::vector<double> dense(static_cast<size_t>(C * C * taps), 0.0);
  for (int64_t c = 0; c < C; ++c)
    for (int64_t k = 0; k < taps; ++k) dense[(c * C + c) * taps + k] = v[c * taps + k];
  return Tensor::from_vector(dense, {C, C, w.size(2), w.size(3)}, w.dtype());
}

// Output and the three gradients of the depthwise op against conv2d on the block-diagonal dense
// weight (whose weight gradient's diagonal is the depthwise one), within `tol` relative to the
// largest magnitude of each tensor.
void expect_matches_dense(const Shape& xs, const Shape& ws, const Geometry& g, DType dt, double tol) {
  Tensor x = rand64(xs, 11).to(dt), w = rand64(ws, 12).to(dt), b = rand64({ws[0]}, 13).to(dt);
  Tensor wd = block_diagonal(w), xd = x.detach().clone(), bd = b.detach().clone();
  for (Tensor* t : {&x, &w, &b, &xd, &wd, &bd}) t->set_requires_grad(true);
  const Tensor y = depthwise_conv2d(x, w, b, g.stride, g.padding);
  const Tensor yd = conv2d(xd, wd, bd, g.stride, g.padding);
  ASSERT_EQ(y.shape(), yd.shape());
  const Tensor r = rand64(y.shape(), 14).to(dt);
  backward(y, r);
  backward(yd, r);
  const int64_t C = ws[0], taps = ws[2] * ws[3];
  std::vector<double> dw_dense = wd.grad().to_vector(), dw_diag;
  for (int64_t c = 0; c < C; ++c)
    for (int64_t k = 0; k < taps; ++k) dw_diag.push_back(dw_dense[(c * C + c) * taps + k]);
  const std::vector<std::vector<double>> ours = {y.to_vector(), x.grad().to_vector(), w.grad().to_vector(),
                                                 b.grad().to_vector()};
  const std::vector<std::vector<double>> dense = {yd.to_vector(), xd.grad().to_vector(), dw_diag,
                                                  bd.grad().to_vector()};
  for (size_t k = 0; k < ours.size(); ++k) {
    ASSERT_EQ(ours[k].size(), dense[k].size());
    double scale = 1;
    for (double v : dense[k]) scale = std::max(scale, std::abs(v));
    for (size_t i = 0; i < ours[k].size(); ++i)
      ASSERT_NEAR(ours[k][i], dense[k][i], tol * scale) << "tensor " << k << " (y, dx, dw, db) element " << i;
  }
}

TEST(DepthwiseConv2d, MatchesDenseConvWithBlockDiagonalWeight) {
  struct Case { Shape x, w; Geometry g; };
  const std::vector<Case> cases = {
      {{2, 5, 20, 24}, {5, 1, 3, 3}, {{1, 1}, {1, 1}}},  // >= 96 positions: conv2d's float kernels
      {{3, 6, 9, 11}, {6, 1, 3, 3}, {{2, 2}, {1, 1}}},
      {{2, 4, 16, 18}, {4, 1, 3, 3}, {{2, 2}, {0, 0}}},
      {{2, 4, 7, 9}, {4, 1, 2, 3}, {{2, 1}, {0, 1}}},
      {{1, 3, 12, 10}, {3, 1, 5, 5}, {{1, 1}, {2, 2}}},  // the any-size kernel path
      {{4, 8, 4, 8}, {8, 1, 3, 3}, {{1, 1}, {1, 1}}},    // a MobileNet's deepest planes
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(shape_str(c.x) + " " + shape_str(c.w));
    expect_matches_dense(c.x, c.w, c.g, DType::F64, 1e-12);
    expect_matches_dense(c.x, c.w, c.g, DType::F32, 1e-5);
  }
}

// Forward and all three gradients with 1 and with 2 threads, bit for bit, on planes large enough
// to be split: stride 1 (register-tiled 3×3, dx as a correlation), stride 2 (phase-split rows,
// scattered dx), the any-size kernel, and many small planes per task.
TEST(DepthwiseConv2d, ForwardBackwardBitwiseIdenticalWithOneAndTwoThreads) {
  struct Case { Shape x, w; Geometry g; };
  const std::vector<Case> cases = {
      {{4, 32, 32, 64}, {32, 1, 3, 3}, {{1, 1}, {1, 1}}},
      {{4, 48, 16, 32}, {48, 1, 3, 3}, {{2, 2}, {1, 1}}},
      {{2, 16, 20, 30}, {16, 1, 5, 5}, {{1, 1}, {2, 2}}},
      {{8, 160, 4, 8}, {160, 1, 3, 3}, {{1, 1}, {1, 1}}},
  };
  auto run = [](int threads, const Case& c) {
    const int saved = omp_get_max_threads();
    omp_set_num_threads(threads);
    Tensor x = Tensor::normal(c.x, 0, 1, 21), w = Tensor::normal(c.w, 0, 0.3, 22), b = Tensor::normal({c.w[0]}, 0, 1, 23);
    for (Tensor* t : {&x, &w, &b}) t->set_requires_grad(true);
    Tensor y = depthwise_conv2d(x, w, b, c.g.stride, c.g.padding);
    backward(y, Tensor::normal(y.shape(), 0, 1, 24));
    std::vector<std::vector<double>> r = {y.to_vector(), x.grad().to_vector(), w.grad().to_vector(),
                                          b.grad().to_vector()};
    omp_set_num_threads(saved);
    return r;
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(shape_str(c.x));
    const auto one = run(1, c), two = run(2, c);
    for (size_t k = 0; k < one.size(); ++k) EXPECT_EQ(one[k], two[k]) << "tensor " << k << " (y, dx, dw, db)";
  }
}

TEST(DepthwiseConv2d, ErrorsNameOpAndShapes) {
  const Tensor x = Tensor::zeros({2, 8, 6, 6});
  try {
    depthwise_conv2d(x, Tensor::zeros({4, 1, 3, 3}), Tensor());
    FAIL() << "expected sl::Error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              "depthwise_conv2d: input [2, 8, 6, 6] has 8 channels, weight [4, 1, 3, 3] has 4 filters");
  }
  auto expect_error = [](const std::function<void()>& f, const std::string& what) {
    try {
      f();
      ADD_FAILURE() << "expected sl::Error for " << what;
    } catch (const Error& e) {
      EXPECT_EQ(std::string(e.what()).rfind("depthwise_conv2d: ", 0), 0u) << e.what();
    }
  };
  expect_error([&] { depthwise_conv2d(Tensor::zeros({8, 6, 6}), Tensor::zeros({8, 1, 3, 3}), Tensor()); }, "rank");
  expect_error([&] { depthwise_conv2d(x, Tensor::zeros({8, 2, 3, 3}), Tensor()); }, "two inputs per filter");
  expect_error([&] { depthwise_conv2d(x, Tensor::zeros({8, 1, 9, 3}), Tensor()); }, "kernel too large");
  expect_error([&] { depthwise_conv2d(x, Tensor::zeros({8, 1, 3, 3}), Tensor::zeros({7})); }, "bias");
  expect_error([&] { depthwise_conv2d(x, Tensor::zeros({8, 1, 3, 3}), Tensor(), {0, 1}); }, "stride");
  expect_error([&] { depthwise_conv2d(x, Tensor::zeros({8, 1, 3, 3}), Tensor(), {1, 1}, {-1, 0}); }, "padding");
  expect_error([&] { depthwise_conv2d(x, Tensor::zeros({8, 1, 3, 3}, DType::F64), Tensor()); }, "dtype");
}

TEST(DepthwiseConv2d, OutputsAndGradientsFiniteForExtremeInputs) {
  for (const auto& [xv, wv] : {std::pair{1e30, 1e-30}, std::pair{1e30, 0.0}, std::pair{0.0, 0.0}}) {
    for (int64_t s : {1, 2}) {
      Tensor x = Tensor::full({2, 3, 7, 9}, xv), w = Tensor::full({3, 1, 3, 3}, wv), b = Tensor::zeros({3});
      for (Tensor* t : {&x, &w, &b}) t->set_requires_grad(true);
      Tensor y = depthwise_conv2d(x, w, b, {s, s}, {1, 1});
      backward(sum(y));
      EXPECT_TRUE(all_finite(y)) << xv << " " << wv;
      EXPECT_TRUE(all_finite(x.grad())) << xv << " " << wv;
      EXPECT_TRUE(all_finite(w.grad())) << xv << " " << wv;
      EXPECT_TRUE(all_finite(b.grad())) << xv << " " << wv;
    }
  }
}

TEST(DepthwiseConv2dModule, HoldsPyTorchShapedParametersWithDefaultInit) {
  nn::DepthwiseConv2d layer(6, 3, 2, 1, true, 5);
  ASSERT_EQ(layer.parameter("weight").shape(), (Shape{6, 1, 3, 3}));
  ASSERT_EQ(layer.parameter("bias").shape(), (Shape{6}));
  const double bound = 1.0 / 3.0;  // 1 / sqrt(fan_in = 1·3·3)
  for (const char* name : {"weight", "bias"})
    for (double v : layer.parameter(name).to_vector()) EXPECT_LE(std::abs(v), bound) << name;
  nn::DepthwiseConv2d same_seed(6, 3, 2, 1, true, 5), other_seed(6, 3, 2, 1, true, 6);
  EXPECT_EQ(layer.parameter("weight").to_vector(), same_seed.parameter("weight").to_vector());
  EXPECT_NE(layer.parameter("weight").to_vector(), other_seed.parameter("weight").to_vector());
  EXPECT_FALSE(nn::DepthwiseConv2d(6, 3, 1, 1, false).has_parameter("bias"));
}

TEST(DepthwiseConv2dModule, ForwardIsTheFunctionalOpAndChecksChannels) {
  nn::DepthwiseConv2d layer(4, 3, 2, 1);
  const Tensor x = Tensor::normal({2, 4, 9, 10}, 0, 1, 31);
  const Tensor y = layer.forward(x);
  EXPECT_EQ(y.shape(), (Shape{2, 4, 5, 5}));
  EXPECT_EQ(y.to_vector(),
            depthwise_conv2d(x, layer.parameter("weight"), layer.parameter("bias"), {2, 2}, {1, 1}).to_vector());
  EXPECT_THROW(layer.forward(Tensor::zeros({2, 3, 9, 10})), Error);
}

}  // namespace
}  // namespace sl::test
