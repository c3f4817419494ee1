// Weight-space interpolation of two states (nn/weight_blend.h).
#include "nn/weight_blend.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "util/error.h"

namespace sl::test {
namespace {

using nn::StateDict;
using nn::blend_states;

StateDict two_tensors(double w0, double w1, double b, int64_t step) {
  StateDict s;
  s.emplace("layer.weight", Tensor::from_vector({w0, w1, -w0, 0.5 * w1}, {2, 2}));
  s.emplace("layer.bias", Tensor::from_vector({b}, {1}, DType::F64));
  s.emplace("layer.step", Tensor::from_indices({step}, {1}));
  return s;
}

TEST(WeightBlend, InterpolatesEveryFloatTensorAndKeepsTheEndsBitForBit) {
  const StateDict a = two_tensors(1.0, 3.0, -2.0, 7), b = two_tensors(0.1, -1.0, 4.0, 12);
  const StateDict mid = blend_states(a, b, 0.25);
  const std::vector<double> w = mid.at("layer.weight").to_vector();
  const std::vector<double> wa = a.at("layer.weight").to_vector(), wb = b.at("layer.weight").to_vector();
  for (size_t i = 0; i < w.size(); ++i)  // one rounding to float from the exact double blend
    EXPECT_NEAR(w[i], 0.75 * wa[i] + 0.25 * wb[i], std::ldexp(std::abs(w[i]), -24) + 1e-300) << i;
  EXPECT_DOUBLE_EQ(mid.at("layer.bias").item(), 0.75 * -2.0 + 0.25 * 4.0);
  EXPECT_EQ(mid.at("layer.step").to_indices(), std::vector<int64_t>{8});  // 0.75·7 + 0.25·12 = 8.25
  for (const double t : {0.0, 1.0}) {
    const StateDict& want = t == 0.0 ? a : b;
    const StateDict end = blend_states(a, b, t);
    for (const auto& [name, tensor] : want) EXPECT_EQ(end.at(name).to_vector(), tensor.to_vector()) << name << " t " << t;
  }
  // The inputs are untouched and the output owns new storage.
  EXPECT_EQ(a.at("layer.weight").to_vector(), wa);
  EXPECT_FALSE(mid.at("layer.weight").storage() == a.at("layer.weight").storage());
}

TEST(WeightBlend, RefusesStatesThatDifferAndWeightsOutsideTheSegment) {
  const StateDict a = two_tensors(1.0, 3.0, -2.0, 7);
  for (const double t : {-0.1, 1.5, std::numeric_limits<double>::quiet_NaN()}) EXPECT_THROW(blend_states(a, a, t), Error);
  StateDict renamed = a;
  renamed.emplace("other.weight", Tensor::zeros({1}));
  try {
    blend_states(a, renamed, 0.5);
    FAIL() << "a state with an extra tensor was blended";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("other.weight"), std::string::npos) << e.what();
  }
  StateDict reshaped = a;
  reshaped.at("layer.weight") = Tensor::zeros({4});
  EXPECT_THROW(blend_states(a, reshaped, 0.5), Error);
}

}  // namespace
}  // namespace sl::test
