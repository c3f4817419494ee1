#include <gtest/gtest.h>

#include "autodiff/ops.h"
#include "support/test_util.h"

namespace sl::test {
namespace {

using test::rand64;

TEST(Tape, BackwardAccumulatesIntoLeavesAcrossCalls) {
  Tensor x = Tensor::from_vector({1, 2, 3}, {3}, DType::F64).set_requires_grad(true);
  backward(sum(mul(x, x)));
  EXPECT_EQ(x.grad().to_vector(), (std::vector<double>{2, 4, 6}));
  backward(sum(mul(x, x)));
  EXPECT_EQ(x.grad().to_vector(), (std::vector<double>{4, 8, 12}));
  x.zero_grad();
  EXPECT_FALSE(x.grad().defined());
}

TEST(Tape, NoGradScopeRecordsNothing) {
  Tensor x = rand64({4}, 1).set_requires_grad(true);
  const size_t before = tape_size();
  {
    NoGradGuard guard;
    Tensor y = exp(x);
    EXPECT_FALSE(y.requires_grad());
    EXPECT_FALSE(grad_enabled());
  }
  EXPECT_TRUE(grad_enabled());
  EXPECT_EQ(tape_size(), before);
}

TEST(Tape, DetachStopsGradient) {
  Tensor x = rand64({3}, 2).set_requires_grad(true);
  Tensor y = add(mul(x, x.detach()), x);
  backward(sum(y));
  // d/dx [x·stop(x) + x] = stop(x) + 1
  const auto g = x.grad().to_vector(), xv = x.to_vector();
  for (size_t i = 0; i < g.size(); ++i) EXPECT_DOUBLE_EQ(g[i], xv[i] + 1.0);
}

TEST(Tape, BackwardFreesTheGraph) {
  Tensor x = rand64({8}, 3).set_requires_grad(true);
  const size_t before = tape_size();
  Tensor loss = sum(tanh(exp(x)));
  EXPECT_GT(tape_size(), before);
  backward(loss);
  EXPECT_EQ(tape_size(), before);
}

TEST(Tape, SecondBackwardThroughFreedGraphIsAClearError) {
  Tensor x = rand64({4}, 4).set_requires_grad(true);
  Tensor loss = sum(square(x));
  backward(loss);
  try {
    backward(loss);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("already freed"), std::string::npos) << e.what();
  }
}

TEST(Tape, RetainGraphAllowsASecondBackward) {
  Tensor x = Tensor::from_vector({3}, {1}, DType::F64).set_requires_grad(true);
  Tensor loss = sum(square(x));
  backward(loss, Tensor(), /*retain_graph=*/true);
  backward(loss);
  EXPECT_DOUBLE_EQ(x.grad().item(), 12.0);
}

TEST(Tape, MemoryReturnsToItsLevelBeforeForward) {
  Tensor w = rand64({64, 64}, 5).set_requires_grad(true);
  Tensor x = rand64({32, 64}, 6);
  // One warm-up step so that w.grad() exists; from then on a step must not grow memory.
  backward(sum(tanh(matmul(x, w))));
  const int64_t before = Storage::live_bytes();
  const size_t tape_before = tape_size();
  for (int i = 0; i < 3; ++i) {
    Tensor h = relu(matmul(x, w));
    Tensor loss = mean(square(sub(h, Tensor::scalar(0.5, DType::F64))));
    EXPECT_GT(Storage::live_bytes(), before);
    backward(loss);
  }
  EXPECT_EQ(Storage::live_bytes(), before);
  EXPECT_EQ(tape_size(), tape_before);
}

TEST(Tape, IndependentGraphsSurviveABackwardOfAnother) {
  // The GAN pattern: backprop the discriminator's loss on a detached fake, then the
  // generator's loss through the same fake.
  Tensor g_param = rand64({4}, 7).set_requires_grad(true);
  Tensor d_param = rand64({4}, 8).set_requires_grad(true);
  Tensor fake = tanh(g_param);
  backward(sum(mul(fake.detach(), d_param)));
  EXPECT_FALSE(g_param.grad().defined());
  d_param.zero_grad();
  backward(sum(mul(fake, d_param)));
  ASSERT_TRUE(g_param.grad().defined());
  EXPECT_TRUE(test::all_finite(g_param.grad()));
}

TEST(Tape, DroppedForwardResultsAreSweptFromTheTape) {
  Tensor x = rand64({2}, 9).set_requires_grad(true);
  const size_t before = tape_size();
  for (int i = 0; i < 20000; ++i) {
    Tensor unused = exp(mul(x, x));  // never backpropagated
  }
  EXPECT_LT(tape_size(), before + 10000);
}

TEST(Tape, GradientOfABroadcastOperandIsSummedToItsShape) {
  Tensor a = Tensor::ones({2, 3}, DType::F64).set_requires_grad(true);
  Tensor b = Tensor::ones({3}, DType::F64).set_requires_grad(true);
  backward(sum(mul(a, b)));
  EXPECT_EQ(b.grad().shape(), (Shape{3}));
  EXPECT_EQ(b.grad().to_vector(), (std::vector<double>{2, 2, 2}));
}

TEST(Tape, RequiresGradOnlyOnLeaves) {
  Tensor x = rand64({2}, 10).set_requires_grad(true);
  Tensor y = exp(x);
  EXPECT_FALSE(y.is_leaf());
  EXPECT_THROW(y.set_requires_grad(false), Error);
}

// The worked example of tape.h's custom-op interface, run for real.
struct Square : Function {
  Tensor x;
  std::string name() const override { return "square"; }
  TensorList forward(const TensorList& in) override {
    x = in[0].detach();
    return {mul(x, x)};
  }
  TensorList backward(const TensorList& grad_out) override { return {mul(grad_out[0], mul_scalar(x, 2.0))}; }
};

TEST(Tape, CustomFunctionRecordsOneNodeAndPassesGradcheck) {
  Tensor x = rand64({5}, 11).set_requires_grad(true);
  const size_t before = tape_size();
  Tensor y = apply(std::make_shared<Square>(), {x})[0];
  EXPECT_EQ(tape_size(), before + 1);
  backward(sum(y));
  EXPECT_EQ(tape_size(), before);
  EXPECT_GRADCHECK([](const TensorList& in) { return apply(std::make_shared<Square>(), {in[0]})[0]; },
                   {rand64({3, 2}, 12)});
}

TEST(Tape, CustomFunctionReleasesWhatItKeptAfterBackward) {
  Tensor x = rand64({1000}, 13).set_requires_grad(true);
  backward(sum(apply(std::make_shared<Square>(), {x})[0]));  // warm-up: creates x.grad
  const int64_t before = Storage::live_bytes();
  backward(sum(apply(std::make_shared<Square>(), {x})[0]));
  EXPECT_EQ(Storage::live_bytes(), before);
}

TEST(Tape, BackwardOnATensorThatNeedsNoGradIsAnError) {
  Tensor x = rand64({2}, 14);
  EXPECT_THROW(backward(sum(x)), Error);
}

// Gradient accumulation reuses buffers in place (autodiff/tape.cpp), so these pin down that no
// gradient a caller can see is ever written through another handle.
TEST(Tape, GradientAHeldByTheCallerIsNotChangedByALaterBackward) {
  Tensor x = Tensor::from_vector({1, 2, 3}, {3}, DType::F64).set_requires_grad(true);
  backward(sum(mul(x, x)));
  const Tensor held = x.grad();
  backward(sum(mul(x, x)));
  EXPECT_EQ(held.to_vector(), (std::vector<double>{2, 4, 6}));
  EXPECT_EQ(x.grad().to_vector(), (std::vector<double>{4, 8, 12}));
  EXPECT_FALSE(held.storage() == x.grad().storage());
}

TEST(Tape, LeavesOfOneSumGetGradientsThatDoNotAlias) {
  // add's backward passes its output gradient through to both operands unchanged.
  Tensor a = Tensor::from_vector({1, 2}, {2}, DType::F64).set_requires_grad(true);
  Tensor b = Tensor::from_vector({3, 4}, {2}, DType::F64).set_requires_grad(true);
  backward(add(a, b), Tensor::from_vector({5, 6}, {2}, DType::F64));
  ASSERT_TRUE(a.grad().defined() && b.grad().defined());
  EXPECT_FALSE(a.grad().storage() == b.grad().storage());
  EXPECT_EQ(a.grad().storage().use_count(), 1);
  a.grad().data<double>()[0] = -1;
  EXPECT_EQ(b.grad().to_vector(), (std::vector<double>{5, 6}));
}

TEST(Tape, AGradOutputPassedThroughToALeafIsCopied) {
  Tensor x = Tensor::from_vector({1, 2}, {2}, DType::F64).set_requires_grad(true);
  const Tensor seed = Tensor::from_vector({7, 8}, {2}, DType::F64);
  backward(add_scalar(x, 1.0), seed);
  EXPECT_FALSE(x.grad().storage() == seed.storage());
  seed.data<double>()[0] = 0;
  EXPECT_EQ(x.grad().to_vector(), (std::vector<double>{7, 8}));
}

TEST(Tape, ALeafReachedByManyPathsSumsEveryPath) {
  // x reaches the loss through add (shared gradient), mul, exp and a scaling: the in-place
  // accumulation must give the same bits as adding the contributions into fresh buffers.
  Tensor x = rand64({1000}, 3).set_requires_grad(true);
  backward(sum(tanh(add(mul(exp(mul_scalar(x, 0.5)), sigmoid(x)), x))));
  Tensor expected;
  {
    NoGradGuard no_grad;
    const Tensor e = exp(mul_scalar(x, 0.5)), s = sigmoid(x), y = tanh(add(mul(e, s), x));
    const Tensor gu = rsub_scalar(1.0, mul(y, y));            // d tanh
    const Tensor gm = gu;                                      // through add
    const Tensor ge = mul(gm, s), gs = mul(gm, e);             // through mul
    const Tensor gx_exp = mul_scalar(mul(ge, e), 0.5);         // exp, then x/2
    const Tensor gx_sig = mul(gs, mul(s, rsub_scalar(1.0, s)));
    expected = add(add(gu, gx_sig), gx_exp);
  }
  const std::vector<double> got = x.grad().to_vector(), want = expected.to_vector();
  for (size_t i = 0; i < got.size(); ++i) EXPECT_NEAR(got[i], want[i], 1e-12) << i;
}

}  // namespace
}  // namespace sl::test
