// nn/modules/batch_norm_folding.h: an eval-mode batch norm folded into the conv before it, and
// ResNet::fold_batch_norms (issue 52: inference with the batch norms folded at load time).
#include "nn/modules/batch_norm_folding.h"

#include <gtest/gtest.h>

#include <cmath>

#include "autodiff/ops.h"
#include "autodiff/tape.h"
#include "nn/functional/conv.h"
#include "nn/modules/resnet.h"

namespace sl::test {
namespace {

// Running statistics and affine parameters far from the identity, so that a wrong fold shows.
void randomise(nn::BatchNormNd& bn, uint64_t seed) {
  const int64_t c = bn.features();
  bn.buffer("running_mean").copy_(Tensor::uniform({c}, -0.5, 0.5, seed));
  bn.buffer("running_var").copy_(Tensor::uniform({c}, 0.3, 3.0, seed + 1));
  bn.parameter("weight").copy_(Tensor::uniform({c}, 0.5, 1.5, seed + 2));
  bn.parameter("bias").copy_(Tensor::uniform({c}, -0.3, 0.3, seed + 3));
}

double max_abs(const Tensor& t) { return max(abs(t)).item(); }

// One pair, float32, with and without a conv bias. The bound is derived from the arithmetic: each
// of the two paths computes s·(Σ w·x + b − μ) + β with a dot product of K = C·k² terms and a few
// more operations, so each is within (K + 4)·u·M of the exact value, M = s·(Σ|w||x| + |b| + |μ|)
// + |β| (u = 2^-24 the unit roundoff), and they are within twice that of each other.
TEST(BatchNormFolding, AConvAndItsBatchNormBecomeOneConvWithinTheRoundingBound) {
  const NoGradGuard no_grad;
  for (const bool bias : {false, true}) {
    const int64_t C = 6, O = 5, k = 3;
    nn::Conv2d conv(C, O, k, nn::ConvOptions{.padding = 1, .bias = bias});
    nn::BatchNorm2d bn(O);
    randomise(bn, 7);
    bn.eval();
    const Tensor x = Tensor::uniform({2, C, 9, 11}, -1.0, 1.0, 3);
    const Tensor before = bn.forward(conv.forward(x));
    // M per output, in float64.
    const Tensor w64 = conv.parameter("weight").to(DType::F64);
    const Tensor awx = nn::conv2d(abs(x.to(DType::F64)), abs(w64), Tensor(), {1, 1}, {1, 1});
    const std::vector<double> mean = bn.buffer("running_mean").to_vector(), var = bn.buffer("running_var").to_vector(),
                              gamma = bn.parameter("weight").to_vector(), beta = bn.parameter("bias").to_vector();
    const std::vector<double> b = bias ? conv.parameter("bias").to_vector() : std::vector<double>(O, 0.0);
    const std::vector<double> a = awx.to_vector();
    const int64_t plane = awx.size(2) * awx.size(3);
    std::vector<double> bound(a.size());
    const double u = std::ldexp(1.0, -24);
    for (size_t i = 0; i < a.size(); ++i) {
      const int64_t o = static_cast<int64_t>(i / plane) % O;
      const double s = gamma[o] / std::sqrt(var[o] + bn.eps());
      bound[i] = 2.0 * (C * k * k + 4) * u * (s * (a[i] + std::abs(b[o]) + std::abs(mean[o])) + std::abs(beta[o]));
    }
    nn::fold_batch_norm(conv, bn);
    EXPECT_TRUE(conv.options().bias);
    EXPECT_TRUE(bn.folded());
    const Tensor after = bn.forward(conv.forward(x));
    const std::vector<double> d = sub(after, before).to_vector();
    double worst = 0.0;
    for (size_t i = 0; i < d.size(); ++i) {
      ASSERT_LE(std::abs(d[i]), bound[i]) << "output " << i << " bias " << bias;
      worst = std::max(worst, std::abs(d[i]) / bound[i]);
    }
    EXPECT_GT(max_abs(after), 0.1);
    RecordProperty(bias ? "worst_fraction_of_bound_bias" : "worst_fraction_of_bound", std::to_string(worst));
  }
}

// A whole ResNet-18 (width 8) in eval mode, folded against unfolded, relative to the features'
// scale. The per-layer bound above, 2·(K + 4)·u with K ≤ 9·64 taps·channels, over the 20 convs of
// the longest path, is about 2.4e4·u: 3e-12 in float64 (u = 2^-53; tested to 1e-12, as the bound
// counts every rounding at its worst) and 1.4e-3 in float32 (u = 2^-24; tested to 1e-3).
// Measured (AVX-512): 4e-16 and 2e-7.
TEST(BatchNormFolding, AFoldedResNetComputesTheSameFeatures) {
  const NoGradGuard no_grad;
  for (const DType t : {DType::F64, DType::F32}) {
    nn::ResNet net(nn::ResNetOptions{.depth = 18, .base_width = 8, .seed = 4});
    uint64_t seed = 100;
    for (auto& [name, m] : net.named_modules())
      if (auto* bn = dynamic_cast<nn::BatchNormNd*>(m)) randomise(*bn, seed += 10);
    net.to(t);
    net.eval();
    const Tensor x = Tensor::uniform({2, 3, 64, 96}, 0.0, 1.0, 9).to(t);
    const nn::ResNetOutput before = net.forward_features(x);
    net.fold_batch_norms();
    const nn::ResNetOutput after = net.forward_features(x);
    const double scale = max_abs(before.pooled), diff = max_abs(sub(after.pooled, before.pooled));
    ASSERT_GT(scale, 1e-3);
    EXPECT_LE(diff, (t == DType::F64 ? 1e-12 : 1e-3) * scale) << "relative " << diff / scale;
    for (size_t i = 0; i < before.features.size(); ++i)
      EXPECT_LE(max_abs(sub(after.features[i], before.features[i])),
                (t == DType::F64 ? 1e-12 : 1e-3) * max_abs(before.features[i]))
          << "layer" << i + 1;
    RecordProperty(t == DType::F64 ? "relative_difference_f64" : "relative_difference_f32", std::to_string(diff / scale));
    std::printf("ResNet-18 (width 8), %s: folded vs unfolded max |diff| / max |features| = %.3g\n",
                t == DType::F64 ? "float64" : "float32", diff / scale);
  }
}

TEST(BatchNormFolding, AFoldedBatchNormRefusesTrainingAndASecondFold) {
  nn::Conv2d conv(3, 4, 3, nn::ConvOptions{.padding = 1, .bias = false});
  nn::BatchNorm2d bn(4);
  nn::fold_batch_norm(conv, bn);
  EXPECT_THROW(nn::fold_batch_norm(conv, bn), Error);
  bn.train();
  EXPECT_THROW(bn.forward(Tensor::zeros({1, 4, 2, 2})), Error);
  nn::BatchNorm2d other(5);
  nn::Conv2d conv2(3, 4, 3);
  EXPECT_THROW(nn::fold_batch_norm(conv2, other), Error);
}

}  // namespace
}  // namespace sl::test
