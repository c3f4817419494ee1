// The pieces of adaptive sampling and the residual filter of inference insertion
// (render/object_insertion.h, "Adaptive sampling" and "Denoising"): the pixel window, the
// allocation of extra samples, and the filter's contract on synthetic fields.
#include "render/insertion_denoise.h"

#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "render/insertion_foreground.h"
#include "render/pixel_window.h"
#include "util/random.h"

namespace sl::test {
namespace {
using namespace sl::render;
using namespace sl::render::insertion;

TEST(PixelWindow, NeighboursAreTheListedPixelsOfTheSquare) {
  const int64_t W = 10;
  // An L-shaped set of pixels, ascending.
  std::vector<int64_t> pixels;
  for (int y = 2; y < 6; ++y)
    for (int x = 3; x < 8; ++x)
      if (x < 5 || y > 3) pixels.push_back(int64_t(y) * W + x);
  const PixelWindow window(pixels, W);
  const std::set<int64_t> listed(pixels.begin(), pixels.end());
  for (size_t p = 0; p < pixels.size(); ++p)
    for (int r : {0, 1, 2}) {
      std::set<int64_t> got;
      window.for_neighbours(p, r, [&](size_t q) { EXPECT_TRUE(got.insert(pixels[q]).second); });
      std::set<int64_t> want;
      const int64_t x = pixels[p] % W, y = pixels[p] / W;
      for (int64_t yy = y - r; yy <= y + r; ++yy)
        for (int64_t xx = x - r; xx <= x + r; ++xx)
          if (xx >= 0 && xx < W && listed.count(yy * W + xx)) want.insert(yy * W + xx);
      EXPECT_EQ(got, want) << "pixel " << pixels[p] << " radius " << r;
    }
}

// m = clamp(t·s − N, 0, cap), rounded to even, with the budget met: N + m grows with the
// spread, flat spreads get nothing extra beyond an even share, and the cap holds.
TEST(AdaptiveSampling, AllocationMeetsTheBudgetAndFollowsTheSpread) {
  const int N = 8, cap = 64;
  std::vector<double> spread;
  std::vector<int> visible;
  for (int p = 0; p < 1000; ++p) {
    spread.push_back(p < 50 ? 10.0 : p < 500 ? 1.0 : 0.5);
    visible.push_back(p % 4 + 1);
  }
  spread[7] = NAN;  // counts as 0
  spread[8] = 0.0;
  double samples = 0;
  for (int v : visible) samples += v;
  const double budget = 4.0 * samples;
  const std::vector<int> m = adaptive_extra_samples(spread, visible, N, budget, cap);
  double cost = 0;
  for (size_t p = 0; p < m.size(); ++p) {
    EXPECT_GE(m[p], 0);
    EXPECT_LE(m[p], cap);
    EXPECT_EQ(m[p] % 2, 0);
    cost += double(visible[p]) * m[p];
  }
  // Rounding to even moves each pixel by at most 1 sample per primary sample.
  EXPECT_NEAR(cost, budget, samples + 1.0);
  EXPECT_EQ(m[7], 0);
  EXPECT_EQ(m[8], 0);
  // The noisiest pixels get the most; a pixel 20× noisier than the quietest is capped or
  // gets (N + m) ∝ s with the quiet ones at 0.
  EXPECT_GT(m[10], m[100]);
  EXPECT_GE(m[100], m[600]);
  EXPECT_EQ(m[600], 0);
  // No budget, or no spread anywhere: nothing extra.
  for (int v : adaptive_extra_samples(spread, visible, N, 0.0, cap)) EXPECT_EQ(v, 0);
  for (int v : adaptive_extra_samples(std::vector<double>(1000, 0.0), visible, N, budget, cap)) EXPECT_EQ(v, 0);
  // A budget beyond every cap: every pixel with a spread is at the cap.
  const std::vector<int> all = adaptive_extra_samples(spread, visible, N, 1e12, cap);
  EXPECT_EQ(all[10], cap);
  EXPECT_EQ(all[600], cap);
  EXPECT_EQ(all[8], 0);
}

struct Field {
  std::vector<int64_t> pixels;
  std::vector<DenoisePixel> px;
};

// A W×H block of pixels: the left half faces +z, the right half +x (a crease), each with its
// own residual ratio R/C; C varies like a texture; R carries iid noise of the given size.
Field crease_field(int W, int H, double noise, uint64_t seed) {
  Field f;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      f.pixels.push_back(int64_t(y) * W + x);
      DenoisePixel d;
      const bool left = x < W / 2;
      d.normal = left ? glm::vec3(0, 0, 1) : glm::vec3(1, 0, 0);
      d.depth = 10.0f;
      d.position = left ? glm::vec3(0.05f * float(x - W / 2), -0.05f * float(y), 0.0f)
                        : glm::vec3(0.0f, -0.05f * float(y), -0.05f * float(x - W / 2));
      d.control = glm::vec3(0.2f + 0.6f * float((x * 7 + y * 3) % 5) / 4.0f, 0.5f, 0.3f);
      const float ratio = left ? 0.1f : -0.3f;
      const float e = float(noise) * (2.0f * uniform01f(seed, uint64_t(y * W + x)) - 1.0f);
      d.residual = d.control * ratio + glm::vec3(e, e, e);
      d.variance = float(3.0 * noise * noise / 3.0 * 3.0);  // of the channel sum of 3 equal uniforms
      f.px.push_back(d);
    }
  return f;
}

InsertionOptions filter_options(int radius) {
  InsertionOptions o;
  o.denoise_radius = radius;
  return o;
}

TEST(ResidualFilter, KeepsAFieldOfOneRatioAndIsTheIdentityAtRadiusZero) {
  Field f = crease_field(12, 8, 0.0, 1);
  for (DenoisePixel& d : f.px) d.normal = glm::vec3(0, 0, 1), d.residual = 0.25f * d.control;  // one ratio
  const PixelWindow window(f.pixels, 12);
  const std::vector<glm::vec3> r = denoise_residual(f.px, window, filter_options(2));
  for (size_t p = 0; p < f.px.size(); ++p)
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(r[p][c], f.px[p].residual[c], 1e-6f * std::abs(f.px[p].residual[c]) + 1e-9f);
  const Field g = crease_field(12, 8, 0.05, 2);
  const std::vector<glm::vec3> same = denoise_residual(g.px, PixelWindow(g.pixels, 12), filter_options(0));
  for (size_t p = 0; p < g.px.size(); ++p) EXPECT_EQ(same[p], g.px[p].residual);
}

TEST(ResidualFilter, CutsIidNoiseWithoutMixingAcrossACrease) {
  const int W = 40, H = 30;
  const double noise = 0.02;
  const Field f = crease_field(W, H, noise, 3);
  const std::vector<glm::vec3> r = denoise_residual(f.px, PixelWindow(f.pixels, W), filter_options(2));
  double before = 0, after = 0, max_crease = 0;
  for (size_t p = 0; p < f.px.size(); ++p) {
    const int x = int(f.pixels[p] % W);
    const float ratio = x < W / 2 ? 0.1f : -0.3f;
    for (int c = 0; c < 3; ++c) {
      const double truth = f.px[p].control[c] * ratio;
      before += std::pow(f.px[p].residual[c] - truth, 2);
      after += std::pow(r[p][c] - truth, 2);
      // Next to the crease the other face's ratio (0.4 away) must not leak in: stay within the noise.
      if (x == W / 2 - 1 || x == W / 2) max_crease = std::max(max_crease, std::abs(r[p][c] - truth));
    }
  }
  EXPECT_LT(after, before / 4.0) << "rms before " << std::sqrt(before / f.px.size()) << " after "
                                 << std::sqrt(after / f.px.size());
  EXPECT_LT(max_crease, noise);
}

TEST(ResidualFilter, AZeroControlKeepsItsOwnResidualAndNothingIsNonFinite) {
  Field f = crease_field(8, 8, 0.01, 4);
  for (size_t p = 0; p < f.px.size(); p += 3) f.px[p].control = glm::vec3(0.0f);  // black texels
  f.px[5].normal = glm::vec3(0.0f);  // unknown normal
  f.px[6].depth = 0.0f;              // unknown depth
  f.px[9].variance = 0.0f;           // a noiseless pixel
  const std::vector<glm::vec3> r = denoise_residual(f.px, PixelWindow(f.pixels, 8), filter_options(2));
  for (size_t p = 0; p < f.px.size(); ++p) {
    for (int c = 0; c < 3; ++c) EXPECT_TRUE(std::isfinite(r[p][c])) << p;
    // All neighbours black too in a channel → its own R; otherwise C_p·(…) = 0 for a black pixel.
    if (f.px[p].control == glm::vec3(0.0f)) {
      for (int c = 0; c < 3; ++c) EXPECT_TRUE(r[p][c] == 0.0f || r[p][c] == f.px[p].residual[c]) << p;
    }
  }
}

}  // namespace
}  // namespace sl::test
