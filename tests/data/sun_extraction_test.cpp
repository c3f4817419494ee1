#include "data/sun_extraction.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

#include "data/image_io.h"
#include "render/equirect.h"
#include "support/test_files.h"
#include "util/math.h"
#include "util/random.h"

namespace sl::test {

namespace {

glm::dvec3 from_angles(double elevation_deg, double azimuth_deg) {
  const double e = elevation_deg * sl::kDegToRad, a = azimuth_deg * sl::kDegToRad;
  return {std::cos(e) * std::sin(a), std::sin(e), -std::cos(e) * std::cos(a)};
}

double angle_deg(const glm::dvec3& a, const glm::dvec3& b) {
  return std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b)) / sl::kDegToRad;
}

// A blue-ish sky gradient with a disk sun of the given angular radius (4×4 supersampled) and
// multiplicative plus additive noise.
sl::Tensor synthetic_sky(int h, const glm::dvec3& sun, double radius_deg, double sun_radiance,
                         double noise, uint64_t seed) {
  const int w = 2 * h;
  sl::Tensor t = sl::Tensor::empty({3, h, w});
  float* p = t.data<float>();
  const double cos_r = std::cos(radius_deg * sl::kDegToRad);
  for (int i = 0; i < h; ++i)
    for (int j = 0; j < w; ++j) {
      double covered = 0.0;
      for (int s = 0; s < 16; ++s) {
        const auto d = sl::render::equirect::uv_to_direction(j + (s % 4 + 0.5) / 4, i + (s / 4 + 0.5) / 4, w, h);
        covered += (d.x * sun.x + d.y * sun.y + d.z * sun.z) >= cos_r ? 1.0 / 16 : 0.0;
      }
      const auto d = sl::render::equirect::uv_to_direction(j + 0.5, i + 0.5, w, h);
      const double sky = d.y > 0 ? 1.0 + 0.5 * d.y : 0.3;
      const int64_t idx = static_cast<int64_t>(i) * w + j;
      const double n1 = 1.0 + noise * sl::normal01(seed, idx), n2 = noise * sl::normal01(seed + 1, idx);
      const double base = sun_radiance * covered;
      p[idx] = static_cast<float>(std::max(0.0, (0.6 * sky + base) * n1 + n2));
      p[h * w + idx] = static_cast<float>(std::max(0.0, (0.8 * sky + base) * n1 + n2));
      p[2 * h * w + idx] = static_cast<float>(std::max(0.0, (1.2 * sky + base) * n1 + n2));
    }
  return t;
}

}  // namespace

TEST(SunExtraction, FindsSyntheticSunsWithinOneDegreeUnderNoise) {
  const double cases[][2] = {{0.0, 30.0}, {89.0, -120.0}, {45.0, 180.0}, {30.0, -179.9},
                             {10.0, 179.5}, {60.0, 0.0}};
  uint64_t seed = 100;
  for (const auto& c : cases)
    for (double radius_deg : {0.3, 2.0}) {
      const glm::dvec3 sun = from_angles(c[0], c[1]);
      const sl::Tensor pano = synthetic_sky(128, sun, radius_deg, 5e4, 0.1, seed++);
      const sl::data::SunEstimate est = sl::data::extract_sun(pano);
      ASSERT_TRUE(est.found);
      EXPECT_NEAR(glm::length(est.direction), 1.0, 1e-12);
      EXPECT_LT(angle_deg(est.direction, sun), 1.0)
          << "elevation " << c[0] << " azimuth " << c[1] << " radius " << radius_deg;
      EXPECT_GT(est.radiance_rgb.x, 100.0);
    }
}

TEST(SunExtraction, HandlesTheAzimuthSeamAndTheZenith) {
  // A disk centred exactly on the seam is split between the first and last columns; a disk at
  // the zenith covers every column of the top rows. Pixel-coordinate averages fail both.
  for (const glm::dvec3& sun : {from_angles(20.0, 180.0), from_angles(90.0, 0.0), from_angles(88.0, 180.0)}) {
    const sl::Tensor pano = synthetic_sky(64, sun, 3.0, 1e4, 0.0, 7);
    const sl::data::SunEstimate est = sl::data::extract_sun(pano);
    EXPECT_LT(angle_deg(est.direction, sun), 0.5) << sun.x << " " << sun.y << " " << sun.z;
  }
}

TEST(SunExtraction, PowerOfASunIsIndependentOfResolution) {
  const glm::dvec3 sun = from_angles(35.0, 60.0);
  const double radius_deg = 1.5, radiance = 1e5;
  const double exact = radiance * 2 * sl::kPi * (1 - std::cos(radius_deg * sl::kDegToRad));
  for (int h : {64, 128}) {
    const sl::data::SunEstimate est =
        sl::data::extract_sun(synthetic_sky(h, sun, radius_deg, radiance, 0.0, 3), {.threshold_fraction = 0.01});
    EXPECT_NEAR(est.power_rgb.y, exact, 0.05 * exact) << h;
  }
}

TEST(SunExtraction, ASingleHotNoiseTexelDoesNotBeatAWideSun) {
  const glm::dvec3 sun = from_angles(40.0, -30.0);
  sl::Tensor pano = synthetic_sky(64, sun, 2.5, 1e3, 0.05, 9);
  for (int c = 0; c < 3; ++c) pano.data<float>()[(c * 64 + 50) * 128 + 5] = 3e3f;  // a firefly
  EXPECT_LT(angle_deg(sl::data::extract_sun(pano).direction, sun), 1.0);
}

TEST(SunExtraction, DegenerateInputsAreHandled) {
  const sl::data::SunEstimate dark = sl::data::extract_sun(sl::Tensor::zeros({3, 8, 16}));
  EXPECT_FALSE(dark.found);
  sl::Tensor bad = sl::Tensor::full({3, 8, 16}, NAN);
  bad.data<float>()[3 * 16 + 4] = 1.0f;
  bad.data<float>()[128 + 3 * 16 + 4] = 1.0f;
  bad.data<float>()[256 + 3 * 16 + 4] = 1.0f;
  const sl::data::SunEstimate one = sl::data::extract_sun(bad);
  EXPECT_TRUE(one.found);
  EXPECT_TRUE(std::isfinite(one.direction.x));
  EXPECT_LT(angle_deg(one.direction,
                      [] {
                        const auto d = sl::render::equirect::uv_to_direction(4.5, 3.5, 16, 8);
                        return glm::dvec3(d.x, d.y, d.z);
                      }()),
            1e-9);
  EXPECT_THROW(sl::data::extract_sun(sl::Tensor::zeros({1, 8, 16})), sl::Error);
  EXPECT_THROW(sl::data::extract_sun(sl::Tensor::zeros({3, 8, 16}), {.threshold_fraction = 1.5}), sl::Error);
}

TEST(SunExtraction, MatchesMeasuredPeakElevationOfRealHdris) {
  const std::string dir = sl::test::shared_data("hdri");
  if (!std::filesystem::exists(dir)) GTEST_SKIP() << "shared data absent: " << dir;
  struct Row {
    const char* file;
    double peak_elevation_deg;
    bool hard_sun;
  };
  // From ../shared/data/MANIFEST.md (elevation of the brightest texel; "hard sun" files).
  const Row rows[] = {
      {"adams_place_bridge_1k.hdr", 89.8, false}, {"aristea_wreck_puresky_1k.hdr", 47.3, false},
      {"chinese_garden_1k.hdr", 30.4, true},      {"hilly_terrain_01_1k.hdr", 11.4, true},
      {"kloppenheim_05_1k.hdr", 74.7, true},      {"modern_buildings_2_1k.hdr", 33.9, true},
      {"narrow_moonlit_road_1k.hdr", 67.7, true}, {"noon_grass_1k.hdr", 85.6, true},
      {"peppermint_powerplant_1k.hdr", 22.7, false}, {"phalzer_forest_01_1k.hdr", 30.8, false},
      {"rainforest_trail_1k.hdr", 38.1, false},   {"st_peters_square_night_1k.hdr", 30.8, false},
      {"dikhololo_night_1k.hdr", 0.9, false},     {"forest_slope_1k.hdr", 39.9, false},
      {"immenstadter_horn_1k.hdr", 35.3, false},  {"kiara_1_dawn_1k.hdr", 3.7, false},
      {"potsdamer_platz_1k.hdr", 20.6, false},    {"rooitou_park_1k.hdr", 10.4, true},
      {"venice_sunset_1k.hdr", 3.3, false},
  };
  std::printf("%-32s %9s %9s %7s %12s %6s\n", "file", "manifest", "extracted", "error", "radiance_Y", "texels");
  for (const Row& r : rows) {
    const std::string path = dir + "/" + r.file;
    const sl::data::SunEstimate est = sl::data::extract_sun(sl::data::read_image(path, {.channels = 3}));
    const double elevation = est.elevation_rad / sl::kDegToRad, error = std::fabs(elevation - r.peak_elevation_deg);
    std::printf("%-32s %9.1f %9.2f %7.2f %12.1f %6d\n", r.file, r.peak_elevation_deg, elevation, error,
                est.radiance_rgb.y, est.texel_count);
    if (r.hard_sun) {
      EXPECT_LT(error, 1.0) << r.file;
    }
  }
}

}  // namespace sl::test
