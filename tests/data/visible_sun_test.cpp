#include "data/visible_sun.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <string>

#include "data/image_io.h"
#include "data/panorama.h"
#include "data/sun_extraction.h"
#include "render/camera.h"
#include "render/exposure.h"
#include "support/test_files.h"
#include "util/error.h"
#include "util/math.h"

namespace sl::test {

namespace {

constexpr int kW = 256, kH = 128;

double angle_deg(const glm::dvec3& a, const glm::dvec3& b) {
  return degrees(std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b)));
}

// A street photo's LDR: a blue sky above row horizon_row (brighter towards the top), a grey
// ground below.
Tensor street_ldr(int horizon_row = 80) {
  Tensor t = Tensor::zeros({3, kH, kW});
  float* p = t.data<float>();
  const int64_t plane = static_cast<int64_t>(kH) * kW;
  for (int r = 0; r < kH; ++r)
    for (int c = 0; c < kW; ++c) {
      const bool sky = r < horizon_row;
      const float t_up = sky ? 1.0f - static_cast<float>(r) / horizon_row : 0.0f;
      const float rgb[3] = {sky ? 0.45f + 0.1f * t_up : 0.35f, sky ? 0.6f + 0.1f * t_up : 0.35f, sky ? 0.85f : 0.33f};
      for (int ch = 0; ch < 3; ++ch) p[ch * plane + static_cast<int64_t>(r) * kW + c] = rgb[ch];
    }
  return t;
}

// A clipped disk of radius_px at continuous (u, v), its glare blending to white over glow_px
// outward (1 − exp(−(d − radius)/glow)), as a lens sees the sun.
void paint_sun(Tensor& ldr, double u, double v, double radius_px, double glow_px) {
  float* p = ldr.data<float>();
  const int h = static_cast<int>(ldr.size(1)), w = static_cast<int>(ldr.size(2));
  const int64_t plane = static_cast<int64_t>(h) * w;
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) {
      const double d = std::hypot(c + 0.5 - u, r + 0.5 - v);
      const double white = d <= radius_px ? 1.0 : std::exp(-(d - radius_px) / glow_px);
      for (int ch = 0; ch < 3; ++ch) {
        float& x = p[ch * plane + static_cast<int64_t>(r) * w + c];
        x = static_cast<float>(white + (1.0 - white) * x);
      }
    }
}

void paint_rect(Tensor& ldr, int c0, int r0, int c1, int r1, float value) {
  float* p = ldr.data<float>();
  const int64_t plane = static_cast<int64_t>(ldr.size(1)) * ldr.size(2);
  for (int r = r0; r < r1; ++r)
    for (int c = c0; c < c1; ++c)
      for (int ch = 0; ch < 3; ++ch) p[ch * plane + static_cast<int64_t>(r) * ldr.size(2) + c] = value;
}

void expect_not_found(const data::VisibleSun& s) {
  EXPECT_FALSE(s.found);
  EXPECT_EQ(s.score, 0.0);
  EXPECT_EQ(s.pixel, glm::dvec2(0.0));
  EXPECT_EQ(s.direction, glm::dvec3(0.0, 1.0, 0.0));
  for (double x : {s.compactness, s.border_fraction, s.halo, s.falloff, s.elevation_deg}) EXPECT_TRUE(std::isfinite(x));
}

}  // namespace

TEST(VisibleSun, GlowingClippedDiskIsFoundAtItsCentre) {
  for (const glm::dvec2 centre : {glm::dvec2(150.3, 40.7), glm::dvec2(61.5, 20.25), glm::dvec2(200.8, 55.6)}) {
    Tensor ldr = street_ldr();
    paint_sun(ldr, centre.x, centre.y, 5.0, 6.0);
    const data::VisibleSun s = data::find_visible_sun(ldr);
    ASSERT_TRUE(s.found) << centre.x << "," << centre.y;
    // The centroid of the pixel centres of a disk of radius 5 px (≈ 80 pixels) lies within a
    // quarter pixel of its centre; the glare reaches white only inside the disk.
    EXPECT_NEAR(s.pixel.x, centre.x, 0.25);
    EXPECT_NEAR(s.pixel.y, centre.y, 0.25);
    EXPECT_GT(s.score, 0.0);
    EXPECT_EQ(s.candidate_count, 1);
  }
}

TEST(VisibleSun, DirectionThroughACameraMatchesTheTrueSun) {
  const render::Intrinsics k = render::intrinsics_from_fov(radians(70.0), kW, kH);
  const render::Camera cam(k, render::rotation_from_yaw_pitch_roll(radians(35.0), radians(12.0), radians(-3.0)),
                           {1.0, 1.6, -2.0});
  for (const auto& [az, el] : {std::pair{50.0, 25.0}, std::pair{20.0, 15.0}, std::pair{38.0, 28.0}}) {
    const glm::dvec3 sun(std::cos(radians(el)) * std::sin(radians(az)), std::sin(radians(el)),
                         -std::cos(radians(el)) * std::cos(radians(az)));
    const render::Projection p = cam.project(cam.position() + 1e3 * sun);
    ASSERT_TRUE(p.in_image);
    Tensor ldr = street_ldr(120);
    paint_sun(ldr, p.pixel.x, p.pixel.y, 5.0, 5.0);
    const data::VisibleSun s = data::find_visible_sun(ldr, cam);
    ASSERT_TRUE(s.found) << az << "," << el;
    // Tolerance: the quarter pixel of the centroid above, and a pixel subtends at most
    // 1/fx radians (at the principal point), so 0.25/fx rad; the position's parallax at 1 km is
    // below 1e-5 rad.
    EXPECT_LT(angle_deg(s.direction, sun), degrees(0.25 / k.fx) + 1e-3) << az << "," << el;
    EXPECT_NEAR(s.elevation_deg, degrees(std::asin(s.direction.y)), 1e-9);
  }
}

TEST(VisibleSun, OvercastSkyIsNotASun) {
  Tensor all_white = Tensor::ones({3, kH, kW});
  expect_not_found(data::find_visible_sun(all_white));
  // A blown-out overcast sky above a grey street: one clipped band across the whole image.
  Tensor band = street_ldr();
  paint_rect(band, 0, 0, kW, 80, 0.99f);
  const data::VisibleSun s = data::find_visible_sun(band);
  expect_not_found(s);
  EXPECT_EQ(s.candidate_count, 1);
}

TEST(VisibleSun, ClippedWallWithoutGlowIsNotASun) {
  // A white facade in the sun: compact and clipped, but its edge is sharp (no halo falling off).
  Tensor ldr = street_ldr();
  paint_rect(ldr, 104, 20, 116, 32, 1.0f);
  const data::VisibleSun s = data::find_visible_sun(ldr);
  expect_not_found(s);
  EXPECT_EQ(s.candidate_count, 1);
  EXPECT_GT(s.compactness, data::VisibleSunParams().min_compactness);  // as compact as a sun
  EXPECT_LT(s.falloff, data::VisibleSunParams().min_falloff);
  // A glowing disk low in the image (a car's chrome reflecting the sun, a street lamp): rejected
  // for its place alone.
  Tensor low = street_ldr();
  paint_sun(low, 128.0, 110.0, 5.0, 6.0);
  expect_not_found(data::find_visible_sun(low));
}

TEST(VisibleSun, EmptyBlackAndNonFiniteImagesFindNothing) {
  expect_not_found(data::find_visible_sun(Tensor::zeros({3, 0, 0})));
  expect_not_found(data::find_visible_sun(Tensor::zeros({3, kH, kW})));
  Tensor nan = Tensor::full({3, kH, kW}, std::numeric_limits<float>::quiet_NaN());
  expect_not_found(data::find_visible_sun(nan));
  Tensor inf = Tensor::full({3, kH, kW}, std::numeric_limits<float>::infinity());
  expect_not_found(data::find_visible_sun(inf));
  // NaN texels beside a real sun neither hide it nor leak into the result.
  Tensor ldr = street_ldr();
  paint_sun(ldr, 90.0, 30.0, 5.0, 6.0);
  float* p = ldr.data<float>();
  for (int64_t i = 0; i < ldr.numel(); i += 97) p[i] = std::numeric_limits<float>::quiet_NaN();
  const data::VisibleSun s = data::find_visible_sun(ldr);
  EXPECT_TRUE(s.found);
  EXPECT_NEAR(s.pixel.x, 90.0, 0.5);
  EXPECT_NEAR(s.pixel.y, 30.0, 0.5);
  EXPECT_TRUE(std::isfinite(s.score) && std::isfinite(s.halo) && std::isfinite(s.falloff));
}

TEST(VisibleSun, BadInputIsRejectedNamingIt) {
  EXPECT_THROW(data::find_visible_sun(Tensor::zeros({1, kH, kW})), Error);
  EXPECT_THROW(data::find_visible_sun(Tensor()), Error);
  const render::Camera cam(render::intrinsics_from_fov(1.0, 64, 32), glm::dmat3(1.0), glm::dvec3(0.0));
  EXPECT_THROW(data::find_visible_sun(Tensor::zeros({3, kH, kW}), cam), Error);
  data::VisibleSunParams bad;
  bad.saturation = 1.5;
  EXPECT_THROW(data::find_visible_sun(Tensor::zeros({3, kH, kW}), bad), Error);
  bad = {};
  bad.max_area_fraction = 0.0;
  EXPECT_THROW(data::find_visible_sun(Tensor::zeros({3, kH, kW}), bad), Error);
}

TEST(VisibleSun, RealHdrCropShowsTheExtractedSun) {
  const std::string path = shared_data("hdri/wide_street_01_1k.exr");
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "shared data absent: " << path;
  const Tensor pano = data::read_image(path, {.channels = 3});
  const data::SunEstimate sun = data::extract_sun(pano);
  ASSERT_TRUE(sun.found);
  // A 70° crop with the sun up and to the right of its centre, exposed as the benchmark's crops
  // (median luminance → LDR 0.4, data/panorama_sample.h).
  data::PerspectiveCropParams cp;
  cp.horizontal_fov_rad = radians(70.0);
  cp.yaw_rad = sun.azimuth_rad - radians(12.0);
  cp.pitch_rad = std::max(0.0, sun.elevation_rad - radians(8.0));
  const data::PerspectiveCrop crop = data::crop_perspective(pano, cp);
  const Tensor ldr = data::to_ldr(crop.image, render::exposure_for_ldr_median(crop.image, 0.4));
  const data::VisibleSun s = data::find_visible_sun(ldr, crop.camera);
  ASSERT_TRUE(s.found) << "halo " << s.halo << " falloff " << s.falloff << " area " << s.area_px;
  EXPECT_LT(angle_deg(s.direction, sun.direction), 3.0);
}

}  // namespace sl::test
