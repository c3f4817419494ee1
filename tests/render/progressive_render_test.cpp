// Progressive rendering (render/progressive_render.h): pass schedule, budgets, the two-seed
// noise estimate against a known noise level, and reproducibility of a stopped render.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <vector>

#include "render/progressive_render.h"
#include "util/error.h"
#include "util/random.h"

namespace sl::test {

namespace {

// A fake renderer: every pixel is `truth` plus Gaussian noise of standard deviation σ/√spp
// (the mean of spp independent samples), keyed by (seed, offset) like a real pass.
struct FakePass {
  float truth = 0.2f, sigma = 0.5f;
  int H = 16, W = 16;
  std::vector<std::pair<uint64_t, int64_t>> calls;
  sl::Tensor operator()(uint64_t seed, int64_t offset, int spp) {
    calls.push_back({seed, offset});
    sl::Tensor t = sl::Tensor::empty({3, H, W});
    for (int64_t i = 0; i < t.numel(); ++i)
      t.data<float>()[i] = truth + sigma / std::sqrt(float(spp)) * float(sl::normal01(seed, uint64_t(offset), i));
    return t;
  }
};

TEST(ProgressiveRender, PassesDoubleAndStopAtTheSampleBudget) {
  FakePass fake;
  sl::render::ProgressiveOptions o;
  o.max_spp = 100;
  const sl::render::ProgressiveResult r = sl::render::render_progressive(std::ref(fake), o);
  EXPECT_EQ(r.status.spp, 100);
  EXPECT_EQ(r.status.noise, -1.0);
  const std::vector<int64_t> offsets{0, 1, 2, 4, 8, 16, 32, 64};
  ASSERT_EQ(fake.calls.size(), offsets.size());
  for (size_t k = 0; k < offsets.size(); ++k) EXPECT_EQ(fake.calls[k].second, offsets[k]);
}

// The estimate from two seeds tracks the true noise of the mean, and the loop stops at the
// first pass whose estimate meets the target.
TEST(ProgressiveRender, TwoSeedNoiseEstimateMatchesTheTrueNoiseAndMeetsTheTarget) {
  FakePass fake;
  fake.H = fake.W = 64;
  sl::render::ProgressiveOptions o;
  o.max_spp = 1 << 14;
  o.two_seeds = true;
  o.exposure = 1.0;
  o.target_noise = 0.01;
  std::vector<sl::render::ProgressiveStatus> seen;
  const sl::render::ProgressiveResult r = sl::render::render_progressive(
      std::ref(fake), o, [&](const sl::render::ProgressiveStatus& s) { seen.push_back(s); });
  ASSERT_GE(seen.size(), 3u);
  EXPECT_LE(r.status.noise, o.target_noise);
  EXPECT_GT(seen[seen.size() - 2].noise, o.target_noise);  // not one pass later than needed
  EXPECT_LT(r.status.spp, o.max_spp);
  // True LDR noise at the final spp: the pixel's σ/√spp through the slope of x^(1/2.2) at truth.
  const double slope = (1.0 / 2.2) * std::pow(double(fake.truth), 1.0 / 2.2 - 1.0);
  const double truth_noise = slope * fake.sigma / std::sqrt(double(r.status.spp));
  EXPECT_NEAR(r.status.noise, truth_noise, 0.1 * truth_noise);
  // And so does the measured error of the returned image.
  double s = 0.0;
  for (int64_t i = 0; i < r.radiance.numel(); ++i) {
    const double e = std::pow(double(r.radiance.data<float>()[i]), 1 / 2.2) - std::pow(double(fake.truth), 1 / 2.2);
    s += e * e;
  }
  EXPECT_NEAR(std::sqrt(s / r.radiance.numel()), truth_noise, 0.1 * truth_noise);
}

TEST(ProgressiveRender, RerunWithTheReachedSppReproducesTheImageBitwise) {
  FakePass a, b;
  sl::render::ProgressiveOptions o;
  o.max_spp = 1 << 12;
  o.two_seeds = true;
  o.exposure = 1.0;
  o.target_noise = 0.02;
  const sl::render::ProgressiveResult first = sl::render::render_progressive(std::ref(a), o);
  o.target_noise = 0.0;
  o.max_spp = first.status.spp;
  const sl::render::ProgressiveResult again = sl::render::render_progressive(std::ref(b), o);
  ASSERT_EQ(first.status.spp, again.status.spp);
  EXPECT_EQ(0, std::memcmp(first.radiance.data<float>(), again.radiance.data<float>(), first.radiance.numel() * 4));
}

TEST(ProgressiveRender, BadBudgetsAreRejected) {
  FakePass fake;
  sl::render::ProgressiveOptions o;
  o.target_noise = 0.01;  // without two seeds
  EXPECT_THROW(sl::render::render_progressive(std::ref(fake), o), sl::Error);
  o.target_noise = 0.0;
  o.max_spp = 0;
  EXPECT_THROW(sl::render::render_progressive(std::ref(fake), o), sl::Error);
  o.max_spp = 4;
  o.seconds = -1.0;
  EXPECT_THROW(sl::render::render_progressive(std::ref(fake), o), sl::Error);
}

}  // namespace

}  // namespace sl::test
