// Real LDR panoramas as samples (data/ldr_panorama_sample.h): the labelled sun turns with the
// image under rotation and flips and lands on the crop's brightest pixel when the crop holds it;
// a texel the camera clipped stays clipped when the jitter darkens the photo while the others
// scale as the linear radiance does; without jitter the crop is the benchmark's; the sky mask
// follows the image; a panorama that is not 2:1 is refused naming it.
#include "data/ldr_panorama_sample.h"

#include <gtest/gtest.h>

#include <cmath>

#include "autodiff/ops.h"
#include "data/augment.h"
#include "data/panorama.h"
#include "render/equirect.h"
#include "util/error.h"
#include "util/math.h"

namespace sl::test {
namespace {

double angle_deg(const glm::dvec3& a, const glm::dvec3& b) {
  return std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b)) * 180.0 / kPi;
}

// A grey street panorama (blue sky above the horizon, grey below) with a clipped sun disk of
// `radius_deg` around `sun`: codes / 255 as a JPEG gives them.
data::LdrPanorama disk_panorama(const glm::dvec3& sun, int width, double radius_deg = 3.0) {
  const int h = width / 2;
  Tensor t = Tensor::empty({3, h, width});
  float* p = t.data<float>();
  const int64_t plane = static_cast<int64_t>(h) * width;
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < width; ++c) {
      const auto d = render::equirect::uv_to_direction(c + 0.5, r + 0.5, width, h);
      const double cosang = d.x * sun.x + d.y * sun.y + d.z * sun.z;
      const bool disk = cosang >= std::cos(radius_deg * kDegToRad);
      const float sky[3] = {0.45f, 0.6f, 0.85f}, ground[3] = {0.35f, 0.33f, 0.3f};
      for (int ch = 0; ch < 3; ++ch)
        p[ch * plane + r * width + c] = disk ? 1.0f : (d.y > 0 ? sky[ch] : ground[ch]);
    }
  data::LdrPanorama pano;
  pano.ldr = t;
  pano.sky_mask = data::ldr_sky_mask(t);
  pano.sun_known = true;
  pano.sun_direction = sun;
  return pano;
}

data::PanoramaSampleOptions small_options() {
  data::PanoramaSampleOptions o;
  o.crop.width = 64;
  o.crop.height = 32;
  o.pano_width = 128;
  o.pano_height = 64;
  return o;
}

glm::dvec3 brightest_direction(const Tensor& pano) {
  const Tensor t = pano.contiguous();
  const int64_t h = t.size(1), w = t.size(2), plane = h * w;
  const float* p = t.data<float>();
  glm::dvec3 sum(0.0);
  for (int64_t i = 0; i < plane; ++i)
    if (p[i] + p[plane + i] + p[2 * plane + i] > 2.9f) {  // the disk's texels
      const auto d = render::equirect::uv_to_direction(i % w + 0.5, i / w + 0.5, static_cast<int>(w),
                                                       static_cast<int>(h));
      sum += glm::dvec3(d.x, d.y, d.z);
    }
  return glm::length(sum) > 0 ? glm::normalize(sum) : glm::dvec3(0.0);
}

TEST(LdrPanoramaSample, TheLabelledSunTurnsWithTheImage) {
  const glm::dvec3 sun = glm::normalize(glm::dvec3(0.5, 0.35, -0.8));
  const data::LdrPanorama pano = disk_panorama(sun, 512);
  const data::PanoramaSampleOptions o = small_options();
  int flips = 0;
  for (uint64_t stream = 0; stream < 12; ++stream) {
    const data::StreetSample s = data::ldr_panorama_street_sample(pano, "p", 5, stream, o);
    const data::PanoramaSampleDraw draw = data::draw_panorama_sample(5, stream, 512, o);
    flips += draw.flip;
    ASSERT_TRUE(s.sun_known);
    // The label: rotated by the draw's columns, then mirrored when flipped.
    glm::dvec3 want = data::rotate_direction_azimuth(sun, 2 * kPi * static_cast<double>(draw.shift_columns) / 512.0);
    if (draw.flip) want = data::flip_panorama_direction(want);
    EXPECT_LT(angle_deg(s.sun_direction, want), 1e-9) << "stream " << stream;
    // The image: the disk's centre in the sample's panorama is the label (a texel is 2.8°).
    EXPECT_LT(angle_deg(brightest_direction(s.pano_ldr), s.sun_direction), 2.0) << "stream " << stream;
  }
  EXPECT_GT(flips, 0);
  EXPECT_LT(flips, 12);
}

TEST(LdrPanoramaSample, ACropThatHoldsTheSunShowsItAtTheLabelsPixel) {
  // A low sun, so that crops pitched ±10° with a 50-80° field of view often hold it.
  const glm::dvec3 sun = glm::normalize(glm::dvec3(-0.3, 0.12, -0.9));
  const data::LdrPanorama pano = disk_panorama(sun, 512, 2.0);
  const data::PanoramaSampleOptions o = small_options();
  int seen = 0;
  for (uint64_t stream = 0; stream < 200 && seen < 5; ++stream) {
    const data::StreetSample s = data::ldr_panorama_street_sample(pano, "p", 9, stream, o);
    const render::Camera& cam = s.views[0].camera;
    const render::Projection pr = cam.project(cam.position() + 1e4 * s.sun_direction);
    if (!pr.in_image || pr.pixel.x < 4 || pr.pixel.y < 4 || pr.pixel.x > o.crop.width - 4 || pr.pixel.y > o.crop.height - 4)
      continue;
    ++seen;
    const Tensor v = s.views[0].ldr.contiguous();
    const int64_t h = v.size(1), w = v.size(2), plane = h * w;
    const float* p = v.data<float>();
    double su = 0, sv = 0, n = 0;
    for (int64_t i = 0; i < plane; ++i)
      if (p[i] + p[plane + i] + p[2 * plane + i] > 2.9f) su += i % w + 0.5, sv += i / w + 0.5, n += 1;
    ASSERT_GT(n, 0) << "stream " << stream;
    EXPECT_NEAR(su / n, pr.pixel.x, 1.0) << "stream " << stream;
    EXPECT_NEAR(sv / n, pr.pixel.y, 1.0) << "stream " << stream;
  }
  EXPECT_GE(seen, 5);
}

// Aimed crops (data/augment.h, data.sun_aim_share) aim at the label as the sample turns it: a
// 37° sun, which no plain crop shows (pitch ≤ 10°, at most 23° above the axis), is in half of the
// views, and its disk is where the label projects; the other half look away from it.
TEST(LdrPanoramaSample, SunAimedCropsShowTheLabelledSunInHalfTheViews) {
  const glm::dvec3 sun = glm::normalize(glm::dvec3(0.5, 0.6, 0.7));  // 37° high, behind the panorama's centre
  const data::LdrPanorama pano = disk_panorama(sun, 512, 2.0);
  data::PanoramaSampleOptions o = small_options();
  o.crop.sun_aim_share = 1.0;
  o.crop.sun_aim_max_pitch_deg = 35.0;
  int shown = 0, disk_there = 0;
  const int n = 60;
  for (uint64_t stream = 0; stream < n; ++stream) {
    const data::StreetSample s = data::ldr_panorama_street_sample(pano, "p", 9, stream, o);
    const render::Camera& cam = s.views[0].camera;
    const render::Projection pr = cam.project(cam.position() + 1e4 * s.sun_direction);
    if (!pr.in_image) continue;
    ++shown;
    const Tensor v = s.views[0].ldr.contiguous();
    const int64_t h = v.size(1), w = v.size(2), plane = h * w;
    const float* p = v.data<float>();
    const int64_t x = std::clamp<int64_t>(static_cast<int64_t>(pr.pixel.x), 0, w - 1);
    const int64_t y = std::clamp<int64_t>(static_cast<int64_t>(pr.pixel.y), 0, h - 1);
    disk_there += p[y * w + x] + p[plane + y * w + x] + p[2 * plane + y * w + x] > 2.9f;
  }
  EXPECT_NEAR(shown, n / 2, 12);
  EXPECT_GE(disk_there, shown - 1);
  o.crop.sun_aim_share = 0.0;
  for (uint64_t stream = 0; stream < n; ++stream) {
    const data::StreetSample s = data::ldr_panorama_street_sample(pano, "p", 9, stream, o);
    const render::Camera& cam = s.views[0].camera;
    EXPECT_FALSE(cam.project(cam.position() + 1e4 * s.sun_direction).in_image);
  }
}

TEST(LdrPanoramaSample, ClippedTexelsStayClippedAndTheRestScaleLinearly) {
  data::LdrPanorama pano;
  const int w = 128, h = 64;
  pano.ldr = Tensor::full({3, h, w}, 0.5f);
  float* p = pano.ldr.data<float>();
  for (int ch = 0; ch < 3; ++ch)
    for (int r = 0; r < h; ++r)
      for (int c = 0; c < w / 2; ++c) p[(ch * h + r) * w + c] = 1.0f;  // the left half clipped
  data::PanoramaSampleOptions o = small_options();
  o.exposure_stops = 2.0;
  o.white_balance_stops = 0.2;
  o.rotate = false;
  o.flip = false;
  int darker = 0;
  for (uint64_t stream = 0; stream < 16; ++stream) {
    const data::PanoramaSampleDraw d = data::draw_panorama_sample(1, stream, w, o);
    const data::StreetSample s = data::ldr_panorama_street_sample(pano, "p", 1, stream, o);
    const Tensor q = s.pano_ldr.contiguous();  // 128 × 64: the working size, so no resampling
    const float* v = q.data<float>();
    const double grey = luminance(d.gain[0], d.gain[1], d.gain[2]);
    for (int ch = 0; ch < 3; ++ch) {
      const double want = std::min(1.0, 0.5 * std::pow(d.gain[ch] / grey * d.exposure_jitter, 1 / 2.2));
      EXPECT_NEAR(v[(ch * h + 10) * w + 5], 1.0, 1e-6) << "a clipped texel, stream " << stream;
      EXPECT_NEAR(v[(ch * h + 10) * w + 100], want, 1e-5) << "an unclipped texel, stream " << stream;
    }
    darker += d.exposure_jitter < 0.7;
  }
  EXPECT_GT(darker, 0);  // the rule was exercised where it matters
}

TEST(LdrPanoramaSample, WithoutJitterTheViewIsThePanoramasCrop) {
  const data::LdrPanorama pano = disk_panorama(glm::normalize(glm::dvec3(0.2, 0.5, -0.8)), 256);
  data::PanoramaSampleOptions o = small_options();
  o.flip = false;
  o.exposure_stops = 0.0;
  o.white_balance_stops = 0.0;
  for (uint64_t stream : {0u, 3u}) {
    const data::PanoramaSampleDraw d = data::draw_panorama_sample(2, stream, 256, o);
    // The crop of the linear radiance codes^2.2 (clipped codes stay 1), re-encoded.
    const Tensor linear = pow_scalar(pano.ldr, 2.2);
    const Tensor rotated = data::rotate_azimuth(linear, 2 * kPi * static_cast<double>(d.shift_columns) / 256.0);
    const data::RandomCrop rc =
        data::random_perspective_crop(rotated.contiguous(), 2, d.crop_stream, o.crop, {0.0, o.camera_height_m, 0.0});
    const data::StreetSample s = data::ldr_panorama_street_sample(pano, "p", 2, stream, o);
    const std::vector<double> got = s.views[0].ldr.to_vector(), want = data::to_ldr(rc.crop.image, 1.0).to_vector();
    ASSERT_EQ(got.size(), want.size());
    for (size_t i = 0; i < got.size(); ++i) ASSERT_NEAR(got[i], want[i], 2e-6) << i;
    EXPECT_EQ(s.exposure, 1.0);
    // The sky mask went with the image: its crop is sky where the view looks above the horizon.
    const Tensor m = s.views[0].sky_mask.contiguous();
    ASSERT_TRUE(m.defined());
    const render::Camera& cam = s.views[0].camera;
    int agree = 0, total = 0;
    for (int r = 0; r < o.crop.height; r += 3)
      for (int c = 0; c < o.crop.width; c += 3) {
        const double y = cam.pixel_ray(c, r).direction.y;
        if (std::abs(y) < 0.05) continue;  // near the horizon
        agree += (m.data<float>()[r * o.crop.width + c] >= 0.5f) == (y > 0);
        ++total;
      }
    EXPECT_GE(agree, total * 95 / 100) << "stream " << stream;
  }
}

// Lean: a panorama whose linear radiance was computed once gives the same samples, bit for bit,
// as one whose codes are raised to 2.2 for every sample.
TEST(LdrPanoramaSample, KeptLinearRadianceChangesNoSample) {
  data::LdrPanorama each = disk_panorama(glm::normalize(glm::dvec3(0.4, 0.3, -0.8)), 256);
  data::LdrPanorama kept = each;
  kept.linear = data::ldr_linear(kept.ldr);
  data::PanoramaSampleOptions o = small_options();
  o.exposure_stops = 1.0;
  for (uint64_t stream : {0u, 1u, 2u, 3u}) {
    const data::StreetSample a = data::ldr_panorama_street_sample(each, "p", 4, stream, o);
    const data::StreetSample b = data::ldr_panorama_street_sample(kept, "p", 4, stream, o);
    EXPECT_EQ(a.views[0].ldr.to_vector(), b.views[0].ldr.to_vector()) << stream;
    EXPECT_EQ(a.pano_hdr.to_vector(), b.pano_hdr.to_vector()) << stream;
  }
}

TEST(LdrPanoramaSample, RefusesAPanoramaThatIsNot2To1NamingIt) {
  data::LdrPanorama pano;
  pano.ldr = Tensor::full({3, 64, 64}, 0.5f);
  try {
    data::ldr_panorama_street_sample(pano, "square.jpg", 1, 0, small_options());
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("square.jpg"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace sl::test
