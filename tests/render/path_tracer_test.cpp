// Reference path tracer against analytic cases: a Lambertian sphere under a constant sky, the
// cosine law under a small sun, the white furnace with interreflections; plus determinism
// across thread counts, MIS consistency and the extreme cases.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <cstdio>
#include <cstring>

#include "render/camera.h"
#include "render/equirect.h"
#include "render/path_tracer.h"
#include "render/primitives.h"
#include "util/math.h"

using sl::render::PathTracer;

namespace sl::test {

namespace {

sl::render::EnvironmentMap constant_env(const glm::vec3& L, int width = 16) {
  sl::Tensor t = sl::Tensor::empty({3, width / 2, width});
  float* p = t.data<float>();
  const int64_t plane = int64_t(width / 2) * width;
  for (int c = 0; c < 3; ++c)
    for (int64_t i = 0; i < plane; ++i) p[c * plane + i] = L[c];
  return sl::render::EnvironmentMap(t);
}

// Black sky with a disk of radiance `sun` and angular radius `radius_rad` around `dir`.
sl::render::EnvironmentMap sun_env(const glm::vec3& dir, float radius_rad, float sun, float sky = 0.0f) {
  const int W = 512, H = 256;
  sl::Tensor t = sl::Tensor::empty({3, H, W});
  float* p = t.data<float>();
  for (int i = 0; i < H; ++i)
    for (int j = 0; j < W; ++j) {
      const auto d = sl::render::equirect::uv_to_direction(j + 0.5, i + 0.5, W, H);
      const double c = d.x * dir.x + d.y * dir.y + d.z * dir.z;
      const float v = c > std::cos(radius_rad) ? sun : sky;
      for (int ch = 0; ch < 3; ++ch) p[(int64_t(ch) * H + i) * W + j] = v;
    }
  return sl::render::EnvironmentMap(t);
}

// Irradiance on an upward surface, ∫ L(ω) max(0, ω·y) dω, by supersampled quadrature of the
// map's own (bilinear) lookup.
double irradiance_up(const sl::render::EnvironmentMap& env) {
  const int W = env.width(), H = env.height(), sub = 4;
  double e = 0.0;
  for (int i = 0; i < H * sub; ++i) {
    const double omega = sl::render::equirect::pixel_solid_angle(i, W * sub, H * sub);
    for (int j = 0; j < W * sub; ++j) {
      const auto d = sl::render::equirect::uv_to_direction(j + 0.5, i + 0.5, W * sub, H * sub);
      if (d.y <= 0) continue;
      e += env.lookup(glm::vec3(d.x, d.y, d.z)).g * d.y * omega;
    }
  }
  return e;
}

sl::render::Material lambert_material(float albedo) {
  sl::render::Material m;
  m.base_color_factor = glm::vec4(albedo, albedo, albedo, 1.0f);
  return m;
}

sl::render::Camera camera_at(const glm::dvec3& pos, double yaw, double pitch, int w, int h, double fov_deg = 40.0) {
  return sl::render::Camera(sl::render::intrinsics_from_fov(fov_deg * sl::kPi / 180.0, w, h),
                            sl::render::rotation_from_yaw_pitch_roll(yaw, pitch, 0.0), pos);
}

float at(const sl::Tensor& t, int c, int row, int col) {
  const auto& s = t.shape();
  return t.data<float>()[(c * s[1] + row) * s[2] + col];
}

// Pixels whose centre ray and all four neighbours hit the mesh: no background in the jitter.
bool interior(const sl::Tensor& mask, int row, int col) {
  const int H = int(mask.shape()[1]), W = int(mask.shape()[2]);
  if (row < 1 || col < 1 || row >= H - 1 || col >= W - 1) return false;
  return at(mask, 0, row, col) > 0 && at(mask, 0, row - 1, col) > 0 && at(mask, 0, row + 1, col) > 0 &&
         at(mask, 0, row, col - 1) > 0 && at(mask, 0, row, col + 1) > 0;
}

bool all_finite(const sl::Tensor& t) {
  const float* p = t.data<float>();
  for (int64_t i = 0; i < t.numel(); ++i)
    if (!std::isfinite(p[i])) return false;
  return true;
}

// (a) A convex Lambertian object never sees itself, so every visible point reflects ρ·L,
// whatever the path depth.
TEST(PathTracer, LambertianSphereUnderConstantSkyReflectsAlbedoTimesSky) {
  const glm::vec3 sky(1.0f, 2.0f, 0.5f);
  const float rho = 0.6f;
  const sl::render::Mesh sphere = sl::render::make_icosphere({0, 0, 0}, 1.0f, 4, lambert_material(rho));
  const sl::render::EnvironmentMap env = constant_env(sky);
  const sl::render::PathTracer tracer(sphere, env);
  sl::render::PathTracerOptions o;
  o.spp = 32;
  o.lambertian = true;
  const sl::render::PathTracerImage img = tracer.render(camera_at({0, 0, 4}, 0, 0, 24, 24), o);
  EXPECT_EQ(img.nonfinite_samples, 0);
  glm::dvec3 mean(0.0);
  int n = 0;
  for (int r = 0; r < 24; ++r)
    for (int c = 0; c < 24; ++c) {
      if (!interior(img.mask, r, c)) continue;
      ++n;
      for (int ch = 0; ch < 3; ++ch) {
        mean[ch] += at(img.radiance, ch, r, c);
        EXPECT_NEAR(at(img.radiance, ch, r, c), rho * sky[ch], 0.12 * rho * sky[ch]) << r << "," << c;
      }
    }
  ASSERT_GT(n, 100);
  for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(mean[ch] / n, rho * sky[ch], 0.01 * rho * sky[ch]) << ch;
  // Background pixels see the sky itself.
  EXPECT_NEAR(at(img.radiance, 1, 0, 0), sky.g, 1e-5);
}

// (b) Cosine law: a small sun of radiance L_s over a Lambertian plane gives ρ/π · E with
// E = ∫ L cos θ dω ≈ L_s·Ω·sin(elevation).
TEST(PathTracer, SunOverLambertianPlaneFollowsTheCosineLaw) {
  const float rho = 0.5f;
  const sl::render::Mesh plane = sl::render::make_ground_plane(200.0f, 0.0f, lambert_material(rho));
  for (double elevation_deg : {70.0, 25.0}) {
    const double el = elevation_deg * sl::kPi / 180.0;
    const glm::vec3 sun_dir(0.0f, float(std::sin(el)), float(-std::cos(el)));
    const float sun = 1000.0f;
    const sl::render::EnvironmentMap env = sun_env(sun_dir, 0.1f, sun);
    // The disk's solid angle from the map itself (texels quantise it), then the cosine law.
    const double omega = env.integral().g / sun;
    const double e = irradiance_up(env);
    EXPECT_NEAR(e, sun * omega * std::sin(el), 0.01 * e) << elevation_deg;
    const sl::render::PathTracer tracer(plane, env);
    sl::render::PathTracerOptions o;
    o.spp = 32;
    o.lambertian = true;
    const sl::render::PathTracerImage img = tracer.render(camera_at({0, 2, 0}, 0.3, -0.8, 16, 16), o);
    double mean = 0.0;
    for (int r = 0; r < 16; ++r)
      for (int c = 0; c < 16; ++c) {
        ASSERT_GT(at(img.mask, 0, r, c), 0.0f);
        mean += at(img.radiance, 1, r, c);
      }
    mean /= 256;
    std::printf("sun at %.0f deg: rendered %.4f, rho/pi*E %.4f\n", elevation_deg, mean, rho / sl::kPi * e);
    EXPECT_NEAR(mean, rho / sl::kPi * e, 0.015 * rho / sl::kPi * e) << elevation_deg;
  }
}

// (c) White furnace: albedo-1 surfaces in a unit environment. L = 1 solves the rendering
// equation for ANY geometry, so the concave contact between a sphere and the ground — where
// paths bounce many times — must render 1 as well (Russian roulette keeps it unbiased).
TEST(PathTracer, WhiteFurnaceRendersOneEverywhereDespiteInterreflection) {
  sl::render::Mesh scene = sl::render::make_icosphere({0, 1, 0}, 1.0f, 3, lambert_material(1.0f));
  scene.append(sl::render::make_ground_plane(6.0f, 0.0f, lambert_material(1.0f)));
  const sl::render::EnvironmentMap env = constant_env(glm::vec3(1.0f));
  const sl::render::PathTracer tracer(scene, env);
  sl::render::PathTracerOptions o;
  o.spp = 32;
  o.max_depth = 256;
  o.lambertian = true;
  const sl::render::PathTracerImage img = tracer.render(camera_at({0, 1.5, 5}, 0, -0.2, 24, 24, 60), o);
  // Per-pixel noise is large where paths bounce many times, so compare 4×4-pixel blocks.
  double mean = 0.0, worst_block = 0.0;
  for (int br = 0; br < 6; ++br)
    for (int bc = 0; bc < 6; ++bc) {
      double block = 0.0;
      for (int r = br * 4; r < br * 4 + 4; ++r)
        for (int c = bc * 4; c < bc * 4 + 4; ++c) block += at(img.radiance, 1, r, c) / 16.0;
      mean += block / 36.0;
      worst_block = std::max(worst_block, std::abs(block - 1.0));
    }
  std::printf("furnace: mean %.4f, largest 4x4-block deviation %.4f\n", mean, worst_block);
  EXPECT_NEAR(mean, 1.0, 0.01);
  EXPECT_LT(worst_block, 0.1);
  EXPECT_EQ(img.nonfinite_samples, 0);
}

sl::render::Mesh disney_scene() {
  sl::render::Material metal;
  metal.base_color_factor = glm::vec4(0.9f, 0.6f, 0.3f, 1.0f);
  metal.metallic = 1.0f;
  metal.roughness = 0.3f;
  sl::render::Material paint;
  paint.base_color_factor = glm::vec4(0.2f, 0.4f, 0.8f, 1.0f);
  paint.metallic = 0.0f;
  paint.roughness = 0.5f;
  paint.clearcoat = 1.0f;
  paint.clearcoat_roughness = 0.1f;
  sl::render::Mesh scene = sl::render::make_icosphere({-0.6f, 0.5f, 0}, 0.5f, 3, metal);
  scene.append(sl::render::make_box({0.1f, 0, -0.4f}, {0.9f, 0.8f, 0.4f}, paint));
  scene.append(sl::render::make_ground_plane(8.0f, 0.0f, lambert_material(0.4f)));
  return scene;
}

// (d) Counter-based randomness: the same bits with one thread or two.
TEST(PathTracer, ImageIsBitwiseIdenticalForOneAndTwoThreads) {
  const sl::render::Mesh scene = disney_scene();
  const sl::render::EnvironmentMap env = sun_env(glm::normalize(glm::vec3(0.3f, 0.6f, -0.5f)), 0.1f, 200.0f, 0.5f);
  const sl::render::PathTracer tracer(scene, env);
  sl::render::PathTracerOptions o;
  o.spp = 4;
  const sl::render::Camera cam = camera_at({0, 1.2, 3}, 0, -0.35, 20, 16);
  const int before = omp_get_max_threads();
  omp_set_num_threads(1);
  const sl::render::PathTracerImage one = tracer.render(cam, o);
  omp_set_num_threads(2);
  const sl::render::PathTracerImage two = tracer.render(cam, o);
  omp_set_num_threads(before);
  for (const auto& [a, b] : {std::pair{one.radiance, two.radiance}, std::pair{one.depth, two.depth},
                             std::pair{one.normal, two.normal}, std::pair{one.mask, two.mask}})
    EXPECT_EQ(0, std::memcmp(a.data<float>(), b.data<float>(), a.numel() * sizeof(float)));
  // A different seed gives a different image.
  o.seed = 1;
  const sl::render::PathTracerImage other = tracer.render(cam, o);
  EXPECT_NE(0, std::memcmp(one.radiance.data<float>(), other.radiance.data<float>(), one.radiance.numel() * 4));
}

// MIS with environment sampling and plain BRDF sampling estimate the same integral.
TEST(PathTracer, BrdfSamplingAloneConvergesToTheSameImageAsMis) {
  const sl::render::Mesh scene = disney_scene();
  // A broad, smooth "sun" so that BRDF sampling alone converges at a test's budget.
  const sl::render::EnvironmentMap env = sun_env(glm::normalize(glm::vec3(0.3f, 0.6f, -0.5f)), 0.6f, 5.0f, 0.5f);
  const sl::render::PathTracer tracer(scene, env);
  const sl::render::Camera cam = camera_at({0, 1.2, 3}, 0, -0.35, 16, 12);
  sl::render::PathTracerOptions o;
  o.spp = 128;
  const sl::render::PathTracerImage mis = tracer.render(cam, o);
  o.environment_sampling = false;
  const sl::render::PathTracerImage brdf = tracer.render(cam, o);
  double a = 0.0, b = 0.0;
  for (int64_t i = 0; i < mis.radiance.numel(); ++i) {
    a += mis.radiance.data<float>()[i];
    b += brdf.radiance.data<float>()[i];
  }
  std::printf("image sum: MIS %.3f, BRDF only %.3f\n", a, b);
  EXPECT_NEAR(a, b, 0.02 * a);
}

// The stratified estimator (default) and the old independent one estimate the same image.
TEST(PathTracer, StratifiedAndIndependentEstimatorsConvergeToTheSameImage) {
  const sl::render::Mesh scene = disney_scene();
  const sl::render::EnvironmentMap env = sun_env(glm::normalize(glm::vec3(0.3f, 0.6f, -0.5f)), 0.1f, 200.0f, 0.5f);
  const sl::render::PathTracer tracer(scene, env);
  const sl::render::Camera cam = camera_at({0, 1.2, 3}, 0, -0.35, 16, 12);
  sl::render::PathTracerOptions o;
  o.spp = 128;
  double sum[2] = {0.0, 0.0};
  for (int k = 0; k < 2; ++k) {
    o.estimator = k == 0 ? sl::render::PathEstimator::Stratified : sl::render::PathEstimator::Independent;
    o.exact_fresnel = k == 0;  // and the Fresnel option changes the image by well under a per cent
    const sl::render::PathTracerImage img = tracer.render(cam, o);
    EXPECT_EQ(img.nonfinite_samples, 0);
    for (int64_t i = 0; i < img.radiance.numel(); ++i) sum[k] += img.radiance.data<float>()[i];
  }
  std::printf("image sum: stratified + exact Fresnel %.3f, independent + Schlick %.3f\n", sum[0], sum[1]);
  EXPECT_NEAR(sum[0], sum[1], 0.02 * sum[1]);
}

// Progressive passes: samples [0, 8) and [8, 16) averaged are the 16-sample render.
TEST(PathTracer, PassesWithSampleOffsetsContinueOneSequence) {
  const sl::render::Mesh scene = disney_scene();
  const sl::render::EnvironmentMap env = sun_env(glm::normalize(glm::vec3(0.3f, 0.6f, -0.5f)), 0.1f, 200.0f, 0.5f);
  const sl::render::PathTracer tracer(scene, env);
  const sl::render::Camera cam = camera_at({0, 1.2, 3}, 0, -0.35, 12, 8);
  sl::render::PathTracerOptions o;
  o.spp = 16;
  const sl::render::PathTracerImage whole = tracer.render(cam, o);
  o.spp = 8;
  const sl::render::PathTracerImage first = tracer.render(cam, o);
  o.sample_offset = 8;
  const sl::render::PathTracerImage second = tracer.render(cam, o);
  for (int64_t i = 0; i < whole.radiance.numel(); ++i) {
    const float w = whole.radiance.data<float>()[i];
    const float avg = 0.5f * (first.radiance.data<float>()[i] + second.radiance.data<float>()[i]);
    EXPECT_NEAR(avg, w, 1e-5f * std::max(1.0f, w)) << i;
  }
  o.sample_offset = -1;
  EXPECT_THROW(tracer.render(cam, o), sl::Error);
}

TEST(PathTracer, AuxiliaryOutputsDescribeThePixelCentreHit) {
  const sl::render::Mesh sphere = sl::render::make_icosphere({0, 0, 0}, 1.0f, 5, lambert_material(0.5f));
  const sl::render::EnvironmentMap env = constant_env(glm::vec3(1.0f));
  const sl::render::PathTracer tracer(sphere, env);
  sl::render::PathTracerOptions o;
  o.spp = 1;
  const sl::render::PathTracerImage img = tracer.render(camera_at({0, 0, 4}, 0, 0, 15, 15), o);
  // The centre pixel looks straight at the sphere's front point (0, 0, 1): depth 3, normal +z.
  EXPECT_NEAR(at(img.depth, 0, 7, 7), 3.0f, 2e-3f);
  EXPECT_NEAR(at(img.normal, 2, 7, 7), 1.0f, 1e-3f);
  EXPECT_EQ(at(img.mask, 0, 0, 0), 0.0f);
  EXPECT_EQ(at(img.depth, 0, 0, 0), 0.0f);
}

// Extreme cases: a sun 10^6 times the sky in one texel, mirror-smooth metal, grazing views,
// an empty mesh, a camera inside a closed box, degenerate triangles.
TEST(PathTracer, ExtremeScenesStayFinite) {
  sl::Tensor t = sl::Tensor::full({3, 32, 64}, 0.01);
  for (int c = 0; c < 3; ++c) t.data<float>()[(c * 32 + 5) * 64 + 20] = 1e4f;
  const sl::render::EnvironmentMap env(t);
  sl::render::Material mirror;
  mirror.metallic = 1.0f;
  mirror.roughness = 0.0f;
  sl::render::Mesh scene = sl::render::make_icosphere({0, 1, 0}, 1.0f, 2, mirror);
  scene.append(sl::render::make_ground_plane(50.0f, 0.0f, mirror));
  sl::render::Mesh degenerate = sl::render::make_ground_plane(1.0f, 0.5f);
  degenerate.positions[2] = degenerate.positions[0];  // a zero-area triangle
  scene.append(degenerate);
  sl::render::PathTracerOptions o;
  o.spp = 4;
  o.max_depth = 16;
  const sl::render::PathTracer tracer(scene, env);
  for (double pitch : {-0.01, -0.5, -1.5}) {
    const sl::render::PathTracerImage img = tracer.render(camera_at({0, 1, 6}, 0, pitch, 12, 8), o);
    EXPECT_TRUE(all_finite(img.radiance) && all_finite(img.depth) && all_finite(img.normal));
    EXPECT_EQ(img.nonfinite_samples, 0);
  }
  const sl::render::Mesh empty;
  const sl::render::PathTracer nothing(empty, env);
  const sl::render::PathTracerImage sky = nothing.render(camera_at({0, 0, 0}, 0, 0, 8, 4), o);
  EXPECT_TRUE(all_finite(sky.radiance));
  const sl::render::Mesh box = sl::render::make_box({-1, -1, -1}, {1, 1, 1});
  const sl::render::PathTracer inside(box, env);
  const sl::render::PathTracerImage dark = inside.render(camera_at({0, 0, 0}, 0, 0, 8, 4), o);
  for (int64_t i = 0; i < dark.radiance.numel(); ++i) EXPECT_EQ(dark.radiance.data<float>()[i], 0.0f);
}

TEST(PathTracer, InvalidOptionsAreRejectedBeforeRendering) {
  const sl::render::Mesh sphere = sl::render::make_icosphere({0, 0, 0}, 1.0f, 1);
  const sl::render::EnvironmentMap env = constant_env(glm::vec3(1.0f));
  const sl::render::PathTracer tracer(sphere, env);
  sl::render::PathTracerOptions o;
  o.spp = 0;
  EXPECT_THROW(tracer.render(camera_at({0, 0, 4}, 0, 0, 4, 4), o), sl::Error);
  o.spp = 1;
  o.max_depth = 0;
  EXPECT_THROW(tracer.render(camera_at({0, 0, 4}, 0, 0, 4, 4), o), sl::Error);
  EXPECT_THROW(sl::render::PathTracer(sphere, sl::render::EnvironmentMap()), sl::Error);
}

TEST(Primitives, MeshesAreClosedOutwardFacingAndValid) {
  const sl::render::Mesh s = sl::render::make_icosphere({1, 2, 3}, 2.0f, 3);
  EXPECT_EQ(s.triangle_count(), 20u * 64u);
  const sl::render::Mesh b = sl::render::make_box({0, 0, 0}, {1, 2, 3});
  const sl::render::Mesh p = sl::render::make_ground_plane(4.0f, 1.0f);
  for (const sl::render::Mesh* m : {&s, &b, &p}) {
    const glm::vec3 c = m->bounds().centre();
    for (const glm::uvec3& t : m->triangles) {
      const glm::vec3 p0 = m->positions[t.x], p1 = m->positions[t.y], p2 = m->positions[t.z];
      const glm::vec3 n = glm::cross(p1 - p0, p2 - p0);
      const glm::vec3 centroid = (p0 + p1 + p2) / 3.0f;
      if (m == &p) {
        EXPECT_GT(n.y, 0.0f);
      } else {
        EXPECT_GT(glm::dot(n, centroid - c), 0.0f);
      }
      EXPECT_GT(glm::dot(n, m->normals[t.x]), 0.0f);
    }
  }
  EXPECT_THROW(sl::render::make_icosphere({0, 0, 0}, -1.0f, 2), sl::Error);
  EXPECT_THROW(sl::render::make_icosphere({0, 0, 0}, 1.0f, 8), sl::Error);
}

}  // namespace

}  // namespace sl::test
