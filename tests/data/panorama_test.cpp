#include "data/panorama.h"

#include <gtest/gtest.h>

#include <cmath>

#include "render/equirect.h"
#include "util/math.h"
#include "util/random.h"

namespace sl::test {

namespace {

glm::dvec3 from_angles(double elevation_rad, double azimuth_rad) {
  return {std::cos(elevation_rad) * std::sin(azimuth_rad), std::sin(elevation_rad),
          -std::cos(elevation_rad) * std::cos(azimuth_rad)};
}

// Fills channel c of texel (i, j) with f(direction of its centre)[c].
template <class F>
sl::Tensor pano_from(int c, int h, int w, F f) {
  sl::Tensor t = sl::Tensor::empty({c, h, w});
  float* p = t.data<float>();
  for (int i = 0; i < h; ++i)
    for (int j = 0; j < w; ++j) {
      const auto d = sl::render::equirect::uv_to_direction(j + 0.5, i + 0.5, w, h);
      const glm::dvec3 v = f(glm::dvec3(d.x, d.y, d.z));
      for (int k = 0; k < c; ++k) p[(k * h + i) * w + j] = static_cast<float>(v[k]);
    }
  return t;
}

// Luminance-weighted mean direction of channel 0 (for blob tracking).
glm::dvec3 centroid(const sl::Tensor& pano) {
  const int h = static_cast<int>(pano.size(1)), w = static_cast<int>(pano.size(2));
  glm::dvec3 acc(0.0);
  for (int i = 0; i < h; ++i)
    for (int j = 0; j < w; ++j) {
      const auto d = sl::render::equirect::uv_to_direction(j + 0.5, i + 0.5, w, h);
      acc += static_cast<double>(pano.data<float>()[i * w + j]) * sl::render::equirect::pixel_solid_angle(i, w, h) *
             glm::dvec3(d.x, d.y, d.z);
    }
  return glm::normalize(acc);
}

double angle_deg(const glm::dvec3& a, const glm::dvec3& b) {
  return std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b)) / sl::kDegToRad;
}

}  // namespace

TEST(Panorama, WholePixelAzimuthRotationIsAnExactColumnRoll) {
  const sl::Tensor pano = sl::Tensor::uniform({3, 8, 16}, 0.0, 1.0, 11);
  const sl::Tensor r = sl::data::rotate_azimuth(pano, -3 * 2 * sl::kPi / 16);
  for (int c = 0; c < 3; ++c)
    for (int i = 0; i < 8; ++i)
      for (int j = 0; j < 16; ++j) EXPECT_EQ(r.at({c, i, j}), pano.at({c, i, (j + 3) % 16}));
  const sl::Tensor full = sl::data::rotate_azimuth(pano, 2 * sl::kPi);
  EXPECT_EQ(full.to_vector(), pano.to_vector());
}

TEST(Panorama, AzimuthRotationMovesContentLikeTheDirectionRotation) {
  const glm::dvec3 blob = from_angles(20 * sl::kDegToRad, 170 * sl::kDegToRad);
  const sl::Tensor pano = pano_from(1, 64, 128, [&](const glm::dvec3& d) {
    return glm::dvec3(std::exp(-std::pow(sl::kPi / 180 * angle_deg(d, blob) / 0.1, 2)));
  });
  for (double delta : {37.3 * sl::kDegToRad, -95.0 * sl::kDegToRad, 2.8125 * sl::kDegToRad}) {
    const sl::Tensor r = sl::data::rotate_azimuth(pano, delta);
    EXPECT_LT(angle_deg(centroid(r), sl::data::rotate_direction_azimuth(blob, delta)), 0.3) << delta;
    // Linear interpolation along rows keeps each row's sum.
    EXPECT_NEAR(sl::data::radiant_power(r, 0), sl::data::radiant_power(pano, 0),
                1e-5 * sl::data::radiant_power(pano, 0));
  }
}

TEST(Panorama, AreaResizePreservesSolidAngleWeightedEnergyOfAOneTexelSun) {
  sl::Tensor pano = sl::Tensor::uniform({3, 64, 128}, 0.5, 1.5, 12);
  for (int c = 0; c < 3; ++c) pano.data<float>()[(c * 64 + 9) * 128 + 77] = 1e6f;  // the sun
  for (auto [h, w] : {std::pair{16, 32}, std::pair{24, 48}, std::pair{7, 13}, std::pair{1, 1}}) {
    const sl::Tensor small = sl::data::resize_area(pano, h, w);
    for (int c = 0; c < 3; ++c) {
      const double before = sl::data::radiant_power(pano, c), after = sl::data::radiant_power(small, c);
      EXPECT_NEAR(after, before, 2e-6 * before) << h << "x" << w;
    }
  }
  // A constant panorama stays constant (weights are normalised per output texel).
  const sl::Tensor flat = sl::data::resize_area(sl::Tensor::full({1, 32, 64}, 2.0), 10, 21);
  for (double x : flat.to_vector()) EXPECT_NEAR(x, 2.0, 1e-6);
}

TEST(Panorama, PerspectiveCropSeesTheDirectionsOfItsCameraAcrossTheSeam) {
  // Each texel stores its own direction; a crop pixel must show its camera ray's direction.
  const sl::Tensor pano = pano_from(3, 256, 512, [](const glm::dvec3& d) { return d; });
  sl::data::PerspectiveCropParams params;
  params.horizontal_fov_rad = 70 * sl::kDegToRad;
  params.yaw_rad = 175 * sl::kDegToRad;  // the view straddles azimuth ±180°
  params.pitch_rad = 15 * sl::kDegToRad;
  params.roll_rad = 10 * sl::kDegToRad;
  params.width = 40;
  params.height = 30;
  const sl::data::PerspectiveCrop crop = sl::data::crop_perspective(pano, params);
  ASSERT_EQ(crop.image.shape(), (sl::Shape{3, 30, 40}));
  double worst = 0.0;
  for (int row = 0; row < 30; ++row)
    for (int col = 0; col < 40; ++col) {
      const glm::dvec3 ray = crop.camera.pixel_ray(col, row).direction;
      const glm::dvec3 seen(crop.image.at({0, row, col}), crop.image.at({1, row, col}),
                            crop.image.at({2, row, col}));
      worst = std::max(worst, glm::length(seen - ray));
    }
  EXPECT_LT(worst, 2e-3);
  EXPECT_NEAR(crop.camera.intrinsics().horizontal_fov_rad(), 70 * sl::kDegToRad, 1e-12);
}

TEST(Panorama, LdrConversionIsThePapersGammaAndClip) {
  const sl::Tensor hdr = sl::Tensor::from_vector({0.0, 0.25, 1.0, 1e5, -1.0, std::nan("")}, {1, 1, 6});
  const auto ldr = sl::data::to_ldr(hdr, 2.0).to_vector();
  EXPECT_EQ(ldr[0], 0.0);
  EXPECT_NEAR(ldr[1], std::pow(0.5, 1 / 2.2), 1e-6);
  EXPECT_EQ(ldr[2], 1.0);
  EXPECT_EQ(ldr[3], 1.0);
  EXPECT_EQ(ldr[4], 0.0);
  EXPECT_EQ(ldr[5], 0.0);
}

TEST(Panorama, SkyMaskHeuristicSeparatesBlueSkyFromBuildingsAndGround) {
  // Blue sky above the horizon, a grey building over azimuths [−40°, 40°] up to 30° elevation,
  // dark ground below.
  const sl::Tensor pano = pano_from(3, 32, 64, [](const glm::dvec3& d) {
    const double elevation = std::asin(d.y) / sl::kDegToRad, azimuth = std::atan2(d.x, -d.z) / sl::kDegToRad;
    if (elevation < 0) return glm::dvec3(0.15, 0.13, 0.1);
    if (elevation < 30 && std::fabs(azimuth) < 40) return glm::dvec3(0.3, 0.3, 0.3);
    return glm::dvec3(0.4, 0.6, 1.0) * (1.0 + 0.5 * d.y);
  });
  const sl::Tensor mask = sl::data::estimate_sky_mask(pano);
  int wrong = 0;
  for (int i = 0; i < 32; ++i)
    for (int j = 0; j < 64; ++j) {
      const auto d = sl::render::equirect::uv_to_direction(j + 0.5, i + 0.5, 64, 32);
      const double elevation = std::asin(d.y) / sl::kDegToRad, azimuth = std::atan2(d.x, -d.z) / sl::kDegToRad;
      const bool sky = elevation > 0 && !(elevation < 30 && std::fabs(azimuth) < 40);
      wrong += (mask.at({0, i, j}) > 0.5) != sky;
    }
  EXPECT_EQ(wrong, 0);
}

TEST(Panorama, BadShapesAreRejectedWithTheShape) {
  try {
    sl::data::rotate_azimuth(sl::Tensor::zeros({4, 4}), 0.1);
    FAIL();
  } catch (const sl::Error& e) {
    EXPECT_NE(std::string(e.what()).find("[4, 4]"), std::string::npos) << e.what();
  }
  EXPECT_THROW(sl::data::resize_area(sl::Tensor::zeros({1, 4, 8}), 0, 4), sl::Error);
  EXPECT_THROW(sl::data::estimate_sky_mask(sl::Tensor::zeros({1, 4, 8})), sl::Error);
  EXPECT_THROW(sl::data::rotate_azimuth(sl::Tensor::zeros({1, 4, 8}), NAN), sl::Error);
}

}  // namespace sl::test
