// The losses of Sec 3.4 on hand-computed cases, and their extreme cases (no NaN/Inf).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "autodiff/gradcheck.h"
#include "autodiff/ops.h"
#include "train/losses.h"
#include "support/torch_fixture.h"
#include "train/metrics.h"
#include "train/sun_distribution.h"
#include "util/math.h"

namespace sl::test {
using train::angular_error_deg;
using train::angular_l1;
using train::depth_consistency;
using train::discriminator_hinge;
using train::elevation_azimuth_l1;
using train::generator_adversarial;
using train::log_encoded_l2;
using train::log_encoded_l2_from_log;
using train::log_encoded_range_l2_from_log;
using train::masked_l1;
using train::median;
using train::psnr;
using train::radiance_l2;
using train::si_psnr;
using train::sky_separation_bce;
using train::bce_with_logits;

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

TEST(Losses, LogEncodedRangeL2IsZeroInsideAndTheDistanceToTheNearestEnd) {
  // x̂ = 0.5, 3, 20 against [1, 10]: log(1 + x̂) lies below, inside and above the span.
  const Tensor y = Tensor::from_vector({std::log(0.5), std::log(3.0), std::log(20.0)}, {3});
  const double below = std::log(2.0) - std::log(1.5), above = std::log(21.0) - std::log(11.0);
  EXPECT_NEAR(log_encoded_range_l2_from_log(y, 1.0, 10.0).item(), (below * below + above * above) / 3, 1e-6);
  EXPECT_EQ(log_encoded_range_l2_from_log(Tensor::from_vector({std::log(3.0)}, {1}), 1.0, 10.0).item(), 0.0);
  // A sun of e^60 and one of e^-60 stay finite, with finite gradients pointing back into the span.
  const Tensor e = Tensor::from_vector({60.0, -60.0}, {2}).set_requires_grad(true);
  const Tensor l = log_encoded_range_l2_from_log(e, 1.0, 10.0);
  backward(l);
  EXPECT_TRUE(std::isfinite(l.item()));
  EXPECT_GT(e.grad().at({0}), 0.0);
  EXPECT_LT(e.grad().at({1}), 0.0);
  // float64 gradcheck away from the kinks at the span's ends.
  const Tensor p = Tensor::from_vector({-2.0, 0.7, 3.5, 1.2}, {2, 2}).to(DType::F64).set_requires_grad(true);
  const GradcheckResult r = gradcheck([&](const TensorList& in) { return log_encoded_range_l2_from_log(in[0], 1.0, 10.0); }, {p});
  EXPECT_TRUE(r.ok) << r.message;
  EXPECT_THROW(log_encoded_range_l2_from_log(p, 2.0, 1.0), Error);
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

glm::dvec3 sun_at(double elevation_deg, double azimuth_deg) {
  const double e = elevation_deg * kPi / 180, a = azimuth_deg * kPi / 180;
  return {std::cos(e) * std::sin(a), std::sin(e), -std::cos(e) * std::cos(a)};  // render/equirect.h
}

TEST(Losses, ElevationAzimuthL1MatchesHandValuesAndItsGradcheck) {
  // Same azimuth, 20° apart in elevation: 20°. Same elevation 60°, azimuths 170° and −170°
  // (20° apart across the wrap): cos 60°·20° = 10°.
  const glm::dvec3 a = sun_at(30, 40), b = sun_at(50, 40), c = sun_at(60, 170), d = sun_at(60, -170);
  const Tensor p = Tensor::from_vector({a.x, a.y, a.z, 2 * c.x, 2 * c.y, 2 * c.z}, {2, 3});  // length is ignored
  const Tensor t = Tensor::from_vector({b.x, b.y, b.z, d.x, d.y, d.z}, {2, 3});
  EXPECT_NEAR(elevation_azimuth_l1(p, t).item(), (20.0 + 10.0) / 2 * kPi / 180, 1e-6);
  // A zero prediction and a zenith target are guarded: finite value and gradient.
  const Tensor z = Tensor::zeros({1, 3}).set_requires_grad(true);
  const Tensor lz = elevation_azimuth_l1(z, Tensor::from_vector({0, 1, 0}, {1, 3}));
  backward(lz);
  EXPECT_TRUE(std::isfinite(lz.item()));
  for (double g : z.grad().to_vector()) EXPECT_TRUE(std::isfinite(g));
  // float64 finite differences, away from the kinks (|Δθ| = 0, Δφ = 0 or ±π).
  const Tensor target = Tensor::from_vector({b.x, b.y, b.z, d.x, d.y, d.z}, {2, 3}).to(DType::F64);
  const glm::dvec3 e = sun_at(30, 55);
  const Tensor pred = Tensor::from_vector({e.x, e.y, e.z, 0.3, 0.5, -0.8}, {2, 3}).to(DType::F64);
  const GradcheckResult r = gradcheck([&](const TensorList& in) { return elevation_azimuth_l1(in[0], target); }, {pred});
  EXPECT_TRUE(r.ok) << r.message;
}

// The reason for the split form: when the azimuth is uncertain (targets spread over a ring at
// elevation 30°), the one prediction minimising angular_l1 climbs to the zenith, while the one
// minimising elevation_azimuth_l1 keeps the ring's elevation.
TEST(Losses, UnderAnUncertainAzimuthTheSplitFormKeepsTheElevation) {
  std::vector<double> ring;
  for (int k = 0; k < 12; ++k) {
    const glm::dvec3 s = sun_at(30, -180 + 30 * k + 7);
    ring.insert(ring.end(), {s.x, s.y, s.z});
  }
  const Tensor targets = Tensor::from_vector(ring, {12, 3}).to(DType::F64);
  auto fit = [&](bool split) {
    Tensor w = Tensor::from_vector({0.6, 0.5, -0.6}, {1, 3}).to(DType::F64);  // start at elevation ~30°
    for (int it = 0; it < 3000; ++it) {
      const Tensor p = w.detach().set_requires_grad(true);
      const Tensor pred = expand(p, {12, 3});
      const Tensor l = split ? elevation_azimuth_l1(pred, targets) : angular_l1(pred, targets);
      backward(l);
      w = sub(p.detach(), mul_scalar(p.grad(), 0.01));
      w = mul_scalar(w, 1.0 / std::sqrt(sum(square(w)).item()));
    }
    return std::asin(std::clamp(w.to_vector()[1], -1.0, 1.0)) * 180 / kPi;
  };
  EXPECT_GT(fit(false), 80.0);
  EXPECT_NEAR(fit(true), 30.0, 3.0);
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

// The domain classifier's loss: −mean(y log σ(z) + (1 − y) log(1 − σ(z))) by hand; a gradcheck; at
// logits of ±1e4 (a classifier sure of itself, right or wrong) value and gradient stay finite.
TEST(Losses, BceWithLogitsMatchesHandValuesGradchecksAndStaysFinite) {
  const std::vector<double> z = {-2.0, 0.0, 1.5}, y = {0.0, 1.0, 1.0};
  double want = 0;
  for (int i = 0; i < 3; ++i) {
    const double p = 1.0 / (1.0 + std::exp(-z[i]));
    want -= (y[i] * std::log(p) + (1 - y[i]) * std::log(1 - p)) / 3;
  }
  EXPECT_NEAR(bce_with_logits(Tensor::from_vector(z, {3}).to(DType::F64), Tensor::from_vector(y, {3}).to(DType::F64)).item(),
              want, 1e-12);
  const Tensor labels = Tensor::from_vector({0.0, 1.0, 1.0, 0.0}, {4}).to(DType::F64);
  const GradcheckResult r =
      gradcheck([&](const TensorList& in) { return bce_with_logits(in[0], labels); },
                {Tensor::from_vector({-2.5, -0.3, 0.8, 2.2}, {4}).to(DType::F64)});
  EXPECT_TRUE(r.ok) << r.message;
  const Tensor extreme = Tensor::from_vector({1e4, -1e4, 1e4, -1e4}, {4}).set_requires_grad(true);
  const Tensor l = bce_with_logits(extreme, Tensor::from_vector({0.0, 1.0, 1.0, 0.0}, {4}));
  EXPECT_NEAR(l.item(), 0.5e4, 1.0);  // two wrong by 1e4, two right
  backward(l);
  for (double g : extreme.grad().to_vector()) EXPECT_TRUE(std::isfinite(g));
  EXPECT_THROW(bce_with_logits(Tensor::zeros({3}), Tensor::zeros({4})), Error);
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

// The losses PyTorch also has, against PyTorch 1.13 on tests/fixtures/torch/losses.safetensors:
// bce_with_logits = F.binary_cross_entropy_with_logits (logits up to ±1e4), the sun
// distribution's weighted soft-target cross-entropy = mean(F.cross_entropy(z, t, reduction="none")
// · w) (logits of spread 3 and 80), and l1 = F.l1_loss. Outputs and gradients.
TEST(Losses, MatchPyTorchOnItsFixtures) {
  size_t cases = 0;
  run_torch_family("losses.safetensors", [&](const Fixture&, const std::string&, const nlohmann::json& c, auto& in) {
    ++cases;
    const std::string op = c.at("op");
    if (op == "bce_with_logits") return bce_with_logits(in["x"], in["y"]);
    if (op == "soft_cross_entropy") return train::sun_distribution_loss(in["x"], in["y"], in["w"]);
    if (op == "l1") return train::l1(in["x"], in["y"]);
    ADD_FAILURE() << "the fixture names an op this test does not know: " << op;
    return Tensor();
  });
  EXPECT_EQ(cases, 4u) << "every case of the fixture ran";
}

}  // namespace
}  // namespace sl::test
