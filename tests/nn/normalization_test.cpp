// Batch, group and instance norm: float64 gradchecks in training and eval, the running-stat
// update (unbiased, as PyTorch), statistics of the output, and errors.
#include "nn/functional/normalization.h"

#include <gtest/gtest.h>

#include <bit>
#include <functional>

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

// ---------------------------------------------------------------- fused activations
using nn::NormActivation;
using Kind = NormActivation::Kind;

// The three norms, each with an optional fused activation: (x, w, b, act) -> y.
using NormFn = std::function<Tensor(const Tensor&, const Tensor&, const Tensor&, NormActivation)>;
std::vector<std::pair<const char*, NormFn>> norms_with_activation() {
  return {{"batch_norm train", [](const Tensor& x, const Tensor& w, const Tensor& b, NormActivation a) {
             return batch_norm(x, Tensor(), Tensor(), w, b, true, 0.1, 1e-5, a);
           }},
          {"batch_norm eval", [](const Tensor& x, const Tensor& w, const Tensor& b, NormActivation a) {
             const int64_t c = x.size(1);
             const Tensor rm = Tensor::uniform({c}, -0.5, 0.5, 31, x.dtype());
             const Tensor rv = Tensor::uniform({c}, 0.5, 2.0, 32, x.dtype());
             return batch_norm(x, rm, rv, w, b, false, 0.1, 1e-5, a);
           }},
          {"group_norm", [](const Tensor& x, const Tensor& w, const Tensor& b, NormActivation a) {
             return group_norm(x, x.size(1) % 2 == 0 ? 2 : 1, w, b, 1e-5, a);
           }},
          {"instance_norm", [](const Tensor& x, const Tensor& w, const Tensor& b, NormActivation a) {
             return instance_norm(x, w, b, 1e-5, a);
           }}};
}

Tensor apply_unfused(const Tensor& y, NormActivation a) {
  if (a.kind == Kind::ReLU) return relu(y);
  if (a.kind == Kind::LeakyReLU) return leaky_relu(y, a.slope);
  return y;
}

// norm + activation as one op gives the bits of the two ops, in value and in every gradient,
// for float32 and float64, odd sizes, zero slopes, and inputs whose normalised values hit 0.
TEST(NormActivation, FusedEqualsUnfusedBitwise) {
  const std::vector<NormActivation> acts{{Kind::ReLU, 0.0}, {Kind::LeakyReLU, 0.2}, {Kind::LeakyReLU, 0.0},
                                         {Kind::LeakyReLU, 0.01}};
  const std::vector<Shape> shapes{{2, 4, 3, 5}, {3, 3, 7}, {2, 6, 2, 3, 5}, {1, 2, 33}, {2, 8, 64}};
  for (DType dt : {DType::F32, DType::F64}) {
    for (const Shape& s : shapes) {
      const int64_t c = s[1];
      Tensor x0 = Tensor::uniform(s, -2, 2, 41, dt);
      if (s == shapes[0]) x0 = clamp(x0, -0.5, 0.5);  // many repeated values
      const Tensor w0 = Tensor::uniform({c}, -1.5, 1.5, 42, dt), b0 = Tensor::uniform({c}, -0.5, 0.5, 43, dt);
      const Tensor upstream = Tensor::uniform(s, -1, 1, 44, dt);
      for (const auto& [name, norm] : norms_with_activation()) {
        for (const NormActivation& a : acts) {
          Tensor xa = x0.clone().set_requires_grad(true), wa = w0.clone().set_requires_grad(true);
          Tensor ba = b0.clone().set_requires_grad(true);
          Tensor xb = x0.clone().set_requires_grad(true), wb = w0.clone().set_requires_grad(true);
          Tensor bb = b0.clone().set_requires_grad(true);
          const Tensor fused = norm(xa, wa, ba, a);
          const Tensor unfused = apply_unfused(norm(xb, wb, bb, {}), a);
          backward(sum(mul(fused, upstream)));
          backward(sum(mul(unfused, upstream)));
          const std::string what = std::string(name) + " slope " + std::to_string(a.slope) + " " + shape_str(s);
          auto same = [&](const Tensor& p, const Tensor& q, const char* part) {
            const auto vp = p.to_vector(), vq = q.to_vector();
            ASSERT_EQ(vp.size(), vq.size());
            for (size_t i = 0; i < vp.size(); ++i)
              ASSERT_EQ(std::bit_cast<uint64_t>(vp[i]), std::bit_cast<uint64_t>(vq[i])) << what << " " << part << " " << i;
          };
          same(fused, unfused, "value");
          same(xa.grad(), xb.grad(), "dx");
          same(wa.grad(), wb.grad(), "dw");
          same(ba.grad(), bb.grad(), "db");
        }
      }
    }
  }
}

TEST(NormActivation, GradcheckFused) {
  for (const auto& [name, norm] : norms_with_activation()) {
    SCOPED_TRACE(name);
    for (const NormActivation a : {NormActivation{Kind::ReLU, 0.0}, NormActivation{Kind::LeakyReLU, 0.2}}) {
      const NormFn f = norm;
      EXPECT_GRADCHECK([f, a](const TensorList& in) { return f(in[0], in[1], in[2], a); },
                       {rand64({2, 4, 3, 2}, 45), rand64({4}, 46, 0.5, 1.5), rand64({4}, 47)});
    }
  }
}

TEST(NormActivation, NegativeSlopeIsRejected) {
  EXPECT_THROW(group_norm(Tensor::zeros({2, 4, 3}), 2, Tensor(), Tensor(), 1e-5, {Kind::LeakyReLU, -0.1}), Error);
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
