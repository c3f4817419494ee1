#include "render/environment_map.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "autodiff/gradcheck.h"
#include "autodiff/ops.h"
#include "render/equirect.h"
#include "util/math.h"
#include "util/random.h"

using sl::render::env_lookup;
using sl::render::EnvironmentMap;

namespace sl::test {
namespace {

// A sky with a hard sun: 1 everywhere, `sun` in one texel.
Tensor sun_sky(int w, int h, int sun_row, int sun_col, float sun) {
  Tensor t = Tensor::ones({3, h, w});
  for (int c = 0; c < 3; ++c) t.data<float>()[(int64_t(c) * h + sun_row) * w + sun_col] = sun;
  return t;
}

TEST(EnvironmentMap, LookupAtTexelCentresReturnsTheTexel) {
  Tensor t = Tensor::uniform({3, 8, 16}, 0, 5, 1);
  EnvironmentMap env(t);
  for (int i = 0; i < 8; ++i)
    for (int j = 0; j < 16; ++j) {
      const auto d = render::equirect::uv_to_direction(j + 0.5, i + 0.5, 16, 8);
      const glm::vec3 v = env.lookup(glm::vec3(d.x, d.y, d.z));
      EXPECT_NEAR(v.g, t.at({1, i, j}), 1e-4) << i << "," << j;
    }
}

TEST(EnvironmentMap, LookupWrapsAcrossTheAzimuthSeam) {
  Tensor t = Tensor::zeros({3, 4, 8});
  for (int c = 0; c < 3; ++c) {
    t.data<float>()[(c * 4 + 1) * 8 + 0] = 2.0f;  // first column
    t.data<float>()[(c * 4 + 1) * 8 + 7] = 4.0f;  // last column
  }
  EnvironmentMap env(t);
  const auto d = render::equirect::uv_to_direction(0.0, 1.5, 8, 4);  // exactly on the seam
  EXPECT_NEAR(env.lookup(glm::vec3(d.x, d.y, d.z)).r, 3.0, 1e-4);
}

TEST(EnvironmentMap, SamplingPdfMatchesTheSampledDensity) {
  // Histogram of samples per texel against pdf × texel solid angle.
  const int W = 16, H = 8;
  EnvironmentMap env(sun_sky(W, H, 2, 5, 200.0f));
  std::vector<double> counts(W * H, 0.0);
  const int n = 200000;
  for (int s = 0; s < n; ++s) {
    const auto smp = env.sample(uniform01f(1, s, 0), uniform01f(1, s, 1));
    ASSERT_NEAR(glm::length(smp.direction), 1.0f, 1e-4f);
    ASSERT_NEAR(smp.pdf, env.pdf(smp.direction), 1e-3f * smp.pdf);
    const auto uv = render::equirect::direction_to_uv(smp.direction.x, smp.direction.y, smp.direction.z, W, H);
    counts[std::min(H - 1, int(uv.v)) * W + std::min(W - 1, int(uv.u))] += 1;
  }
  double total_prob = 0;
  for (int i = 0; i < H; ++i)
    for (int j = 0; j < W; ++j) {
      const auto c = render::equirect::uv_to_direction(j + 0.5, i + 0.5, W, H);
      const double p = env.pdf(glm::vec3(c.x, c.y, c.z)) * render::equirect::pixel_solid_angle(i, W, H);
      total_prob += p;
      const double expected = p * n;
      // Poisson counts: 5 standard deviations.
      EXPECT_NEAR(counts[i * W + j], expected, 5 * std::sqrt(expected) + 1) << i << "," << j;
    }
  EXPECT_NEAR(total_prob, 1.0, 1e-6);
}

TEST(EnvironmentMap, ImportanceSampledEstimateMatchesQuadratureWithAHugeSun) {
  // E[L/pdf] with the map's own sampling equals ∫ lookup(ω) dω (by dense quadrature), with a
  // 10^5 sun in one texel; the bound-based distribution keeps the variance small.
  const int W = 32, H = 16;
  EnvironmentMap env(sun_sky(W, H, 3, 10, 1e5f));
  double exact = 0;
  const int sub = 16;
  for (int i = 0; i < H * sub; ++i)
    for (int j = 0; j < W * sub; ++j) {
      const auto d = render::equirect::uv_to_direction((j + 0.5) / sub, (i + 0.5) / sub, W, H);
      exact += env.lookup(glm::vec3(d.x, d.y, d.z)).r * render::equirect::pixel_solid_angle(i, W * sub, H * sub);
    }
  double est = 0;
  const int n = 20000;
  for (int s = 0; s < n; ++s) {
    const auto smp = env.sample(uniform01f(2, s, 0), uniform01f(2, s, 1));
    est += smp.radiance.r / smp.pdf;
  }
  EXPECT_NEAR(est / n / exact, 1.0, 0.03);
}

// Bilinear sampling: pdf_bilinear is the density sample_bilinear draws from — a
// histogram on a fine grid (4×4 per texel, so the within-texel shape is checked, not just the
// texel's mass) against the pdf integrated over each fine cell — and it is proportional to
// the lookup's luminance inside every cell.
// The unit-coordinate forms the inference shading uses: pdf_bilinear_unit at a direction's
// coordinates is pdf_bilinear bit for bit; a sample's own coordinates give the same direction as
// the two-argument sampler and the density at that direction to float rounding.
TEST(EnvironmentMap, UnitCoordinateFormsAgreeWithTheDirectionForms) {
  const int W = 16, H = 8;
  Tensor t = sun_sky(W, H, 2, 5, 500.0f);
  EnvironmentMap env(t);
  for (int s = 0; s < 2000; ++s) {
    render::equirect::UV unit;
    const glm::vec3 d = env.sample_bilinear_direction(uniform01f(5, s, 0), uniform01f(5, s, 1), unit);
    ASSERT_EQ(d, env.sample_bilinear_direction(uniform01f(5, s, 0), uniform01f(5, s, 1)));
    const auto back = render::equirect::direction_to_uv(d.x, d.y, d.z, 1, 1);
    ASSERT_EQ(env.pdf_bilinear_unit(back), env.pdf_bilinear(d));
    ASSERT_NEAR(env.pdf_bilinear_unit(unit), env.pdf_bilinear(d), 1e-4f * env.pdf_bilinear(d));
    // The single-precision coordinates of the inner loops, and the density with the direction's
    // own cos(elevation).
    const auto fast = render::equirect::direction_to_unit(d.x, d.y, d.z);
    ASSERT_NEAR(fast.u, back.u, 1e-6);
    ASSERT_NEAR(fast.v, back.v, 1e-6);
    ASSERT_NEAR(env.pdf_bilinear_unit(fast, std::sqrt(double(d.x) * d.x + double(d.z) * d.z)), env.pdf_bilinear(d),
                1e-4f * env.pdf_bilinear(d));
  }
  // Poles and the seam.
  for (const glm::vec3& d : {glm::vec3(0, 1, 0), glm::vec3(0, -1, 0), glm::vec3(0, 0, 1), glm::vec3(-1e-7f, 0, 1)}) {
    const auto a = render::equirect::direction_to_unit(d.x, d.y, d.z);
    const auto b = render::equirect::direction_to_uv(d.x, d.y, d.z, 1, 1);
    EXPECT_NEAR(a.v, b.v, 1e-6);
    EXPECT_NEAR(std::fmod(a.u - b.u + 1.5, 1.0), 0.5, 1e-6);  // equal modulo the seam
  }
}

TEST(EnvironmentMap, BilinearSamplingPdfMatchesTheSampledDensity) {
  const int W = 16, H = 8, sub = 4;
  Tensor t = sun_sky(W, H, 2, 5, 200.0f);
  for (int c = 0; c < 3; ++c) t.data<float>()[(c * H + 0) * W + 3] = 30.0f;  // a bright texel at the zenith row
  for (int c = 0; c < 3; ++c) t.data<float>()[(c * H + 4) * W + 15] = 50.0f;  // one at the seam
  EnvironmentMap env(t);
  const int n = 400000;
  std::vector<double> counts(W * H * sub * sub, 0.0);
  for (int s = 0; s < n; ++s) {
    const auto smp = env.sample_bilinear(uniform01f(3, s, 0), uniform01f(3, s, 1));
    ASSERT_NEAR(glm::length(smp.direction), 1.0f, 1e-4f);
    ASSERT_GT(smp.pdf, 0.0f);
    ASSERT_NEAR(smp.pdf, env.pdf_bilinear(smp.direction), 1e-3f * smp.pdf);
    const auto uv =
        render::equirect::direction_to_uv(smp.direction.x, smp.direction.y, smp.direction.z, W * sub, H * sub);
    counts[std::min(H * sub - 1, int(uv.v)) * W * sub + std::min(W * sub - 1, int(uv.u))] += 1;
  }
  double total_prob = 0;
  const int q = 4;  // quadrature points per fine cell and axis
  for (int i = 0; i < H * sub; ++i)
    for (int j = 0; j < W * sub; ++j) {
      double p = 0;
      for (int a = 0; a < q; ++a)
        for (int b = 0; b < q; ++b) {
          const auto d = render::equirect::uv_to_direction(j + (b + 0.5) / q, i + (a + 0.5) / q, W * sub, H * sub);
          // Solid angle of the quadrature point's share: cos(elevation) du dv, exact at the point
          // (the pdf carries 1/cos, which a per-pixel solid angle would not cancel at the poles).
          const double cos_el = std::sqrt(std::max(0.0, 1.0 - d.y * d.y));
          const double domega = cos_el * (2 * kPi / (W * sub)) * (kPi / (H * sub)) / (q * q);
          p += env.pdf_bilinear(glm::vec3(d.x, d.y, d.z)) * domega;
        }
      total_prob += p;
      const double expected = p * n;
      EXPECT_NEAR(counts[i * W * sub + j], expected, 5 * std::sqrt(expected) + 0.01 * expected + 2) << i << "," << j;
    }
  EXPECT_NEAR(total_prob, 1.0, 2e-3);
  // Inside a cell the density follows the lookup: pdf / luminance(lookup) · cos(elevation) is
  // the cell's constant.
  for (double u : {5.6, 5.9, 6.3}) {
    const auto d0 = render::equirect::uv_to_direction(5.7, 2.6, W, H),
               d1 = render::equirect::uv_to_direction(u, 2.9, W, H);
    const glm::vec3 a(d0.x, d0.y, d0.z), b(d1.x, d1.y, d1.z);
    const double ra = env.pdf_bilinear(a) / env.lookup(a).g * std::sqrt(1 - a.y * a.y);
    const double rb = env.pdf_bilinear(b) / env.lookup(b).g * std::sqrt(1 - b.y * b.y);
    EXPECT_NEAR(ra / rb, 1.0, 1e-4) << u;
  }
}

// With a 10^5 sun the bilinear estimator of ∫ lookup dω has far lower variance than the
// texel sampler (whose L/pdf varies up to 64× beside the sun), and both are unbiased.
TEST(EnvironmentMap, BilinearSamplingOfAHugeSunHasLowVariance) {
  const int W = 32, H = 16;
  EnvironmentMap env(sun_sky(W, H, 3, 10, 1e5f));
  double exact = 0;
  const int sub = 16;
  for (int i = 0; i < H * sub; ++i)
    for (int j = 0; j < W * sub; ++j) {
      const auto d = render::equirect::uv_to_direction((j + 0.5) / sub, (i + 0.5) / sub, W, H);
      exact += env.lookup(glm::vec3(d.x, d.y, d.z)).r * render::equirect::pixel_solid_angle(i, W * sub, H * sub);
    }
  double mean[2] = {0, 0}, sq[2] = {0, 0};
  const int n = 20000;
  for (int s = 0; s < n; ++s) {
    const float u1 = uniform01f(4, s, 0), u2 = uniform01f(4, s, 1);
    const auto a = env.sample_bilinear(u1, u2), b = env.sample(u1, u2);
    const double x[2] = {a.radiance.r / a.pdf / exact, b.radiance.r / b.pdf / exact};
    for (int k = 0; k < 2; ++k) mean[k] += x[k] / n, sq[k] += x[k] * x[k] / n;
  }
  const double sd_bilinear = std::sqrt(sq[0] - mean[0] * mean[0]), sd_texel = std::sqrt(sq[1] - mean[1] * mean[1]);
  std::printf("relative sd per sample: bilinear %.4f, texel %.4f\n", sd_bilinear, sd_texel);
  EXPECT_NEAR(mean[0], 1.0, 0.01);
  EXPECT_NEAR(mean[1], 1.0, 0.03);
  EXPECT_LT(sd_bilinear, 0.25 * sd_texel);
}

TEST(EnvironmentMap, BlackMapFallsBackToUniformSphere) {
  EnvironmentMap env(Tensor::zeros({3, 4, 8}));
  const auto s = env.sample(0.3f, 0.7f);
  EXPECT_NEAR(s.pdf, 1.0 / (4 * kPi), 1e-6);
  const auto b = env.sample_bilinear(0.3f, 0.7f);
  EXPECT_NEAR(b.pdf, 1.0 / (4 * kPi), 1e-6);
  EXPECT_NEAR(env.pdf_bilinear(b.direction), 1.0 / (4 * kPi), 1e-6);
  EXPECT_TRUE(std::isfinite(s.direction.x));
}

TEST(EnvironmentMap, ResizePreservesTheIntegralWithASun) {
  EnvironmentMap env(sun_sky(64, 32, 5, 17, 1e6f));
  const glm::dvec3 before = env.integral();
  for (auto [w, h] : {std::pair{16, 8}, std::pair{48, 24}, std::pair{128, 64}}) {
    const glm::dvec3 after = env.resized(w, h).integral();
    EXPECT_NEAR(after.x / before.x, 1.0, 1e-5) << w << "x" << h;
  }
}

TEST(EnvironmentMap, RotationMovesAzimuthAndKeepsEnergy) {
  EnvironmentMap env(sun_sky(16, 8, 3, 4, 50.0f));
  EnvironmentMap rot = env.rotated(2 * kPi * 3 / 16);  // exactly three columns
  EXPECT_FLOAT_EQ(rot.texel(3, 7).r, 50.0f);
  EXPECT_NEAR(rot.integral().x / env.integral().x, 1.0, 1e-6);
}

TEST(EnvironmentMap, NegativeOrNanTexelIsAnErrorNamingIt) {
  Tensor t = Tensor::ones({3, 4, 8});
  t.data<float>()[9] = -1.0f;
  try {
    EnvironmentMap env(t);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("row 1, col 1"), std::string::npos) << e.what();
  }
}

TEST(EnvLookup, GradcheckWithRespectToTexels) {
  Tensor dirs = normalize(Tensor::uniform({7, 3}, -1, 1, 3, DType::F64), 1);
  const GradcheckResult r =
      gradcheck([dirs](const TensorList& in) { return env_lookup(in[0], dirs); }, {Tensor::uniform({3, 4, 8}, 0, 2, 4, DType::F64)});
  EXPECT_TRUE(r.ok) << r.message;
}

TEST(EnvLookup, MatchesTheScalarLookupAndIgnoresZeroDirections) {
  Tensor t = Tensor::uniform({3, 8, 16}, 0, 3, 5);
  EnvironmentMap env(t);
  Tensor dirs = Tensor::from_vector({0.3, 0.5, -0.8, 0, 0, 0, -1, 0.1, 0.2}, {3, 3});
  Tensor out = env_lookup(t, dirs);
  const glm::vec3 a = env.lookup(glm::normalize(glm::vec3(0.3f, 0.5f, -0.8f)));
  EXPECT_NEAR(out.at({0, 0}), a.r, 1e-5);
  EXPECT_EQ(out.at({1, 2}), 0.0);
}

}  // namespace
}  // namespace sl::test
