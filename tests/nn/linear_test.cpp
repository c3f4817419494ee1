// linear: gradcheck over batch dims, bias and non-contiguous inputs; values; errors.
#include "nn/functional/linear.h"

#include <gtest/gtest.h>

#include "support/test_util.h"

namespace sl::test {
using nn::linear;

namespace {

TEST(Linear, ComputesXTimesWTransposedPlusBias) {
  const Tensor x = Tensor::from_vector({1, 2}, {1, 2}, DType::F64);
  const Tensor w = Tensor::from_vector({1, 0, 2, 3, 4, 5}, {3, 2}, DType::F64);
  const Tensor b = Tensor::from_vector({1, 1, 1}, {3}, DType::F64);
  EXPECT_EQ(linear(x, w, b).to_vector(), (std::vector<double>{2, 9, 15}));
}

TEST(Linear, GradcheckBatchDimsBiasAndNonContiguous) {
  EXPECT_GRADCHECK([](const TensorList& in) { return linear(in[0], in[1], in[2]); },
                   {rand64({2, 3, 4}, 1), rand64({5, 4}, 2), rand64({5}, 3)});
  EXPECT_GRADCHECK([](const TensorList& in) { return linear(in[0], in[1], Tensor()); },
                   {rand64({4}, 4), rand64({1, 4}, 5)});
  const Tensor xt = transpose(rand64({3, 2}, 6), 0, 1);
  const Tensor wt = transpose(rand64({3, 4}, 7), 0, 1);
  EXPECT_GRADCHECK([](const TensorList& in) { return linear(in[0], in[1], Tensor()); }, {xt, wt});
}

TEST(Linear, ErrorsNameShapes) {
  try {
    linear(Tensor::zeros({2, 3}), Tensor::zeros({4, 5}), Tensor());
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "linear: input [2, 3] has 3 features, weight [4, 5] expects 5");
  }
  EXPECT_THROW(linear(Tensor::zeros({2, 3}), Tensor::zeros({4, 3}), Tensor::zeros({3})), Error);
}

}  // namespace
}  // namespace sl::test
