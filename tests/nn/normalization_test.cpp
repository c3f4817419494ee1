// Batch, group and instance norm: float64 gradchecks in training and eval, the running-stat
// update (unbiased, as PyTorch), statistics of the output, and errors.
#include "nn/functional/normalization.h"

#include <gtest/gtest.h>

#include "support/test_util.h"

namespace sl::test {
using nn::batch_norm;
using nn::group_norm;
using nn::instance_norm;

namespace {

TEST(BatchNorm, GradcheckTrainingAnyRank) {
  for (const Shape& s : {Shape{4, 3}, Shape{2, 3, 4}, Shape{2, 2, 3, 2}, Shape{1, 2, 2, 3, 2}}) {
    EXPECT_GRADCHECK([](const TensorList& in) { return batch_norm(in[0], Tensor(), Tensor(), in[1], in[2], true); },
                     {rand64(s, 1), rand64({s[1]}, 2, 0.5, 1.5), rand64({s[1]}, 3)});
  }
}

TEST(BatchNorm, GradcheckEvalUsesRunningStats) {
  const Tensor rm = rand64({3}, 4), rv = rand64({3}, 5, 0.5, 2.0);
  EXPECT_GRADCHECK([&](const TensorList& in) { return batch_norm(in[0], rm, rv, in[1], in[2], false); },
                   {rand64({2, 3, 2, 2}, 6), rand64({3}, 7), rand64({3}, 8)});
}

TEST(BatchNorm, TrainingUpdatesRunningStatsWithUnbiasedVariance) {
  const Tensor x = Tensor::from_vector({1, 2, 3, 5}, {4, 1}, DType::F32);
  Tensor rm = Tensor::zeros({1}), rv = Tensor::ones({1});
  batch_norm(x, rm, rv, Tensor(), Tensor(), true, 0.1);
  // mean 2.75; biased var 2.1875; unbiased 2.9166...
  EXPECT_NEAR(rm.item(), 0.275, 1e-6);
  EXPECT_NEAR(rv.item(), 0.9 + 0.1 * (2.1875 * 4.0 / 3.0), 1e-6);
}

TEST(BatchNorm, TrainingOutputHasZeroMeanUnitVariancePerChannel) {
  const Tensor y = batch_norm(rand64({4, 2, 5}, 9), Tensor(), Tensor(), Tensor(), Tensor(), true, 0.1, 0.0);
  const Tensor m = mean(y, {0, 2}), v = mean(square(y), {0, 2});
  for (double e : m.to_vector()) EXPECT_NEAR(e, 0.0, 1e-12);
  for (double e : v.to_vector()) EXPECT_NEAR(e, 1.0, 1e-12);
}

TEST(BatchNorm, ConstantInputStaysFinite) {
  Tensor x = Tensor::full({3, 2, 4}, 7.0);
  x.set_requires_grad(true);
  Tensor y = batch_norm(x, Tensor(), Tensor(), Tensor(), Tensor(), true);
  backward(sum(y));
  EXPECT_TRUE(sl::test::all_finite(y));
  EXPECT_TRUE(sl::test::all_finite(x.grad()));
}

TEST(GroupNorm, GradcheckWithAndWithoutAffine) {
  EXPECT_GRADCHECK([](const TensorList& in) { return group_norm(in[0], 2, in[1], in[2]); },
                   {rand64({2, 4, 3, 2}, 10), rand64({4}, 11), rand64({4}, 12)});
  EXPECT_GRADCHECK([](const TensorList& in) { return group_norm(in[0], 1, Tensor(), Tensor()); },
                   {rand64({2, 3, 5}, 13)});
  const Tensor x = permute(rand64({2, 3, 2, 4}, 14), {0, 3, 2, 1});  // non-contiguous [2, 4, 2, 3]
  EXPECT_GRADCHECK([](const TensorList& in) { return group_norm(in[0], 4, in[1], Tensor()); },
                   {x, rand64({4}, 15)});
}

TEST(InstanceNorm, GradcheckAndPerChannelStatistics) {
  EXPECT_GRADCHECK([](const TensorList& in) { return instance_norm(in[0], in[1], in[2]); },
                   {rand64({2, 3, 2, 2, 2}, 16), rand64({3}, 17), rand64({3}, 18)});
  const Tensor y = instance_norm(rand64({2, 3, 7}, 19), Tensor(), Tensor(), 0.0);
  for (double e : mean(y, {2}).to_vector()) EXPECT_NEAR(e, 0.0, 1e-12);
}

TEST(Normalization, ErrorsNameOpAndShapes) {
  EXPECT_THROW(group_norm(Tensor::zeros({2, 6, 3}), 4, Tensor(), Tensor()), Error);
  EXPECT_THROW(instance_norm(Tensor::zeros({2, 6}), Tensor(), Tensor()), Error);
  EXPECT_THROW(batch_norm(Tensor::zeros({2, 3, 4}), Tensor(), Tensor(), Tensor::ones({4}), Tensor(), true), Error);
  EXPECT_THROW(batch_norm(Tensor::zeros({2, 3, 4}), Tensor(), Tensor(), Tensor(), Tensor(), false), Error);
  EXPECT_THROW(batch_norm(Tensor::zeros({1, 3}), Tensor(), Tensor(), Tensor(), Tensor(), true), Error);
}

}  // namespace
}  // namespace sl::test
