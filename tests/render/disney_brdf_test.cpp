// Disney BRDF: energy bounds (white furnace), reciprocity, sampling density against a histogram,
// and the extreme cases the header promises.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "render/disney_brdf.h"
#include "util/math.h"
#include "util/random.h"

namespace sl::test {

namespace {

namespace disney = sl::render::disney;
const glm::vec3 kUp(0.0f, 0.0f, 1.0f);

glm::vec3 view_at(float theta) { return {std::sin(theta), 0.0f, std::cos(theta)}; }

glm::vec3 random_hemisphere(uint64_t seed, uint64_t i) {
  const float z = sl::uniform01f(seed, i, 0);
  const float phi = 2.0f * sl::kPiF * sl::uniform01f(seed, i, 1);
  const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
  return {r * std::cos(phi), r * std::sin(phi), z};
}

sl::render::disney::Params white(float metallic, float roughness, float specular, float clearcoat) {
  sl::render::disney::Params p;
  p.base_color = glm::vec3(1.0f);
  p.metallic = metallic;
  p.roughness = roughness;
  p.specular = specular;
  p.clearcoat = clearcoat;
  return p;
}

// Directional albedo ∫ f cos dω_i by the BRDF's own importance sampling, stratified in (u1, u2).
// Lost samples (reflected below the horizon) contribute 0, which keeps the estimate unbiased.
glm::dvec3 albedo(const sl::render::disney::Params& p, const glm::vec3& wo, int strata = 128) {
  glm::dvec3 sum(0.0);
  for (int i = 0; i < strata; ++i)
    for (int j = 0; j < strata; ++j) {
      const uint64_t k = static_cast<uint64_t>(i * strata + j);
      const float u1 = (i + sl::uniform01f(7, k, 0)) / strata;
      const float u2 = (j + sl::uniform01f(7, k, 1)) / strata;
      const sl::render::disney::Sample s = sl::render::disney::sample(p, kUp, wo, u1, u2, sl::uniform01f(7, k, 2));
      if (s.pdf > 0.0f) sum += glm::dvec3(s.f * (s.wi.z / s.pdf));
    }
  return sum / double(strata * strata);
}

// The same integral by deterministic quadrature over the hemisphere, independent of sample():
// z = s² puts more nodes near the horizon, where grazing lobes live. Only for lobes wider than
// the grid (roughness ≥ 0.5).
glm::dvec3 albedo_quadrature(const sl::render::disney::Params& p, const glm::vec3& wo, int n = 800) {
  glm::dvec3 sum(0.0);
  for (int i = 0; i < n; ++i) {
    const double s = (i + 0.5) / n, z = s * s;  // dz = 2s ds
    const double r = std::sqrt(1.0 - z * z);
    for (int j = 0; j < n; ++j) {
      const double phi = 2.0 * sl::kPiF * (j + 0.5) / n;
      const glm::vec3 wi(r * std::cos(phi), r * std::sin(phi), z);
      sum += glm::dvec3(sl::render::disney::eval(p, kUp, wo, wi)) * (z * 2.0 * s);
    }
  }
  return sum * (2.0 * sl::kPiF / (double(n) * n));
}

// Pure GGX (metallic 1, no coat) reflects at most everything: single scattering only loses
// energy (the Smith masking term; no multiple-scattering compensation, Kulla & Conty 2017).
// evaluate() is eval() and pdf() in one call, with identical bits.
TEST(DisneyBrdf, EvaluateEqualsEvalAndPdf) {
  for (float metallic : {0.0f, 1.0f})
    for (float roughness : {0.05f, 0.6f})
      for (int i = 0; i < 200; ++i) {
        const auto p = white(metallic, roughness, 0.5f, i % 2 ? 0.5f : 0.0f);
        const glm::vec3 wo = view_at(0.7f), wi = random_hemisphere(11, uint64_t(i));
        const auto e = sl::render::disney::evaluate(p, kUp, wo, wi);
        EXPECT_EQ(e.f, sl::render::disney::eval(p, kUp, wo, wi));
        EXPECT_EQ(e.pdf, sl::render::disney::pdf(p, kUp, wo, wi));
      }
}

// The prepared shading point (disney::point) is what the inference shading uses for its N
// directions: its sample() and evaluate() must give the per-call forms' exact bits.
TEST(DisneyBrdf, PreparedPointGivesThePerCallBits) {
  for (float metallic : {0.0f, 1.0f})
    for (float roughness : {0.05f, 0.6f})
      for (int i = 0; i < 200; ++i) {
        const auto p = white(metallic, roughness, 0.5f, i % 2 ? 0.5f : 0.0f);
        const glm::vec3 n = glm::normalize(kUp + glm::vec3(0.1f, -0.2f, 0.0f)) * 1.7f;  // not unit: both normalise
        const glm::vec3 wo = view_at(0.02f * float(i % 80)), wi = random_hemisphere(13, uint64_t(i));
        const auto q = sl::render::disney::point(p, n, wo);
        const auto e1 = sl::render::disney::evaluate(p, n, wo, wi), e2 = sl::render::disney::evaluate(q, wi);
        EXPECT_EQ(e1.f, e2.f);
        EXPECT_EQ(e1.pdf, e2.pdf);
        const float u1 = float(i % 17) / 17.0f, u2 = float(i % 23) / 23.0f, u3 = float(i % 7) / 7.0f;
        const auto s1 = sl::render::disney::sample(p, n, wo, u1, u2, u3), s2 = sl::render::disney::sample(q, u1, u2, u3);
        EXPECT_EQ(s1.wi, s2.wi);
        EXPECT_EQ(s1.f, s2.f);
        EXPECT_EQ(s1.pdf, s2.pdf);
      }
  // A view below the horizon: no sample, as the per-call form.
  const auto q = sl::render::disney::point(white(0.0f, 0.5f, 0.5f, 0.0f), kUp, glm::vec3(0, -1, 0));
  EXPECT_FALSE(q.ok);
  EXPECT_EQ(sl::render::disney::sample(q, 0.3f, 0.4f, 0.5f).pdf, 0.0f);
}

TEST(DisneyBrdf, WhiteFurnaceAlbedoOfGgxMetalNeverExceedsOne) {
  for (float roughness : {0.0f, 0.1f, 0.25f, 0.5f, 0.75f, 1.0f})
    for (float theta_deg : {0.0f, 30.0f, 60.0f, 75.0f, 85.0f, 89.0f}) {
      const glm::dvec3 a = albedo(white(1.0f, roughness, 0.5f, 0.0f), view_at(theta_deg * sl::kPiF / 180));
      EXPECT_LE(a.g, 1.005) << "roughness " << roughness << " view " << theta_deg << " deg";
      EXPECT_GT(a.g, 0.0);
    }
}

// Burley's model adds diffuse and specular without energy coupling, and its diffuse is
// Lambertian only on average: at grazing views the Fresnel-weighted specular (F → 1) comes on
// top of a diffuse lobe that still reflects (brighter for rough surfaces, F_D90 > 1). So the
// albedo of a white surface is bounded by these measured maxima over metallic, roughness,
// specular and clearcoat (the table is printed): within 10 % of 1 up to 45°, and up to ~1.6 at
// 89° — a property of the model, not a sampling error (see the quadrature cross-check below).
TEST(DisneyBrdf, WhiteFurnaceAlbedoStaysWithinBurleysKnownExcess) {
  const struct {
    float theta_deg;
    double bound;
  } views[] = {{0.0f, 1.10}, {45.0f, 1.10}, {75.0f, 1.30}, {89.0f, 1.65}};
  for (const auto& v : views) {
    double worst = 0.0;
    for (float metallic : {0.0f, 0.5f, 1.0f})
      for (float roughness : {0.0f, 0.25f, 0.5f, 1.0f})
        for (float specular : {0.0f, 0.5f, 1.0f})
          for (float clearcoat : {0.0f, 1.0f}) {
            const glm::dvec3 a =
                albedo(white(metallic, roughness, specular, clearcoat), view_at(v.theta_deg * sl::kPiF / 180));
            ASSERT_TRUE(std::isfinite(a.r) && std::isfinite(a.g) && std::isfinite(a.b));
            worst = std::max(worst, a.g);
            EXPECT_LE(a.g, v.bound) << "metallic " << metallic << " roughness " << roughness << " specular "
                                    << specular << " clearcoat " << clearcoat << " view " << v.theta_deg;
          }
    std::printf("view %4.0f deg: largest white-furnace albedo %.4f (bound %.2f)\n", v.theta_deg, worst, v.bound);
  }
}

TEST(DisneyBrdf, SampledAlbedoMatchesQuadratureOfEval) {
  for (const sl::render::disney::Params& p :
       {white(0.0f, 1.0f, 0.5f, 0.0f), white(1.0f, 0.5f, 0.5f, 0.0f), white(0.3f, 0.7f, 1.0f, 1.0f)})
    for (float theta : {0.0f, 0.7f, 1.3f}) {
      const glm::dvec3 mc = albedo(p, view_at(theta)), quad = albedo_quadrature(p, view_at(theta));
      EXPECT_NEAR(mc.g, quad.g, 0.01 * quad.g) << "metallic " << p.metallic << " roughness " << p.roughness
                                               << " view " << theta;
    }
}

// White metal (F = 1) at normal incidence. Roughness 1 is α = 1, where D = 1/π and the albedo
// has the closed form (1/2)·∫₀¹ 2μ/(1 + μ) dμ = 1 − ln 2 ≈ 0.307: half the microfacets reflect
// the view below the horizon, the rest lose to masking. Smooth metal reflects everything.
TEST(DisneyBrdf, WhiteMetalAtNormalIncidenceReflectsAllButTheMaskingLoss) {
  const struct {
    float roughness;
    double lo, hi;
  } cases[] = {{0.0f, 0.995, 1.005}, {0.25f, 0.99, 1.003}, {0.5f, 0.90, 0.93},
               {1.0f, 1.0 - std::log(2.0) - 0.003, 1.0 - std::log(2.0) + 0.003}};
  for (const auto& c : cases) {
    const glm::dvec3 a = albedo(white(1.0f, c.roughness, 0.5f, 0.0f), kUp);
    std::printf("white metal, roughness %.2f, normal incidence: albedo %.4f\n", c.roughness, a.g);
    EXPECT_GE(a.g, c.lo) << "roughness " << c.roughness;
    EXPECT_LE(a.g, c.hi) << "roughness " << c.roughness;
  }
}

// Rough white dielectric with specular = 0 at normal incidence: the diffuse part integrates to
// exactly 1 + 1/28 (F_D90 = 1.5 + n·l when v = n), plus a small Fresnel rim from the specular lobe.
TEST(DisneyBrdf, RoughWhiteDiffuseAtNormalIncidenceIsLambertianPlusBurleyRetroReflection) {
  sl::render::disney::Params p = white(0.0f, 1.0f, 0.0f, 0.0f);
  const glm::dvec3 a = albedo(p, kUp);
  std::printf("white diffuse, roughness 1, specular 0, normal incidence: albedo %.4f\n", a.g);
  EXPECT_GE(a.g, 1.0 + 1.0 / 28.0 - 0.005);
  EXPECT_LE(a.g, 1.0 + 1.0 / 28.0 + 0.03);
  // Lambertian within the retro-reflection factor: the diffuse lobe alone is base/π at n·l = 1.
  EXPECT_NEAR(sl::render::disney::eval(p, kUp, kUp, kUp).g, 1.0f / sl::kPiF, 1e-6f);
}

TEST(DisneyBrdf, EvalIsReciprocal) {
  for (uint64_t i = 0; i < 2000; ++i) {
    sl::render::disney::Params p;
    p.base_color = glm::vec3(sl::uniform01f(3, i, 10), sl::uniform01f(3, i, 11), sl::uniform01f(3, i, 12));
    p.metallic = sl::uniform01f(3, i, 13);
    p.roughness = sl::uniform01f(3, i, 14);
    p.specular = sl::uniform01f(3, i, 15);
    p.specular_tint = sl::uniform01f(3, i, 16);
    p.sheen = sl::uniform01f(3, i, 17);
    p.clearcoat = sl::uniform01f(3, i, 18);
    p.clearcoat_gloss = sl::uniform01f(3, i, 19);
    const glm::vec3 a = random_hemisphere(4, i), b = random_hemisphere(5, i);
    const glm::vec3 fab = sl::render::disney::eval(p, kUp, a, b), fba = sl::render::disney::eval(p, kUp, b, a);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(fab[k], fba[k], 1e-4f * std::max(1.0f, std::abs(fab[k]))) << i;
  }
}

TEST(DisneyBrdf, SampleReturnsEvalAndPdfOfItsDirection) {
  const sl::render::disney::Params p = white(0.3f, 0.4f, 0.7f, 0.6f);
  const glm::vec3 n = glm::normalize(glm::vec3(0.2f, 0.9f, -0.3f));
  const glm::vec3 wo = glm::normalize(glm::vec3(0.5f, 0.6f, 0.1f));
  int valid = 0;
  for (uint64_t i = 0; i < 1000; ++i) {
    const sl::render::disney::Sample s =
        sl::render::disney::sample(p, n, wo, sl::uniform01f(9, i, 0), sl::uniform01f(9, i, 1), sl::uniform01f(9, i, 2));
    if (s.pdf == 0.0f) continue;
    ++valid;
    EXPECT_NEAR(glm::length(s.wi), 1.0f, 1e-5f);
    EXPECT_NEAR(s.pdf, sl::render::disney::pdf(p, n, wo, s.wi), 1e-4f * s.pdf);
    const glm::vec3 f = sl::render::disney::eval(p, n, wo, s.wi);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(s.f[k], f[k], 1e-4f * std::max(1.0f, f[k]));
  }
  EXPECT_GT(valid, 900);
}

// Histogram of sampled directions over equal-solid-angle bins (uniform in cos θ and φ) against
// ∫ pdf over each bin by midpoint quadrature; chi-square per degree of freedom on populated bins.
void expect_histogram_matches_pdf(const sl::render::disney::Params& p, const glm::vec3& wo) {
  constexpr int kTheta = 16, kPhi = 32, kSub = 8;
  constexpr int kSamples = 400000;
  std::vector<double> observed(kTheta * kPhi, 0.0), expected(kTheta * kPhi, 0.0);
  for (int i = 0; i < kSamples; ++i) {
    const sl::render::disney::Sample s = sl::render::disney::sample(p, kUp, wo, sl::uniform01f(11, i, 0),
                                                                    sl::uniform01f(11, i, 1), sl::uniform01f(11, i, 2));
    if (s.pdf == 0.0f) continue;
    const int bt = std::min(kTheta - 1, static_cast<int>(s.wi.z * kTheta));
    float phi = std::atan2(s.wi.y, s.wi.x);
    if (phi < 0) phi += 2 * sl::kPiF;
    const int bp = std::min(kPhi - 1, static_cast<int>(phi / (2 * sl::kPiF) * kPhi));
    observed[bt * kPhi + bp] += 1.0;
  }
  const double cell = (1.0 / (kTheta * kSub)) * (2 * sl::kPiF / (kPhi * kSub));
  for (int bt = 0; bt < kTheta; ++bt)
    for (int bp = 0; bp < kPhi; ++bp)
      for (int a = 0; a < kSub; ++a)
        for (int b = 0; b < kSub; ++b) {
          const float z = (bt * kSub + a + 0.5f) / (kTheta * kSub);
          const float phi = 2 * sl::kPiF * (bp * kSub + b + 0.5f) / (kPhi * kSub);
          const float r = std::sqrt(1 - z * z);
          const glm::vec3 wi(r * std::cos(phi), r * std::sin(phi), z);
          expected[bt * kPhi + bp] += kSamples * cell * sl::render::disney::pdf(p, kUp, wo, wi);
        }
  double chi2 = 0.0;
  int dof = 0;
  for (int k = 0; k < kTheta * kPhi; ++k) {
    if (expected[k] < 20.0) continue;
    chi2 += (observed[k] - expected[k]) * (observed[k] - expected[k]) / expected[k];
    ++dof;
  }
  ASSERT_GT(dof, 50);
  // Quadrature error on the peak bins adds to pure noise (χ²/dof ≈ 1), hence the margin.
  EXPECT_LT(chi2 / dof, 1.5) << "chi2 " << chi2 << " over " << dof << " bins, roughness " << p.roughness;
}

TEST(DisneyBrdf, SampledDirectionsFollowPdfDielectric) {
  expect_histogram_matches_pdf(white(0.0f, 0.5f, 0.5f, 0.0f), view_at(0.6f));
}
TEST(DisneyBrdf, SampledDirectionsFollowPdfRoughMetalWithClearcoat) {
  sl::render::disney::Params p = white(1.0f, 0.8f, 0.5f, 1.0f);
  p.clearcoat_gloss = 0.0f;
  expect_histogram_matches_pdf(p, view_at(1.2f));
}
TEST(DisneyBrdf, SampledDirectionsFollowPdfMixedAtNormalIncidence) {
  sl::render::disney::Params p = white(0.5f, 0.3f, 1.0f, 0.5f);
  p.base_color = glm::vec3(0.2f, 0.5f, 0.9f);
  p.sheen = 1.0f;
  expect_histogram_matches_pdf(p, kUp);
}

// ∫ pdf dω over the hemisphere equals the fraction of samples that are not lost below the
// horizon: 1 for diffuse, less for rough GGX, whose visible normals reflect grazing views
// below the horizon (up to ~25 % of all samples at roughness 0.7 and 80° here).
TEST(DisneyBrdf, PdfIntegratesToTheFractionOfValidSamples) {
  for (float roughness : {0.3f, 0.7f, 1.0f})
    for (float theta : {0.0f, 0.8f, 1.4f}) {
      sl::render::disney::Params p = white(0.5f, roughness, 0.5f, 0.5f);
      p.clearcoat_gloss = 0.0f;  // α_c = 0.1: wide enough for the quadrature grid
      const glm::vec3 wo = view_at(theta);
      constexpr int kS = 600, kPhi = 600;
      double integral = 0.0;
      for (int i = 0; i < kS; ++i)
        for (int j = 0; j < kPhi; ++j) {
          const float s = (i + 0.5f) / kS, z = s * s, phi = 2 * sl::kPiF * (j + 0.5f) / kPhi;
          const float r = std::sqrt(1 - z * z);
          integral += 2.0 * s * sl::render::disney::pdf(p, kUp, wo, {r * std::cos(phi), r * std::sin(phi), z});
        }
      integral *= (1.0 / kS) * (2 * sl::kPiF / kPhi);
      int valid = 0;
      constexpr int kSamples = 100000;
      for (int i = 0; i < kSamples; ++i)
        valid += sl::render::disney::sample(p, kUp, wo, sl::uniform01f(13, i, 0), sl::uniform01f(13, i, 1),
                                            sl::uniform01f(13, i, 2))
                     .pdf > 0.0f;
      const double fraction = double(valid) / kSamples;
      EXPECT_NEAR(integral, fraction, 0.01) << "roughness " << roughness << " view " << theta;
      EXPECT_LE(integral, 1.005);
    }
}

bool finite(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

TEST(DisneyBrdf, ExtremeInputsGiveFiniteValuesAndZeroBelowTheHorizon) {
  const glm::vec3 grazing(1.0f, 0.0f, 1e-7f), zero(0.0f), nan(std::nanf(""));
  const glm::vec3 dirs[] = {kUp, view_at(0.7f), grazing, glm::vec3(1, 0, 0), glm::vec3(0, 0, -1), zero, nan,
                            glm::vec3(1e-30f, 0, 1e-30f), glm::vec3(1e30f, 0, 1e30f)};
  for (float roughness : {0.0f, 1e-6f, 1.0f, std::nanf(""), -1.0f, 2.0f})
    for (float metallic : {0.0f, 1.0f})
      for (float clearcoat : {0.0f, 1.0f}) {
        sl::render::disney::Params p = white(metallic, roughness, 1.0f, clearcoat);
        p.clearcoat_gloss = 1.0f;
        p.sheen = 1.0f;
        for (const glm::vec3& n : {kUp, zero, nan})
          for (const glm::vec3& wo : dirs)
            for (const glm::vec3& wi : dirs) {
              const glm::vec3 f = sl::render::disney::eval(p, n, wo, wi);
              const float pd = sl::render::disney::pdf(p, n, wo, wi);
              ASSERT_TRUE(finite(f)) << roughness;
              ASSERT_TRUE(std::isfinite(pd));
              ASSERT_GE(glm::min(f.x, glm::min(f.y, f.z)), 0.0f);
              if (!(glm::dot(n, wo) > 0.0f) || !(glm::dot(n, wi) > 0.0f)) {
                EXPECT_EQ(f, glm::vec3(0.0f));
                EXPECT_EQ(pd, 0.0f);
              }
            }
        for (const glm::vec3& wo : dirs)
          for (float u : {0.0f, 0.5f, 0.99999994f, 1.0f}) {
            const sl::render::disney::Sample s = sl::render::disney::sample(p, kUp, wo, u, 1.0f - u, u);
            ASSERT_TRUE(finite(s.f) && std::isfinite(s.pdf));
            if (s.pdf > 0.0f) {
              EXPECT_GT(s.wi.z, 0.0f);
              EXPECT_TRUE(finite(s.f / s.pdf));
            }
          }
      }
}

TEST(DisneyBrdf, ScalarTermsAreFiniteAtTheirLimits) {
  for (float alpha : {sl::render::disney::kMinAlpha, 0.5f, 1.0f})
    for (float c : {0.0f, 1e-8f, 0.5f, 1.0f, 1.0000001f}) {
      EXPECT_TRUE(std::isfinite(sl::render::disney::ggx_d(c, alpha)));
      EXPECT_TRUE(std::isfinite(sl::render::disney::gtr1_d(c, std::min(alpha, 0.1f))));
      EXPECT_TRUE(std::isfinite(sl::render::disney::smith_v1(c, alpha)));
      EXPECT_LE(sl::render::disney::smith_g1(c, alpha), 1.0f + 1e-6f);
    }
  // GGX D integrates to 1 over projected solid angle: ∫ D cos θ_h dω_h = 1.
  for (float alpha : {0.05f, 0.3f, 1.0f}) {
    double s = 0.0;
    constexpr int kN = 200000;
    for (int i = 0; i < kN; ++i) {
      const double z = (i + 0.5) / kN;  // dω = dz dφ, φ integrates to 2π
      s += sl::render::disney::ggx_d(static_cast<float>(z), alpha) * z;
    }
    EXPECT_NEAR(s * 2 * sl::kPiF / kN, 1.0, 2e-3) << alpha;
  }
}

}  // namespace

namespace {

// Exact dielectric Fresnel, against closed forms: at normal incidence
// ((η − 1)/(η + 1))², at grazing incidence 1, and at 60° for η = 1.5 the mean of
// Fresnel's s- and p-reflectances written out from Snell's law.
TEST(DisneyBrdf, ExactFresnelMatchesFresnelsEquations) {
  EXPECT_NEAR(sl::render::disney::fresnel_dielectric(1.0f, 1.5f), 0.04f, 1e-6f);
  EXPECT_NEAR(sl::render::disney::fresnel_dielectric(0.0f, 1.5f), 1.0f, 1e-6f);
  EXPECT_NEAR(sl::render::disney::ior_from_f0(0.04f), 1.5f, 1e-5f);
  const double eta = 1.5, ci = 0.5, si = std::sqrt(1 - ci * ci), st = si / eta, ct = std::sqrt(1 - st * st);
  const double rs = (ci - eta * ct) / (ci + eta * ct), rp = (eta * ci - ct) / (eta * ci + ct);
  EXPECT_NEAR(sl::render::disney::fresnel_dielectric(0.5f, 1.5f), 0.5 * (rs * rs + rp * rp), 1e-6);
  // Total internal reflection from the dense side.
  EXPECT_EQ(sl::render::disney::fresnel_dielectric(0.1f, 1.0f / 1.5f), 1.0f);
  // The normalised weight runs from 0 at normal incidence to 1 at grazing, like Schlick's.
  EXPECT_NEAR(sl::render::disney::fresnel_weight(1.0f, 0.04f, true), 0.0f, 1e-6f);
  EXPECT_NEAR(sl::render::disney::fresnel_weight(0.0f, 0.04f, true), 1.0f, 1e-6f);
  for (float c = 0.0f; c <= 1.0f; c += 0.05f) {
    const float w = sl::render::disney::fresnel_weight(c, 0.04f, true);
    EXPECT_TRUE(w >= 0.0f && w <= 1.0f) << c;
    EXPECT_NEAR(w, sl::render::disney::schlick_weight(c), 0.06f) << c;  // Schlick approximates this curve
  }
}

// With exact Fresnel the BRDF stays reciprocal, finite, and differs from Schlick only in its
// specular lobes: a pure diffuse-free, coat-free dielectric at 60° shows the closed-form ratio.
TEST(DisneyBrdf, ExactFresnelOptionIsReciprocalAndChangesOnlyTheFresnelTerm) {
  for (uint64_t i = 0; i < 500; ++i) {
    sl::render::disney::Params p;
    p.base_color = glm::vec3(sl::uniform01f(9, i, 10), sl::uniform01f(9, i, 11), sl::uniform01f(9, i, 12));
    p.metallic = sl::uniform01f(9, i, 13);
    p.roughness = sl::uniform01f(9, i, 14);
    p.clearcoat = sl::uniform01f(9, i, 18);
    p.exact_fresnel = true;
    const glm::vec3 a = random_hemisphere(10, i), b = random_hemisphere(11, i);
    const glm::vec3 fab = sl::render::disney::eval(p, kUp, a, b), fba = sl::render::disney::eval(p, kUp, b, a);
    for (int k = 0; k < 3; ++k) {
      EXPECT_TRUE(std::isfinite(fab[k]));
      EXPECT_NEAR(fab[k], fba[k], 1e-4f * std::max(1.0f, std::abs(fab[k]))) << i;
    }
  }
  // Black dielectric (no diffuse), mirror direction at 60°: f ∝ F(l·h) with l·h = cos 60°.
  sl::render::disney::Params p = white(0.0f, 0.3f, 0.5f, 0.0f);
  p.base_color = glm::vec3(0.0f);
  const glm::vec3 wo = view_at(sl::kPiF / 3), wi(-wo.x, -wo.y, wo.z);
  const float schlick = sl::render::disney::eval(p, kUp, wo, wi).g;
  p.exact_fresnel = true;
  const float exact = sl::render::disney::eval(p, kUp, wo, wi).g;
  const float f0 = 0.04f;
  EXPECT_NEAR(exact / schlick,
              sl::render::disney::fresnel_dielectric(0.5f, 1.5f) /
                  (f0 + (1.0f - f0) * sl::render::disney::schlick_weight(0.5f)),
              1e-4f);
}

}  // namespace

}  // namespace sl::test
