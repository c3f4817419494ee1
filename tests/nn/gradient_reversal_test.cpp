// gradient_reversal: the identity forward; backward −λ times the incoming gradient (a gradcheck at
// λ = −1, where it is the identity, and the exact map for other λ); a fresh tensor, not a view.
#include "nn/functional/gradient_reversal.h"

#include <gtest/gtest.h>

#include "autodiff/ops.h"
#include "support/test_util.h"

namespace sl::test {
using nn::gradient_reversal;

namespace {

TEST(GradientReversal, ForwardIsTheIdentityOnAFreshTensor) {
  const Tensor x = rand64({3, 4}, 1);
  const Tensor y = gradient_reversal(x, 0.7);
  EXPECT_EQ(y.to_vector(), x.to_vector());
  EXPECT_FALSE(y.same(x));
  const Tensor xt = transpose(rand64({4, 3}, 2), 0, 1);  // strided input
  EXPECT_EQ(gradient_reversal(xt, 2.0).to_vector(), xt.contiguous().to_vector());
}

TEST(GradientReversal, AtMinusOneItIsTheIdentityAndGradchecks) {
  EXPECT_GRADCHECK([](const TensorList& in) { return mul(gradient_reversal(in[0], -1.0), in[0]); },
                   {sl::test::rand64({3, 5}, 3)});
}

TEST(GradientReversal, BackwardIsMinusLambdaTimesTheIncomingGradient) {
  for (double lambda : {0.0, 0.25, 1.0, 3.0}) {
    Tensor x = rand64({2, 6}, 4).set_requires_grad(true);
    const Tensor w = rand64({2, 6}, 5);
    backward(sum(mul(gradient_reversal(x, lambda), w)));
    const auto g = x.grad().to_vector(), wv = w.to_vector();
    for (size_t i = 0; i < g.size(); ++i) EXPECT_EQ(g[i], -lambda * wv[i]) << "lambda " << lambda << " element " << i;
  }
}

TEST(GradientReversal, RejectsANonFiniteLambdaAndIntegers) {
  EXPECT_THROW(gradient_reversal(Tensor::ones({2}), std::nan("")), Error);
  EXPECT_THROW(gradient_reversal(Tensor::ones({2}), INFINITY), Error);
  EXPECT_THROW(gradient_reversal(Tensor::zeros({2}, DType::I64), 1.0), Error);
}

}  // namespace
}  // namespace sl::test
