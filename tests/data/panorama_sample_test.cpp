// Real panoramas as training samples (data/panorama_sample.h): the sun label follows rotation
// and flips, the sky-mask rule holds on a sky-model panorama, the hard-sun criterion separates a
// clear sun from an overcast sky, and a panorama that is not 2:1 is refused naming the file.
#include "data/panorama_sample.h"

#include <gtest/gtest.h>

#include <cmath>

#include "data/panorama.h"
#include "data/sky_model.h"
#include "render/equirect.h"
#include "util/math.h"

using sl::data::extract_sun;
using sl::data::flip_panorama_direction;
using sl::data::panorama_street_sample;
using sl::data::PanoramaSampleOptions;
using sl::data::PreethamSky;
using sl::data::rotate_azimuth;
using sl::data::rotate_direction_azimuth;
using sl::data::SkyParams;
using sl::data::StreetSample;
using sl::data::sun_hardness;
using sl::data::SunHardness;

namespace sl::test {
namespace {

double angle_deg(const glm::dvec3& a, const glm::dvec3& b) {
  return std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b)) * 180.0 / kPi;
}

Tensor clear_sky(double elevation_deg, double azimuth_deg, int h = 64) {
  SkyParams p;
  p.sun_elevation_rad = elevation_deg * kPi / 180.0;
  p.sun_azimuth_rad = azimuth_deg * kPi / 180.0;
  return PreethamSky(p).render(h, 2 * h);
}

PanoramaSampleOptions small_options() {
  PanoramaSampleOptions o;
  o.crop.width = 64;
  o.crop.height = 32;
  o.pano_width = 128;
  o.pano_height = 64;
  return o;
}

TEST(PanoramaSample, RotatingThePanoramaMovesTheSunLabelWithIt) {
  const Tensor pano = clear_sky(35.0, 20.0);
  const int64_t shift = 16;  // whole columns: exact
  const double delta = 2 * kPi * static_cast<double>(shift) / 128.0;
  const Tensor rotated = rotate_azimuth(pano, delta);
  PanoramaSampleOptions o = small_options();
  o.flip = false;  // a flip reverses azimuths; AFlipMirrorsTheSunLabel covers it
  for (uint64_t seed : {1u, 2u, 3u}) {
    const StreetSample a = panorama_street_sample(pano, "a", seed, 7, o);
    const StreetSample b = panorama_street_sample(rotated, "b", seed, 7, o);
    ASSERT_TRUE(a.sun_known && b.sun_known);
    EXPECT_LT(angle_deg(b.sun_direction, rotate_direction_azimuth(a.sun_direction, delta)), 0.5) << "seed " << seed;
    // The same crop camera sees the content moved by delta: the label is not a constant.
    EXPECT_GT(angle_deg(a.sun_direction, b.sun_direction), 10.0);
    // The label matches the sample's own panorama and the sun's elevation is kept.
    EXPECT_LT(angle_deg(a.sun_direction, extract_sun(a.pano_hdr).direction), 2.0);
    EXPECT_NEAR(std::asin(a.sun_direction.y) * 180 / kPi, 35.0, 1.0);
  }
  // Different seeds rotate differently (every panorama is rotated in azimuth).
  const StreetSample s1 = panorama_street_sample(pano, "a", 1, 7, small_options());
  const StreetSample s2 = panorama_street_sample(pano, "a", 2, 7, small_options());
  EXPECT_GT(angle_deg(s1.sun_direction, s2.sun_direction), 1.0);
}

TEST(PanoramaSample, AFlipMirrorsTheSunLabel) {
  const Tensor pano = clear_sky(40.0, -60.0);
  PanoramaSampleOptions with = small_options(), without = small_options();
  without.flip = false;
  int flipped = 0;
  for (uint64_t stream = 0; stream < 16; ++stream) {
    const StreetSample f = panorama_street_sample(pano, "p", 5, stream, with);
    const StreetSample n = panorama_street_sample(pano, "p", 5, stream, without);
    if (angle_deg(f.sun_direction, n.sun_direction) < 0.5) continue;  // this draw did not flip
    ++flipped;
    EXPECT_LT(angle_deg(f.sun_direction, flip_panorama_direction(n.sun_direction)), 0.5);
    EXPECT_LT(angle_deg(f.sun_direction, extract_sun(f.pano_hdr).direction), 2.0);
  }
  EXPECT_GT(flipped, 2);
  EXPECT_LT(flipped, 14);
}

TEST(PanoramaSample, SkyMaskRuleHoldsOnASkyModelPanorama) {
  const Tensor pano = clear_sky(30.0, 0.0);
  PanoramaSampleOptions o = small_options();
  o.rotate = false;
  o.flip = false;
  const StreetSample s = panorama_street_sample(pano, "sky", 1, 0, o);
  const Tensor& m = s.pano_sky_mask;
  const int64_t h = m.size(1), w = m.size(2);
  double upper = 0, lower = 0;
  for (int64_t r = 0; r < h; ++r)
    for (int64_t c = 0; c < w; ++c) (r < h / 2 ? upper : lower) += m.data<float>()[r * w + c];
  EXPECT_GT(upper / static_cast<double>(h / 2 * w), 0.95) << "clear sky above the horizon is sky";
  EXPECT_EQ(lower, 0.0) << "nothing below the horizon is sky";
  // The view's mask is the panorama's, seen through the crop camera.
  const Tensor& vm = s.views[0].sky_mask;
  EXPECT_EQ(vm.shape(), (Shape{1, 32, 64}));
}

TEST(PanoramaSample, HardSunCriterionSeparatesAClearSunFromAnOvercastSky) {
  const SunHardness clear = sun_hardness(clear_sky(45.0, 0.0));
  EXPECT_TRUE(clear.hard) << "share " << clear.share;
  EXPECT_GT(clear.share, 0.25);
  SkyParams p;
  p.sun_disk = false;
  p.cloud_cover = 0.9;
  const SunHardness overcast = sun_hardness(PreethamSky(p).render(64, 128));
  EXPECT_FALSE(overcast.hard) << "share " << overcast.share;
  // The same clear sky upside down: its sun is below the horizon.
  const Tensor up = clear_sky(45.0, 0.0);
  Tensor down = Tensor::empty(up.shape());
  const int64_t h = up.size(1), w = up.size(2);
  for (int64_t c = 0; c < 3; ++c)
    for (int64_t r = 0; r < h; ++r)
      for (int64_t x = 0; x < w; ++x) down.data<float>()[(c * h + r) * w + x] = up.data<float>()[(c * h + h - 1 - r) * w + x];
  const SunHardness below = sun_hardness(down);
  EXPECT_GT(below.share, 0.25);
  EXPECT_FALSE(below.hard);
}

TEST(PanoramaSample, APanoramaThatIsNot2To1IsRefusedNamingIt) {
  const Tensor bad = Tensor::zeros({3, 64, 100});
  try {
    panorama_street_sample(bad, "odd_1k.hdr", 1, 0, small_options());
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("odd_1k.hdr"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("2:1"), std::string::npos) << e.what();
  }
}

TEST(PanoramaSample, IsAPureFunctionOfSeedAndStreamWithFiniteValues) {
  const Tensor pano = clear_sky(20.0, 90.0);
  const StreetSample a = panorama_street_sample(pano, "p", 9, 3, small_options());
  const StreetSample b = panorama_street_sample(pano, "p", 9, 3, small_options());
  EXPECT_EQ(a.views[0].ldr.to_vector(), b.views[0].ldr.to_vector());
  EXPECT_EQ(a.sun_direction, b.sun_direction);
  for (float v : a.views[0].ldr.to_vector()) ASSERT_TRUE(std::isfinite(v) && v >= 0 && v <= 1);
  for (float v : a.views[0].depth.to_vector()) ASSERT_EQ(v, 0.0f);  // unknown depth: holes
}

// The sun's energy: a cap of constant radiance L holds L·2π(1 − cos r) within r, whatever the
// panorama's azimuth; channels are summed apart.
TEST(PanoramaSample, SunEnergyIsTheCapsRadianceTimesItsSolidAngle) {
  const int w = 1024, h = 512;
  const glm::dvec3 sun = glm::normalize(glm::dvec3(0.3, 0.6, -0.7));
  Tensor pano = Tensor::zeros({3, h, w});
  float* p = pano.data<float>();
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) {
      const auto d = render::equirect::uv_to_direction(c + 0.5, r + 0.5, w, h);
      if (d.x * sun.x + d.y * sun.y + d.z * sun.z >= std::cos(10.0 * kPi / 180.0))
        for (int ch = 0; ch < 3; ++ch) p[(ch * h + r) * w + c] = 1000.0f * static_cast<float>(ch + 1);
      else
        p[r * w + c] = 1.0f;  // a dim red sky outside the cap
    }
  const double cap = 2 * kPi * (1 - std::cos(5.0 * kPi / 180.0));
  const glm::dvec3 e = data::sun_energy_rgb(pano, sun, 5.0);
  for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(e[ch], 1000.0 * (ch + 1) * cap, 0.02 * 1000.0 * (ch + 1) * cap) << ch;
  const double delta = 2 * kPi * 100.0 / w;  // whole columns
  const glm::dvec3 turned = data::sun_energy_rgb(rotate_azimuth(pano, delta), rotate_direction_azimuth(sun, delta), 5.0);
  for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(turned[ch], e[ch], 0.01 * e[ch]) << ch;
}

}  // namespace
}  // namespace sl::test
