// data/sun_from_shadows.h on analytic scenes: a camera 1.6 m above the ground, boxes standing on
// it, and a photo whose ground is dark exactly where a box blocks the true sun (a slab test, not
// the fit's own depth-map march), so the fit must find the sun from the picture.
#include "data/sun_from_shadows.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "util/error.h"
#include "util/math.h"

namespace sl::data {
namespace {

struct Box {
  glm::dvec3 lo, hi;
};

// Ray–box slab test: the entry distance, or +inf.
double hit_box(const glm::dvec3& o, const glm::dvec3& d, const Box& b) {
  double t0 = 1e-9, t1 = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    if (std::abs(d[a]) < 1e-15) {
      if (o[a] < b.lo[a] || o[a] > b.hi[a]) return std::numeric_limits<double>::infinity();
      continue;
    }
    double ta = (b.lo[a] - o[a]) / d[a], tb = (b.hi[a] - o[a]) / d[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta), t1 = std::min(t1, tb);
  }
  return t0 <= t1 ? t0 : std::numeric_limits<double>::infinity();
}

glm::dvec3 sun_dir(double az_deg, double el_deg) {
  const double a = az_deg * kPi / 180.0, e = el_deg * kPi / 180.0;
  return {std::cos(e) * std::sin(a), std::sin(e), -std::cos(e) * std::cos(a)};
}

double angle_deg(const glm::dvec3& a, const glm::dvec3& b) {
  return std::acos(std::clamp(glm::dot(glm::normalize(a), glm::normalize(b)), -1.0, 1.0)) * 180.0 / kPi;
}

struct Scene {
  Tensor ldr, depth;
  render::Camera camera;
};

// 320×160 view looking down −Z; ground y = 0; lit ground LDR 0.8, shadowed 0.3, boxes 0.5, sky 1.
Scene make_scene(const std::vector<Box>& boxes, const glm::dvec3& sun) {
  const int W = 320, H = 160;
  const render::Intrinsics k = render::intrinsics_from_fov(90.0 * kPi / 180.0, W, H);
  Scene s;
  s.camera = render::Camera(k, render::rotation_from_yaw_pitch_roll(0.0, -8.0 * kPi / 180.0, 0.0), {0.0, 1.6, 0.0});
  s.ldr = Tensor::zeros({3, H, W});
  s.depth = Tensor::zeros({H, W});
  float* img = s.ldr.data<float>();
  float* dep = s.depth.data<float>();
  for (int row = 0; row < H; ++row)
    for (int col = 0; col < W; ++col) {
      const render::CameraRay ray = s.camera.pixel_ray(col, row);
      double t = ray.direction.y < 0 ? -ray.origin.y / ray.direction.y : std::numeric_limits<double>::infinity();
      bool box = false;
      for (const Box& b : boxes) {
        const double tb = hit_box(ray.origin, ray.direction, b);
        if (tb < t) t = tb, box = true;
      }
      float v = 1.0f;
      const size_t i = static_cast<size_t>(row) * W + col;
      if (std::isfinite(t) && t < 200.0) {
        const glm::dvec3 p = ray.origin + t * ray.direction;
        dep[i] = static_cast<float>(s.camera.world_to_camera(p).z);
        if (box) {
          v = 0.5f;
        } else {
          bool shadow = false;
          for (const Box& b : boxes) shadow |= std::isfinite(hit_box(p + 1e-6 * sun, sun, b));
          v = shadow ? 0.3f : 0.8f;
        }
      }
      for (int c = 0; c < 3; ++c) img[static_cast<size_t>(c) * H * W + i] = v;
    }
  return s;
}

const std::vector<Box> kCars = {{{-3.5, 0.0, -12.0}, {-1.7, 1.5, -7.5}},
                                {{1.5, 0.0, -18.0}, {3.3, 1.5, -13.5}},
                                {{-2.0, 0.0, -26.0}, {-0.2, 1.5, -21.5}}};

TEST(SunFromShadows, FindsTheSunThatCastTheShadows) {
  // Suns in front of the camera: their shadows fall toward it, where it sees them. Known limit,
  // measured: a high sun beside or behind the camera casts shadows mostly hidden behind their
  // casters, and the fit is then far off (a sun at 100°/55° comes out at 48°/67°, 27° away).
  for (const auto& [az, el] : std::vector<std::pair<double, double>>{{60.0, 40.0}, {-45.0, 30.0}, {-20.0, 25.0}}) {
    const glm::dvec3 sun = sun_dir(az, el);
    const Scene s = make_scene(kCars, sun);
    const ShadowSunFit fit = fit_sun_from_shadows(s.ldr, s.depth, s.camera);
    EXPECT_TRUE(fit.found) << "sun " << az << "/" << el << ", score " << fit.score;
    EXPECT_LT(angle_deg(fit.direction, sun), 15.0)
        << "sun " << az << "/" << el << " fitted " << fit.azimuth_deg << "/" << fit.elevation_deg;
    EXPECT_NEAR(glm::length(fit.direction), 1.0, 1e-12);
    // The shadowed ground is 0.3 against 0.8 in LDR: (0.3/0.8)^2.2 in linear luminance.
    EXPECT_NEAR(fit.shadow_ratio, std::pow(0.3 / 0.8, 2.2), 0.02);
  }
}

TEST(SunFromShadows, FindsNothingWithoutGeometryThatCastsAShadow) {
  // The ground plane alone (the depth a photo gets without lidar or a depth file), with a
  // photo that has dark patches: nothing in the depth can explain them, so no sun is claimed.
  Scene s = make_scene({}, sun_dir(30.0, 45.0));
  float* img = s.ldr.data<float>();
  const int64_t H = s.ldr.size(1), W = s.ldr.size(2);
  for (int64_t row = H / 2; row < H; ++row)
    for (int64_t col = 0; col < W / 3; ++col)
      for (int c = 0; c < 3; ++c) img[c * H * W + row * W + col] = 0.3f;
  const ShadowSunFit fit = fit_sun_from_shadows(s.ldr, s.depth, s.camera);
  EXPECT_FALSE(fit.found);
  EXPECT_GT(fit.ground_samples, 100);
}

TEST(SunFromShadows, MaskMarksTheBlockedGroundOfOneDirection) {
  const glm::dvec3 sun = sun_dir(60.0, 40.0);
  const Scene s = make_scene(kCars, sun);
  ShadowSunOptions every_pixel;
  every_pixel.stride_px = 1;  // one sample per pixel, so the mask has no cell edges
  const Tensor mask = shadow_sun_mask(s.ldr, s.depth, s.camera, sun, every_pixel);
  ASSERT_EQ(mask.shape(), (Shape{1, 160, 320}));
  // Where the mask says blocked, the analytic photo is mostly the shadow's 0.3 (the depth map
  // sees only the casters' front faces, so the edges differ), and far more often than under the
  // sun mirrored to the other side of the camera.
  const auto agreement = [&](const Tensor& mk, int* count) {
    const float* m = mk.data<float>();
    const float* img = s.ldr.data<float>();
    int blocked = 0, agree = 0;
    for (int64_t i = 0; i < mk.numel(); ++i)
      if (m[i] == 1.0f) ++blocked, agree += img[i] == 0.3f;
    *count = blocked;
    return blocked ? double(agree) / blocked : 0.0;
  };
  int n_true = 0, n_mirror = 0;
  const double a_true = agreement(mask, &n_true);
  const double a_mirror = agreement(shadow_sun_mask(s.ldr, s.depth, s.camera, sun_dir(-60.0, 40.0), every_pixel), &n_mirror);
  ASSERT_GT(n_true, 200);
  EXPECT_GT(a_true, 0.65);
  EXPECT_LT(a_mirror, 0.5 * a_true) << n_mirror << " blocked under the mirrored sun";
}

TEST(SunFromShadows, IsDeterministicAndSkipsNonFinitePixels) {
  Scene s = make_scene(kCars, sun_dir(60.0, 40.0));
  const ShadowSunFit a = fit_sun_from_shadows(s.ldr, s.depth, s.camera);
  // Depth holes of every kind and a NaN pixel change nothing the fit can see as a number.
  float* dep = s.depth.data<float>();
  dep[0] = std::numeric_limits<float>::quiet_NaN();
  dep[1] = std::numeric_limits<float>::infinity();
  dep[2] = -1.0f;
  s.ldr.data<float>()[100 * 320 + 5] = std::numeric_limits<float>::quiet_NaN();
  const ShadowSunFit b = fit_sun_from_shadows(s.ldr, s.depth, s.camera);
  EXPECT_TRUE(std::isfinite(b.score) && std::isfinite(b.shadow_ratio));
  EXPECT_TRUE(std::isfinite(b.direction.x) && std::isfinite(b.direction.y) && std::isfinite(b.direction.z));
  EXPECT_NEAR(angle_deg(a.direction, b.direction), 0.0, 2.5);
  const ShadowSunFit c = fit_sun_from_shadows(s.ldr, s.depth, s.camera);
  EXPECT_EQ(b.azimuth_deg, c.azimuth_deg);
  EXPECT_EQ(b.elevation_deg, c.elevation_deg);
  EXPECT_EQ(b.score, c.score);
}

TEST(SunFromShadows, RejectsMismatchedInputsByName) {
  const Scene s = make_scene(kCars, sun_dir(60.0, 40.0));
  EXPECT_THROW(fit_sun_from_shadows(Tensor::zeros({1, 160, 320}), s.depth, s.camera), Error);
  EXPECT_THROW(fit_sun_from_shadows(s.ldr, Tensor::zeros({80, 320}), s.camera), Error);
  ShadowSunOptions bad;
  bad.march_steps = 1;
  try {
    fit_sun_from_shadows(s.ldr, s.depth, s.camera, bad);
    ADD_FAILURE() << "no throw";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("march"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace sl::data
