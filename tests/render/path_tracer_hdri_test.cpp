// The reference path tracer under real HDRIs: a diffuse plane against the analytic
// value from the texels, for the stratified and the old independent estimator, and the noise
// of the two estimators at equal samples. Lives with the data tests because it reads the
// shared HDRIs through OpenImageIO.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>

#include "data/image_io.h"
#include "render/camera.h"
#include "render/environment_map.h"
#include "render/equirect.h"
#include "render/path_tracer.h"
#include "render/primitives.h"
#include "util/math.h"

using sl::data::ImageReadOptions;
using sl::data::read_image;
using sl::render::Camera;
using sl::render::EnvironmentMap;
using sl::render::intrinsics_from_fov;
using sl::render::make_ground_plane;
using sl::render::Material;
using sl::render::Mesh;
using sl::render::PathEstimator;
using sl::render::PathTracer;
using sl::render::PathTracerImage;
using sl::render::PathTracerOptions;
using sl::render::rotation_from_yaw_pitch_roll;

namespace sl::test {
namespace {

const std::string kData = STREETLIGHT_SHARED_DATA;

// E = ∫ L(ω) max(0, ω·y) dω over the map's own bilinear lookup, by 2×2-supersampled quadrature
// over the texel grid (green channel).
double irradiance_up(const EnvironmentMap& env) {
  const int W = env.width() * 2, H = env.height() * 2;
  double e = 0.0;
  for (int i = 0; i < H / 2; ++i) {
    const double omega = render::equirect::pixel_solid_angle(i, W, H);
    for (int j = 0; j < W; ++j) {
      const auto d = render::equirect::uv_to_direction(j + 0.5, i + 0.5, W, H);
      e += env.lookup(glm::vec3(d.x, d.y, d.z)).g * d.y * omega;
    }
  }
  return e;
}

Mesh lambert_plane(float albedo) {
  Material m;
  m.base_color_factor = glm::vec4(albedo, albedo, albedo, 1.0f);
  return make_ground_plane(200.0f, 0.0f, m);
}

Camera looking_down() {
  return Camera(intrinsics_from_fov(40.0 * kPi / 180.0, 24, 24), rotation_from_yaw_pitch_roll(0.4, -1.2, 0.0),
                {0.0, 2.0, 0.0});
}

double mean_green(const Tensor& img) {
  const int64_t plane = img.size(1) * img.size(2);
  double s = 0.0;
  for (int64_t i = 0; i < plane; ++i) s += img.data<float>()[plane + i];
  return s / double(plane);
}

// RMS over pixels of the difference of two renders / √2: the per-image pixel noise.
double two_seed_noise(const Tensor& a, const Tensor& b) {
  double s = 0.0;
  for (int64_t i = 0; i < a.numel(); ++i) {
    const double d = double(a.data<float>()[i]) - double(b.data<float>()[i]);
    s += d * d;
  }
  return std::sqrt(s / double(a.numel()) / 2.0);
}

class PlaneUnderHdri : public ::testing::TestWithParam<const char*> {};

// A diffuse plane sees the whole upper hemisphere and nothing else: L = ρ/π · E exactly.
TEST_P(PlaneUnderHdri, DiffusePlaneMatchesTheIrradianceOfTheTexels) {
  const std::string file = kData + "/hdri/" + GetParam();
  if (!std::filesystem::exists(file)) GTEST_SKIP() << "shared HDRI not found: " << file;
  ImageReadOptions ro;
  ro.channels = 3;
  const EnvironmentMap env(read_image(file, ro));
  const float rho = 0.5f;
  const double expected = rho / kPi * irradiance_up(env);
  const Mesh plane = lambert_plane(rho);
  const PathTracer tracer(plane, env);
  PathTracerOptions o;
  o.spp = 256;
  o.lambertian = true;
  for (PathEstimator est : {PathEstimator::Stratified, PathEstimator::Independent}) {
    o.estimator = est;
    const PathTracerImage img = tracer.render(looking_down(), o);
    ASSERT_EQ(img.nonfinite_samples, 0);
    const double mean = mean_green(img.radiance);
    std::printf("%s %s: plane %.5f, rho/pi*E %.5f (%+.3f%%)\n", GetParam(),
                est == PathEstimator::Stratified ? "stratified" : "independent", mean, expected,
                100.0 * (mean / expected - 1.0));
    EXPECT_NEAR(mean, expected, 0.006 * expected);  // about 4 standard errors at 256 spp
  }
}

// At equal samples the stratified estimator is less noisy than the old one on the same plane.
TEST_P(PlaneUnderHdri, StratifiedEstimatorIsLessNoisyThanIndependent) {
  const std::string file = kData + "/hdri/" + GetParam();
  if (!std::filesystem::exists(file)) GTEST_SKIP() << "shared HDRI not found: " << file;
  ImageReadOptions ro;
  ro.channels = 3;
  const EnvironmentMap env(read_image(file, ro));
  const Mesh plane = lambert_plane(0.5f);
  const PathTracer tracer(plane, env);
  PathTracerOptions o;
  o.spp = 16;
  o.lambertian = true;
  double noise[2];
  for (int k = 0; k < 2; ++k) {
    o.estimator = k == 0 ? PathEstimator::Stratified : PathEstimator::Independent;
    o.seed = 1;
    const Tensor a = tracer.render(looking_down(), o).radiance;
    o.seed = 2;
    const Tensor b = tracer.render(looking_down(), o).radiance;
    noise[k] = two_seed_noise(a, b);
  }
  std::printf("%s at 16 spp: noise stratified %.5f, independent %.5f (ratio %.3f)\n", GetParam(), noise[0],
              noise[1], noise[0] / noise[1]);
  EXPECT_LT(noise[0], 0.8 * noise[1]);
}

INSTANTIATE_TEST_SUITE_P(HardSunAndSoftSky, PlaneUnderHdri,
                         ::testing::Values("chinese_garden_1k.hdr", "potsdamer_platz_1k.hdr"));

}  // namespace
}  // namespace sl::test
