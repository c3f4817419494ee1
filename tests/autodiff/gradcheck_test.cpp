// Every differentiable op of autodiff/ passes a float64 central-difference gradcheck,
// with broadcasting, size-1 and size-0 dims and non-contiguous inputs where views exist.
#include <gtest/gtest.h>

#include "autodiff/ops.h"
#include "support/test_util.h"

namespace sl::test {
namespace {

using test::rand64;
using Fn = std::function<Tensor(const TensorList&)>;

// A transposed (non-contiguous) view of a contiguous leaf with the transposed shape.
Tensor nc(const Tensor& t) { return transpose(t, 0, -1); }

// ---- elementwise binary with broadcasting
struct BinaryCase {
  const char* name;
  Tensor (*op)(const Tensor&, const Tensor&);
  double lo, hi;  // input range keeping away from singularities
};

class BinaryGradcheck : public ::testing::TestWithParam<BinaryCase> {};

TEST_P(BinaryGradcheck, SameShapeBroadcastSizeOneSizeZeroAndNonContiguous) {
  const BinaryCase c = GetParam();
  auto op = c.op;
  const Fn f = [op](const TensorList& in) { return op(in[0], in[1]); };
  EXPECT_GRADCHECK(f, {rand64({3, 4}, 1, c.lo, c.hi), rand64({3, 4}, 2, c.lo, c.hi)});
  EXPECT_GRADCHECK(f, {rand64({2, 3, 4}, 3, c.lo, c.hi), rand64({4}, 4, c.lo, c.hi)});
  EXPECT_GRADCHECK(f, {rand64({2, 1, 4}, 5, c.lo, c.hi), rand64({3, 1}, 6, c.lo, c.hi)});
  EXPECT_GRADCHECK(f, {rand64({1}, 7, c.lo, c.hi), rand64({2, 3}, 8, c.lo, c.hi)});
  EXPECT_GRADCHECK(f, {rand64({0, 3}, 9, c.lo, c.hi), rand64({3}, 10, c.lo, c.hi)});
  const Fn fnc = [op](const TensorList& in) { return op(nc(in[0]), in[1]); };
  EXPECT_GRADCHECK(fnc, {rand64({4, 3}, 11, c.lo, c.hi), rand64({3, 4}, 12, c.lo, c.hi)});
}

INSTANTIATE_TEST_SUITE_P(
    Ops, BinaryGradcheck,
    ::testing::Values(BinaryCase{"add", &add, -1, 1}, BinaryCase{"sub", &sub, -1, 1}, BinaryCase{"mul", &mul, -1, 1},
                      BinaryCase{"div", &div, 0.5, 2}, BinaryCase{"pow", &pow, 0.5, 2},
                      BinaryCase{"minimum", &minimum, -1, 1}, BinaryCase{"maximum", &maximum, -1, 1},
                      BinaryCase{"atan2", &atan2, -1, 1}),
    [](const ::testing::TestParamInfo<BinaryCase>& i) { return std::string(i.param.name); });

TEST(Gradcheck, WhereBroadcastsConditionAndOperands) {
  Tensor cond = gt(rand64({3, 1}, 20), Tensor::scalar(0.0, DType::F64));
  EXPECT_GRADCHECK([cond](const TensorList& in) { return where(cond, in[0], in[1]); },
                   {rand64({3, 4}, 21), rand64({4}, 22)});
}

TEST(Gradcheck, ScalarArithmetic) {
  EXPECT_GRADCHECK([](const TensorList& in) { return add_scalar(mul_scalar(rsub_scalar(2.0, in[0]), 3.0), -1.0); },
                   {rand64({2, 3}, 23)});
}

// ---- unary
struct UnaryCase {
  const char* name;
  std::function<Tensor(const Tensor&)> op;
  double lo, hi;
};

class UnaryGradcheck : public ::testing::TestWithParam<UnaryCase> {};

TEST_P(UnaryGradcheck, ContiguousNonContiguousAndSizeZero) {
  const UnaryCase c = GetParam();
  auto op = c.op;
  EXPECT_GRADCHECK([op](const TensorList& in) { return op(in[0]); }, {rand64({3, 5}, 30, c.lo, c.hi)});
  EXPECT_GRADCHECK([op](const TensorList& in) { return op(nc(in[0])); }, {rand64({4, 1, 3}, 31, c.lo, c.hi)});
  EXPECT_GRADCHECK([op](const TensorList& in) { return op(in[0]); }, {rand64({2, 0}, 32, c.lo, c.hi)});
}

// Inputs for kinked ops (abs, relu, clamp...) are drawn away from the kink by > eps.
INSTANTIATE_TEST_SUITE_P(
    Ops, UnaryGradcheck,
    ::testing::Values(
        UnaryCase{"neg", [](const Tensor& x) { return neg(x); }, -1, 1},
        UnaryCase{"exp", [](const Tensor& x) { return exp(x); }, -2, 2},
        UnaryCase{"log", [](const Tensor& x) { return log(x); }, 0.2, 3},
        UnaryCase{"log1p", [](const Tensor& x) { return log1p(x); }, -0.5, 3},
        UnaryCase{"expm1", [](const Tensor& x) { return expm1(x); }, -2, 2},
        UnaryCase{"sqrt", [](const Tensor& x) { return sqrt(x); }, 0.2, 3},
        UnaryCase{"square", [](const Tensor& x) { return square(x); }, -2, 2},
        UnaryCase{"abs", [](const Tensor& x) { return abs(x); }, 0.1, 2},
        UnaryCase{"abs_negative", [](const Tensor& x) { return abs(x); }, -2, -0.1},
        UnaryCase{"pow_scalar", [](const Tensor& x) { return pow_scalar(x, 2.5); }, 0.2, 2},
        UnaryCase{"pow_scalar_negative_exponent", [](const Tensor& x) { return pow_scalar(x, -1.5); }, 0.5, 2},
        UnaryCase{"clamp", [](const Tensor& x) { return clamp(x, -0.5, 0.5); }, -1, 1},
        UnaryCase{"relu", [](const Tensor& x) { return relu(add_scalar(x, 0.013)); }, -1, 1},
        UnaryCase{"leaky_relu", [](const Tensor& x) { return leaky_relu(add_scalar(x, 0.013), 0.2); }, -1, 1},
        UnaryCase{"elu", [](const Tensor& x) { return elu(add_scalar(x, 0.013), 1.3); }, -2, 2},
        UnaryCase{"sigmoid", [](const Tensor& x) { return sigmoid(x); }, -4, 4},
        UnaryCase{"softplus", [](const Tensor& x) { return softplus(x); }, -4, 4},
        UnaryCase{"tanh", [](const Tensor& x) { return tanh(x); }, -2, 2},
        UnaryCase{"sin", [](const Tensor& x) { return sin(x); }, -3, 3},
        UnaryCase{"cos", [](const Tensor& x) { return cos(x); }, -3, 3},
        UnaryCase{"acos", [](const Tensor& x) { return acos(x); }, -0.9, 0.9}),
    [](const ::testing::TestParamInfo<UnaryCase>& i) { return std::string(i.param.name); });

// ---- reductions
TEST(Gradcheck, SumAndMeanOverAxesWithKeepdim) {
  for (bool keep : {false, true}) {
    EXPECT_GRADCHECK([keep](const TensorList& in) { return sum(in[0], {1}, keep); }, {rand64({2, 3, 4}, 40)});
    EXPECT_GRADCHECK([keep](const TensorList& in) { return sum(in[0], {0, -1}, keep); }, {rand64({2, 3, 4}, 41)});
    EXPECT_GRADCHECK([keep](const TensorList& in) { return mean(nc(in[0]), {0}, keep); }, {rand64({4, 3}, 42)});
  }
  EXPECT_GRADCHECK([](const TensorList& in) { return sum(in[0]); }, {rand64({3, 0, 2}, 43)});
  EXPECT_GRADCHECK([](const TensorList& in) { return mean(in[0]); }, {rand64({1, 1}, 44)});
}

TEST(Gradcheck, MaxAndMinOverAxes) {
  for (bool keep : {false, true}) {
    EXPECT_GRADCHECK([keep](const TensorList& in) { return max(in[0], {1}, keep); }, {rand64({3, 5}, 45)});
    EXPECT_GRADCHECK([keep](const TensorList& in) { return min(nc(in[0]), {0}, keep); }, {rand64({4, 3}, 46)});
  }
  EXPECT_GRADCHECK([](const TensorList& in) { return max(in[0]); }, {rand64({2, 3, 2}, 47)});
}

TEST(Gradcheck, LogsumexpAndNormalize) {
  for (bool keep : {false, true})
    EXPECT_GRADCHECK([keep](const TensorList& in) { return logsumexp(in[0], -1, keep); }, {rand64({3, 4}, 48, -3, 3)});
  EXPECT_GRADCHECK([](const TensorList& in) { return logsumexp(nc(in[0]), 0); }, {rand64({4, 2}, 49)});
  EXPECT_GRADCHECK([](const TensorList& in) { return normalize(in[0], -1); }, {rand64({5, 3}, 50)});
  EXPECT_GRADCHECK([](const TensorList& in) { return normalize(nc(in[0]), 1); }, {rand64({3, 2, 4}, 51)});
}

// ---- matmul
TEST(Gradcheck, MatmulPlainBatchedAndBroadcast) {
  const Fn f = [](const TensorList& in) { return matmul(in[0], in[1]); };
  EXPECT_GRADCHECK(f, {rand64({3, 4}, 60), rand64({4, 5}, 61)});
  EXPECT_GRADCHECK(f, {rand64({2, 3, 4}, 62), rand64({2, 4, 2}, 63)});
  EXPECT_GRADCHECK(f, {rand64({2, 3, 4}, 64), rand64({4, 2}, 65)});     // shared right operand
  EXPECT_GRADCHECK(f, {rand64({3, 4}, 66), rand64({2, 4, 2}, 67)});     // shared left operand
  EXPECT_GRADCHECK(f, {rand64({2, 1, 3, 4}, 68), rand64({3, 4, 2}, 69)});  // broadcast batch dims
  EXPECT_GRADCHECK(f, {rand64({1, 0}, 70), rand64({0, 3}, 71)});           // K = 0
  EXPECT_GRADCHECK([](const TensorList& in) { return matmul(nc(in[0]), nc(in[1])); },
                   {rand64({4, 3}, 72), rand64({2, 4}, 73)});
}

// ---- shape ops
TEST(Gradcheck, ReshapePermuteTransposeFlatten) {
  EXPECT_GRADCHECK([](const TensorList& in) { return reshape(in[0], {3, -1}); }, {rand64({2, 3, 2}, 80)});
  EXPECT_GRADCHECK([](const TensorList& in) { return reshape(nc(in[0]), {-1}); }, {rand64({3, 2}, 81)});
  EXPECT_GRADCHECK([](const TensorList& in) { return permute(in[0], {2, 0, 1}); }, {rand64({2, 3, 4}, 82)});
  EXPECT_GRADCHECK([](const TensorList& in) { return flatten(transpose(in[0], 0, 2), 1); }, {rand64({2, 3, 4}, 83)});
}

TEST(Gradcheck, SliceSelectSqueezeUnsqueezeExpand) {
  EXPECT_GRADCHECK([](const TensorList& in) { return slice(in[0], 1, 1, 5, 2); }, {rand64({2, 6}, 84)});
  EXPECT_GRADCHECK([](const TensorList& in) { return slice(nc(in[0]), 0, -2, 100); }, {rand64({2, 5}, 85)});
  EXPECT_GRADCHECK([](const TensorList& in) { return select(in[0], 1, -1); }, {rand64({2, 3, 2}, 86)});
  EXPECT_GRADCHECK([](const TensorList& in) { return squeeze(unsqueeze(in[0], 1), 0); }, {rand64({1, 3}, 87)});
  EXPECT_GRADCHECK([](const TensorList& in) { return expand(in[0], {2, 3, 4}); }, {rand64({3, 1}, 88)});
  EXPECT_GRADCHECK([](const TensorList& in) { return slice(in[0], 0, 1, 1); }, {rand64({3, 2}, 89)});  // empty
}

TEST(Gradcheck, ConcatStackPad) {
  EXPECT_GRADCHECK([](const TensorList& in) { return concat({in[0], in[1], nc(in[2])}, 1); },
                   {rand64({2, 3}, 90), rand64({2, 1}, 91), rand64({2, 2}, 92)});
  EXPECT_GRADCHECK([](const TensorList& in) { return concat({in[0], in[1]}, 0); },
                   {rand64({0, 2}, 93), rand64({3, 2}, 94)});
  EXPECT_GRADCHECK([](const TensorList& in) { return stack({in[0], in[1]}, -1); },
                   {rand64({2, 3}, 95), rand64({2, 3}, 96)});
  EXPECT_GRADCHECK([](const TensorList& in) { return pad(in[0], {{1, 2}, {0, 1}}, 0.5); }, {rand64({2, 3}, 97)});
  EXPECT_GRADCHECK([](const TensorList& in) { return pad(nc(in[0]), {{2, 0}}); }, {rand64({3, 2}, 98)});
}

// ---- index ops
TEST(Gradcheck, IndexSelectWithRepeatedIndices) {
  const Tensor idx = Tensor::from_indices({2, 0, 2, 1}, {4});
  EXPECT_GRADCHECK([idx](const TensorList& in) { return index_select(in[0], 1, idx); }, {rand64({2, 3, 2}, 100)});
  EXPECT_GRADCHECK([idx](const TensorList& in) { return index_select(nc(in[0]), 0, idx); }, {rand64({2, 3}, 101)});
}

TEST(Gradcheck, GatherAndScatterAdd) {
  const Tensor idx = Tensor::from_indices({0, 2, 2, 1, 1, 0}, {2, 3});
  EXPECT_GRADCHECK([idx](const TensorList& in) { return gather(in[0], 1, idx); }, {rand64({2, 4}, 102)});
  const Tensor idx0 = Tensor::from_indices({1, 0, 1, 1, 2, 0}, {2, 3});
  EXPECT_GRADCHECK([idx0](const TensorList& in) { return gather(nc(in[0]), 0, idx0); }, {rand64({3, 3}, 103)});
  EXPECT_GRADCHECK([idx](const TensorList& in) { return scatter_add(in[0], 1, idx, in[1]); },
                   {rand64({2, 4}, 104), rand64({2, 3}, 105)});
  EXPECT_GRADCHECK([idx0](const TensorList& in) { return scatter_add(in[0], 0, idx0, in[1]); },
                   {rand64({3, 3}, 106), rand64({2, 4}, 107)});  // src larger than index
}

// ---- grid sampling
TEST(Gradcheck, GridSample2dAllModes) {
  for (bool align : {false, true})
    for (GridPadding pad : {GridPadding::Zeros, GridPadding::Border}) {
      EXPECT_GRADCHECK([=](const TensorList& in) { return grid_sample_2d(in[0], in[1], align, pad); },
                       {rand64({2, 3, 4, 5}, 110), rand64({2, 3, 2, 2}, 111, -1.2, 1.2)});
    }
  EXPECT_GRADCHECK([](const TensorList& in) { return grid_sample_2d(permute(in[0], {0, 3, 1, 2}), in[1]); },
                   {rand64({1, 4, 3, 2}, 112), rand64({1, 2, 2, 2}, 113, -0.9, 0.9)});
}

TEST(Gradcheck, GridSample3dAllModes) {
  for (bool align : {false, true})
    for (GridPadding pad : {GridPadding::Zeros, GridPadding::Border}) {
      EXPECT_GRADCHECK([=](const TensorList& in) { return grid_sample_3d(in[0], in[1], align, pad); },
                       {rand64({1, 2, 3, 4, 3}, 114), rand64({1, 2, 1, 2, 3}, 115, -1.2, 1.2)});
    }
}

// ---- conversions are differentiable too
TEST(Gradcheck, CloneContiguousAndDtypeRoundTrip) {
  EXPECT_GRADCHECK([](const TensorList& in) { return nc(in[0]).contiguous(); }, {rand64({3, 2}, 120)});
  EXPECT_GRADCHECK([](const TensorList& in) { return in[0].clone(); }, {rand64({3}, 121)});
  // f64 -> f32 -> f64 loses precision, so check the gradient's value directly.
  Tensor x = rand64({3}, 122).set_requires_grad(true);
  backward(sum(mul_scalar(x.to(DType::F32), 3.0).to(DType::F64)));
  EXPECT_EQ(x.grad().to_vector(), (std::vector<double>{3, 3, 3}));
}

}  // namespace
}  // namespace sl::test
