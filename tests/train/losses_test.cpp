// The losses of Sec 3.4 on hand-computed cases, and their extreme cases (no NaN/Inf).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "autodiff/ops.h"
#include "train/losses.h"
#include "train/metrics.h"
#include "util/math.h"

namespace sl::test {
using train::angular_error_deg;
using train::angular_l1;
using train::depth_consistency;
using train::discriminator_hinge;
using train::generator_adversarial;
using train::log_encoded_l2;
using train::log_encoded_l2_from_log;
using train::masked_l1;
using train::median;
using train::psnr;
using train::radiance_l2;
using train::si_psnr;
using train::sky_separation_bce;

namespace {

TEST(Losses, LogEncodedL2MatchesHandValue) {
  const Tensor p = Tensor::from_vector({0.0, 3.0}, {2});
  const Tensor t = Tensor::from_vector({1.0, 3.0}, {2});
  EXPECT_NEAR(log_encoded_l2(p, t).item(), std::pow(std::log(2.0), 2) / 2, 1e-6);
  // From log: log(1 + e^y) with y = log 1 = 0 is log 2, so pred 1 vs target 1 gives 0.
  EXPECT_NEAR(log_encoded_l2_from_log(Tensor::from_vector({0.0}, {1}), Tensor::from_vector({1.0}, {1})).item(), 0, 1e-7);
  // A sun of e^60 stays finite in log form.
  const Tensor y = Tensor::from_vector({60.0}, {1}).set_requires_grad(true);
  const Tensor l = log_encoded_l2_from_log(y, Tensor::from_vector({1e6}, {1}));
  backward(l);
  EXPECT_TRUE(std::isfinite(l.item()));
  EXPECT_TRUE(std::isfinite(y.grad().item()));
}

TEST(Losses, AngularL1IsTheAngleAndFiniteAtAgreement) {
  const Tensor a = Tensor::from_vector({1, 0, 0, 0, 1, 0}, {2, 3}).set_requires_grad(true);
  const Tensor b = Tensor::from_vector({0, 1, 0, 0, 1, 0}, {2, 3});
  const Tensor l = angular_l1(a, b);
  EXPECT_NEAR(l.item(), (kPi / 2 + 0) / 2, 1e-5);
  backward(l);
  for (double g : a.grad().to_vector()) EXPECT_TRUE(std::isfinite(g));
  const Tensor z = Tensor::zeros({1, 3}).set_requires_grad(true);  // zero vector: guarded
  const Tensor lz = angular_l1(z, Tensor::from_vector({0, 1, 0}, {1, 3}));
  backward(lz);
  EXPECT_TRUE(std::isfinite(lz.item()));
  for (double g : z.grad().to_vector()) EXPECT_TRUE(std::isfinite(g));
}

TEST(Losses, MaskedL1AveragesInsideTheMaskOnly) {
  const Tensor p = Tensor::from_vector({1, 2, 3, 4}, {1, 1, 2, 2});
  const Tensor t = Tensor::zeros({1, 1, 2, 2});
  const Tensor m = Tensor::from_vector({1, 0, 0, 1}, {1, 1, 2, 2});
  EXPECT_NEAR(masked_l1(p, t, m).item(), (1 + 4) / 2.0, 1e-6);
  EXPECT_NEAR(masked_l1(p, t, Tensor::zeros({1, 1, 2, 2})).item(), 0.0, 0);  // empty mask: 0, not NaN
}

TEST(Losses, RadianceL2ComparesInLdr) {
  // LDR(1) = 1, LDR(0.5^2.2) = 0.5, LDR(100) = 1 (clipped).
  const Tensor r = Tensor::from_vector({1.0, std::pow(0.5, 2.2), 100.0}, {1, 3});
  const Tensor t = Tensor::from_vector({1.0, 0.5, 0.5}, {1, 3});
  EXPECT_NEAR(radiance_l2(r, t).item(), 0.25 / 3, 1e-5);
  const Tensor zero = Tensor::zeros({1, 3}).set_requires_grad(true);
  backward(radiance_l2(zero, t));
  for (double g : zero.grad().to_vector()) EXPECT_TRUE(std::isfinite(g));
}

TEST(Losses, DepthConsistencyNormalisesByOpacityAndSkipsInvalid) {
  // depth 5 at opacity 0.5 is a surface at 10 m: zero error; the NaN and 0 targets are skipped.
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const Tensor d = Tensor::from_vector({5.0, 1.0, 1.0}, {3}).set_requires_grad(true);
  const Tensor tau = Tensor::from_vector({0.5, 1.0, 0.0}, {3});
  const Tensor target = Tensor::from_vector({10.0, nan, 0.0}, {3});
  const Tensor l = depth_consistency(d, tau, target);
  EXPECT_NEAR(l.item(), 0.0, 1e-6);
  backward(l);
  for (double g : d.grad().to_vector()) EXPECT_TRUE(std::isfinite(g));
  const Tensor l2 = depth_consistency(Tensor::from_vector({2.0}, {1}), Tensor::from_vector({0.0}, {1}),
                                      Tensor::from_vector({std::exp(1.0) * 3 - 1}, {1}));
  EXPECT_NEAR(l2.item(), 1.0, 1e-5);  // |log 3 − log 3e|
}

TEST(Losses, SkySeparationBceIsFiniteAtZeroAndOne) {
  const Tensor tau = Tensor::from_vector({1.0, 0.0, 0.5}, {3}).set_requires_grad(true);
  const Tensor sky = Tensor::from_vector({1.0, 0.0, 1.0}, {3});
  const Tensor l = sky_separation_bce(tau, sky);
  EXPECT_NEAR(l.item(), -(std::log(1 + 1e-4) + std::log(1 + 1e-4) + std::log(0.5 + 1e-4)) / 3, 1e-5);
  backward(l);
  for (double g : tau.grad().to_vector()) EXPECT_TRUE(std::isfinite(g));
  // Wrong labels at the extremes: large but finite.
  EXPECT_TRUE(std::isfinite(sky_separation_bce(tau.detach(), Tensor::from_vector({0, 1, 0}, {3})).item()));
}

TEST(Losses, AdversarialHingeAndGenerator) {
  const Tensor real = Tensor::from_vector({2.0, 0.0}, {2});
  const Tensor fake = Tensor::from_vector({-2.0, 0.5}, {2});
  EXPECT_NEAR(discriminator_hinge(real, fake).item(), (0 + 1) / 2.0 + (0 + 1.5) / 2.0, 1e-6);
  EXPECT_NEAR(generator_adversarial(fake).item(), 0.75, 1e-6);
}

TEST(Metrics, PsnrAndScaleInvariantPsnr) {
  const Tensor t = Tensor::from_vector({0.2, 0.4, 0.6, 0.8}, {4});
  const Tensor p = Tensor::from_vector({0.1, 0.2, 0.3, 0.4}, {4});  // half of t
  EXPECT_GT(si_psnr(p, t), 90.0);                                   // exact after scaling by 2
  const double mse = (0.01 + 0.04 + 0.09 + 0.16) / 4;
  EXPECT_NEAR(psnr(p, t), 10 * std::log10(1 / mse), 1e-5);  // float32 inputs
  EXPECT_NEAR(angular_error_deg({1, 0, 0}, {0, 0, 1}), 90.0, 1e-9);
  EXPECT_DOUBLE_EQ(median({3, 1, 2, 10}), 2.5);
}

}  // namespace
}  // namespace sl::test
