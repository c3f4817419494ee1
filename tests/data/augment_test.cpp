// Augmentation: flips mirror the world consistently with the pixels; crops return cameras
// that see what the panorama shows; exposure jitter is seeded.
#include <gtest/gtest.h>

#include "data/augment.h"
#include "data/panorama_dataset.h"
#include "render/equirect.h"
#include "support/test_files.h"
#include "util/error.h"
#include "util/math.h"

using sl::data::CropRanges;
using sl::data::flip_panorama;
using sl::data::flip_panorama_direction;
using sl::data::flip_view;
using sl::data::PanoramaDataset;
using sl::data::PanoramaItem;
using sl::data::random_exposure_factor;
using sl::data::random_perspective_crop;
using sl::data::RandomCrop;
using sl::data::scale_hdr;
using sl::data::scale_ldr;
using sl::data::StreetView;
using sl::data::to_ldr;
using sl::render::Camera;
using sl::render::intrinsics_from_fov;
using sl::render::Projection;
using sl::render::rotation_from_yaw_pitch_roll;

namespace sl::test {
namespace {

TEST(Augment, FlippedViewSeesTheMirroredWorld) {
  StreetView v;
  v.camera = Camera(intrinsics_from_fov(1.2, 40, 20), rotation_from_yaw_pitch_roll(0.4, 0.1, 0.0), {1, 1.6, -2});
  v.ldr = Tensor::zeros({3, 20, 40});
  v.depth = Tensor::zeros({20, 40});
  v.ldr.data<float>()[5 * 40 + 7] = 1.0f;  // channel 0, row 5, column 7
  v.depth.data<float>()[5 * 40 + 7] = 12.0f;
  glm::dvec3 sun = glm::normalize(glm::dvec3(0.3, 0.8, -0.5));
  const glm::dvec3 sun0 = sun;
  const StreetView f = flip_view(v, &sun);
  EXPECT_EQ(f.ldr.data<float>()[5 * 40 + (40 - 1 - 7)], 1.0f);
  EXPECT_EQ(f.depth.data<float>()[5 * 40 + (40 - 1 - 7)], 12.0f);
  // A world point seen at pixel (u, v) appears, after mirroring the world, at (W − u, v).
  const glm::dvec3 p = v.camera.unproject(7.5, 5.5, 12.0);
  const glm::dvec3 a = v.camera.rotation()[0];
  const glm::dvec3 mirrored = p - 2.0 * glm::dot(p - v.camera.position(), a) * a;
  const Projection pr = f.camera.project(mirrored);
  EXPECT_NEAR(pr.pixel.x, 40 - 7.5, 1e-9);
  EXPECT_NEAR(pr.pixel.y, 5.5, 1e-9);
  EXPECT_NEAR(pr.depth, 12.0, 1e-9);
  // The sun is mirrored by the same plane: flipping twice restores it.
  EXPECT_NEAR(glm::dot(sun, a), -glm::dot(sun0, a), 1e-12);
  glm::dvec3 back = sun;
  flip_view(f, &back);
  EXPECT_NEAR(glm::length(back - sun0), 0.0, 1e-12);
}

// flip_sample mirrors the world across x = 0 for every view at once: each view sees the
// mirrored point at (W − u, v) with the same depth, the sun and the panorama follow, the
// insertion is dropped and a second flip gives the sample back.
TEST(Augment, FlippedSampleMirrorsEveryViewAndThePanoramaConsistently) {
  sl::data::StreetSample s;
  s.id = "x";
  s.sun_direction = glm::normalize(glm::dvec3(0.3, 0.8, -0.5));
  s.pano_position = {0.7, 1.6, -3.0};
  s.pano_ldr = Tensor::zeros({3, 16, 32});
  s.pano_ldr.data<float>()[4 * 32 + 3] = 1.0f;
  s.has_insertion = true;
  for (const auto& [yaw, roll] : {std::pair{0.4, 0.0}, std::pair{-1.9, 0.15}}) {
    StreetView v;
    v.camera = Camera(intrinsics_from_fov(1.2, 40, 20), rotation_from_yaw_pitch_roll(yaw, 0.1, roll), {1, 1.6, -2});
    v.ldr = Tensor::zeros({3, 20, 40});
    v.depth = Tensor::zeros({20, 40});
    s.views.push_back(v);
  }
  const sl::data::StreetSample f = sl::data::flip_sample(s);
  ASSERT_EQ(f.views.size(), 2u);
  EXPECT_FALSE(f.has_insertion);
  for (size_t k = 0; k < 2; ++k) {
    const Camera& c = s.views[k].camera;
    const glm::dvec3 p = c.unproject(7.5, 5.5, 12.0);
    const Projection pr = f.views[k].camera.project({-p.x, p.y, p.z});
    EXPECT_NEAR(pr.pixel.x, 40 - 7.5, 1e-9) << "view " << k;
    EXPECT_NEAR(pr.pixel.y, 5.5, 1e-9) << "view " << k;
    EXPECT_NEAR(pr.depth, 12.0, 1e-9) << "view " << k;
    EXPECT_NEAR(glm::determinant(f.views[k].camera.rotation()), 1.0, 1e-12);
  }
  EXPECT_EQ(f.sun_direction, glm::dvec3(-s.sun_direction.x, s.sun_direction.y, s.sun_direction.z));
  EXPECT_EQ(f.pano_position, glm::dvec3(-0.7, 1.6, -3.0));
  EXPECT_EQ(f.pano_ldr.data<float>()[4 * 32 + (32 - 1 - 3)], 1.0f);
  const sl::data::StreetSample back = sl::data::flip_sample(f);
  EXPECT_EQ(back.sun_direction, s.sun_direction);
  EXPECT_EQ(back.pano_ldr.to_vector(), s.pano_ldr.to_vector());
  for (size_t k = 0; k < 2; ++k) {
    EXPECT_EQ(back.views[k].camera.position(), s.views[k].camera.position());
    EXPECT_NEAR(glm::length(back.views[k].camera.rotation()[0] - s.views[k].camera.rotation()[0]), 0.0, 1e-15);
    EXPECT_NEAR(back.views[k].camera.intrinsics().cx, s.views[k].camera.intrinsics().cx, 1e-12);
  }
}

TEST(Augment, PanoramaFlipMirrorsAzimuth) {
  Tensor pano = Tensor::zeros({3, 16, 32});
  const glm::dvec3 d = glm::normalize(glm::dvec3(0.6, 0.3, -0.4));
  const render::equirect::UV uv = render::equirect::direction_to_uv(d.x, d.y, d.z, 32, 16);
  pano.data<float>()[static_cast<int>(uv.v) * 32 + static_cast<int>(uv.u)] = 1.0f;
  const Tensor f = flip_panorama(pano);
  const glm::dvec3 m = flip_panorama_direction(d);
  const render::equirect::UV uv2 = render::equirect::direction_to_uv(m.x, m.y, m.z, 32, 16);
  EXPECT_EQ(f.data<float>()[static_cast<int>(uv2.v) * 32 + static_cast<int>(uv2.u)], 1.0f);
}

TEST(Augment, RandomCropIsSeededAndReturnsItsCamera) {
  Tensor pano = Tensor::zeros({3, 32, 64});
  const RandomCrop a = random_perspective_crop(pano, 3, 1), b = random_perspective_crop(pano, 3, 1),
                   c = random_perspective_crop(pano, 3, 2);
  EXPECT_EQ(a.yaw_deg, b.yaw_deg);
  EXPECT_NE(a.yaw_deg, c.yaw_deg);
  // The crop camera's optical axis has the sampled yaw and pitch (render/camera.h).
  const glm::dvec3 fwd = a.crop.camera.rotation()[2];
  const render::equirect::UV uv = render::equirect::direction_to_uv(fwd.x, fwd.y, fwd.z, 360, 180);
  EXPECT_NEAR(uv.u - 180.0, a.yaw_deg, 1e-6);
  EXPECT_NEAR(90.0 - uv.v, a.pitch_deg, 1e-6);
  EXPECT_NEAR(a.crop.camera.intrinsics().horizontal_fov_rad() * 180 / kPi, a.fov_deg, 1e-6);
}

glm::dvec3 direction(double azimuth_deg, double elevation_deg) {
  const double a = azimuth_deg * kPi / 180.0, e = elevation_deg * kPi / 180.0;
  return {std::cos(e) * std::sin(a), std::sin(e), -std::cos(e) * std::cos(a)};
}

// Sun-aimed crops (data/augment.h): half look toward the sun, which then lies in the view, half
// away from it; a sun too high for the pitch limit, and every crop not drawn for aiming, keeps
// the plain draw.
TEST(Augment, SunAimedCropsShowTheSunOrTurnAwayFromItInEqualShares) {
  Tensor pano = Tensor::zeros({3, 32, 64});
  CropRanges plain;
  plain.width = 64;
  plain.height = 32;
  CropRanges aimed = plain;
  aimed.sun_aim_share = 1.0;
  const glm::dvec3 position(0.0, 1.6, 0.0);
  const glm::dvec3 sun = direction(-120.0, 32.0);  // above a plain crop's view at pitch ≤ 10°
  int toward = 0, away = 0, plain_in_view = 0;
  for (uint64_t stream = 0; stream < 400; ++stream) {
    const RandomCrop p = random_perspective_crop(pano, 7, stream, plain, position, &sun);
    const RandomCrop a = random_perspective_crop(pano, 7, stream, aimed, position, &sun);
    EXPECT_EQ(p.aimed, 0);
    EXPECT_EQ(a.fov_deg, p.fov_deg);  // only yaw and pitch change
    EXPECT_EQ(a.roll_deg, p.roll_deg);
    const auto shows = [&](const RandomCrop& c) {
      return c.crop.camera.project(c.crop.camera.position() + 1e4 * sun).in_image;
    };
    plain_in_view += shows(p);
    ASSERT_NE(a.aimed, 0) << "a 32° sun can be brought into a view pitched at most 25°";
    if (a.aimed > 0) {
      ++toward;
      EXPECT_TRUE(shows(a)) << "stream " << stream;
      EXPECT_LE(std::abs(a.pitch_deg), 25.0);
    } else {
      ++away;
      EXPECT_FALSE(shows(a));
      EXPECT_EQ(a.pitch_deg, p.pitch_deg);
      // The view's axis points away from the sun's azimuth: more than 90° off.
      EXPECT_GT(std::abs(std::remainder(a.yaw_deg - (-120.0), 360.0)), 90.0);
    }
  }
  EXPECT_EQ(plain_in_view, 0);
  EXPECT_NEAR(toward, 200, 40);
  EXPECT_EQ(toward + away, 400);
  // A sun at 75° cannot be brought into view below 25° of pitch: no crop is aimed, none changes.
  const glm::dvec3 high = direction(30.0, 75.0);
  for (uint64_t stream = 0; stream < 50; ++stream) {
    const RandomCrop p = random_perspective_crop(pano, 7, stream, plain), a = random_perspective_crop(pano, 7, stream, aimed, position, &high);
    EXPECT_EQ(a.aimed, 0);
    EXPECT_EQ(a.yaw_deg, p.yaw_deg);
    EXPECT_EQ(a.pitch_deg, p.pitch_deg);
  }
  // A share of 0.3: about that many aimed; the others are the plain draw exactly.
  aimed.sun_aim_share = 0.3;
  int n_aimed = 0;
  for (uint64_t stream = 0; stream < 400; ++stream) {
    const RandomCrop p = random_perspective_crop(pano, 7, stream, plain), a = random_perspective_crop(pano, 7, stream, aimed, position, &sun);
    if (a.aimed != 0) {
      ++n_aimed;
      continue;
    }
    EXPECT_EQ(a.yaw_deg, p.yaw_deg);
    EXPECT_EQ(a.pitch_deg, p.pitch_deg);
  }
  EXPECT_NEAR(n_aimed, 120, 35);
  CropRanges bad = plain;
  bad.sun_aim_share = 1.5;
  EXPECT_THROW(random_perspective_crop(pano, 7, 0, bad, position, &sun), Error);
}

TEST(Augment, ExposureJitterScalesHdrAndLdrConsistently) {
  const double k = random_exposure_factor(1, 2, 1.0);
  EXPECT_GE(k, 0.5);
  EXPECT_LE(k, 2.0);
  EXPECT_EQ(k, random_exposure_factor(1, 2, 1.0));
  const Tensor hdr = Tensor::full({3, 2, 2}, 0.1);
  const Tensor ldr = to_ldr(hdr, 1.0);
  const Tensor a = scale_ldr(ldr, k), b = to_ldr(scale_hdr(hdr, k), 1.0);
  for (int i = 0; i < 12; ++i) EXPECT_NEAR(a.data<float>()[i], b.data<float>()[i], 1e-6);
}

TEST(PanoramaDataset, RotatedSunMatchesTheRotatedPeak) {
  const std::string folder = test::shared_data("hdri");
  if (!std::filesystem::exists(folder)) GTEST_SKIP() << "shared data folder " << folder << " is absent";
  CropRanges r;
  r.width = 64;
  r.height = 32;
  const PanoramaDataset ds(folder, r);
  size_t index = ds.size();  // chinese_garden: a hard sun (selected by name: the folder grows)
  for (size_t i = 0; i < ds.size(); ++i)
    if (ds.folder().path(i).find("chinese_garden_1k") != std::string::npos) index = i;
  ASSERT_LT(index, ds.size()) << "chinese_garden_1k.hdr is missing from " << folder;
  const PanoramaItem a = ds.load(index, 1), b = ds.load(index, 2);
  EXPECT_NE(a.azimuth_rad, b.azimuth_rad);
  ASSERT_TRUE(a.sun.found && b.sun.found);
  // Same elevation; azimuths differ by the difference of the rotations.
  EXPECT_NEAR(a.sun.elevation_rad, b.sun.elevation_rad, 1e-3);
  const double d = std::remainder((a.sun.azimuth_rad - b.sun.azimuth_rad) - (a.azimuth_rad - b.azimuth_rad),
                                  2 * kPi);
  EXPECT_NEAR(d, 0.0, 1e-3);
  EXPECT_EQ(a.crop_ldr.shape(), (Shape{3, 32, 64}));
}

}  // namespace
}  // namespace sl::test
