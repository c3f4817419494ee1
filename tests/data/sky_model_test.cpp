#include "data/sky_model.h"

#include <gtest/gtest.h>

#include <cmath>

#include "data/panorama.h"
#include "data/sun_extraction.h"
#include "render/equirect.h"
#include "util/math.h"

namespace sl::test {

namespace {

glm::dvec3 from_angles(double elevation_deg, double azimuth_deg) {
  const double e = elevation_deg * sl::kDegToRad, a = azimuth_deg * sl::kDegToRad;
  return {std::cos(e) * std::sin(a), std::sin(e), -std::cos(e) * std::cos(a)};
}

double lum(const glm::dvec3& c) { return sl::luminance(c.x, c.y, c.z); }

double angle_deg(const glm::dvec3& a, const glm::dvec3& b) {
  return std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b)) / sl::kDegToRad;
}

sl::data::SkyParams sky(double elevation_deg, double azimuth_deg, double turbidity = 3.0) {
  sl::data::SkyParams p;
  p.sun_elevation_rad = elevation_deg * sl::kDegToRad;
  p.sun_azimuth_rad = azimuth_deg * sl::kDegToRad;
  p.turbidity = turbidity;
  return p;
}

}  // namespace

TEST(SkyModel, TheSunIsThePeakOfTheRenderedPanorama) {
  for (double elevation : {5.0, 30.0, 60.0, 89.0})
    for (double azimuth : {-180.0, -45.0, 100.0}) {
      const sl::data::PreethamSky model(sky(elevation, azimuth));
      const sl::Tensor pano = model.render(64, 128);
      const sl::data::SunEstimate est = sl::data::extract_sun(pano);
      EXPECT_LT(angle_deg(est.direction, model.sun_direction()), 1.5) << elevation << " " << azimuth;
      for (double x : pano.to_vector()) ASSERT_TRUE(std::isfinite(x) && x >= 0.0);
    }
}

TEST(SkyModel, SunDiskEnergyIsItsRadianceTimesItsSolidAngleAtAnyResolution) {
  sl::data::SkyParams with = sky(40.0, 20.0);
  with.ground_albedo = 0.0;  // the sun also lights the ground; keep only the disk's own energy
  sl::data::SkyParams without = with;
  without.sun_disk = false;
  const sl::data::PreethamSky a(with), b(without);
  for (int h : {16, 64, 256}) {
    const sl::Tensor pa = a.render(h, 2 * h), pb = b.render(h, 2 * h);
    for (int c = 0; c < 3; ++c) {
      const double expected = a.sun_radiance()[c] * a.sun_solid_angle();
      EXPECT_NEAR(sl::data::radiant_power(pa, c) - sl::data::radiant_power(pb, c), expected, 1e-3 * expected) << h;
    }
  }
}

TEST(SkyModel, SunIsTenThousandToOneHundredThousandTimesTheMeanSky) {
  for (double elevation : {5.0, 15.0, 30.0, 45.0, 60.0, 75.0, 89.0}) {
    const sl::data::PreethamSky model(sky(elevation, 0.0));
    double sum = 0, weight = 0;  // solid-angle mean of the clear sky over the upper hemisphere
    for (int i = 0; i < 32; ++i)
      for (int j = 0; j < 128; ++j) {
        const auto d = sl::render::equirect::uv_to_direction(j + 0.5, i + 0.5, 128, 64);
        const double omega = sl::render::equirect::pixel_solid_angle(i, 128, 64);
        sum += lum(model.clear_sky_radiance({d.x, d.y, d.z})) * omega;
        weight += omega;
      }
    const double ratio = lum(model.sun_radiance()) / (sum / weight);
    EXPECT_GT(ratio, 1e4) << elevation;
    EXPECT_LT(ratio, 1e5) << elevation;
  }
  // A low sun is dimmer and redder (longer air mass).
  const sl::data::PreethamSky low(sky(3.0, 0.0)), high(sky(60.0, 0.0));
  EXPECT_LT(lum(low.sun_radiance()), 0.1 * lum(high.sun_radiance()));
  EXPECT_GT(low.sun_radiance().x / low.sun_radiance().z, 2.0 * high.sun_radiance().x / high.sun_radiance().z);
}

TEST(SkyModel, RadianceIsSymmetricAboutTheSunsVerticalPlane) {
  const double sun_azimuth = 37.0;
  const sl::data::PreethamSky model(sky(25.0, sun_azimuth));
  for (double elevation : {1.0, 20.0, 50.0, 85.0})
    for (double offset : {5.0, 60.0, 150.0}) {
      const glm::dvec3 l = model.radiance(from_angles(elevation, sun_azimuth + offset));
      const glm::dvec3 r = model.radiance(from_angles(elevation, sun_azimuth - offset));
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(l[c], r[c], 1e-9 * (1 + l[c]));
    }
}

TEST(SkyModel, RadianceIsContinuousAcrossTheSky) {
  const sl::data::PreethamSky model(sky(30.0, 0.0, 4.0));
  // Neighbouring directions 0.1° apart differ by < 2% everywhere above the horizon.
  double worst = 0.0;
  for (double elevation = 0.5; elevation < 90.0; elevation += 2.0)
    for (double azimuth = -180.0; azimuth < 180.0; azimuth += 3.0) {
      const double a = lum(model.radiance(from_angles(elevation, azimuth)));
      const double b = lum(model.radiance(from_angles(elevation + 0.1, azimuth + 0.1)));
      worst = std::max(worst, std::fabs(a - b) / a);
    }
  EXPECT_LT(worst, 0.02);
}

TEST(SkyModel, ZenithLuminanceRisesWithSunElevation) {
  double previous = 0.0;
  for (double elevation = 0.0; elevation <= 90.0; elevation += 10.0) {
    const sl::data::PreethamSky model(sky(elevation, 0.0));
    EXPECT_GT(model.zenith_luminance(), previous) << elevation;
    previous = model.zenith_luminance();
    // The rendered zenith matches the model's zenith luminance.
    EXPECT_NEAR(lum(model.clear_sky_radiance({0, 1, 0})), model.zenith_luminance(), 0.05 * previous);
  }
}

TEST(SkyModel, AtEqualAngleFromTheSunTheHorizonIsBrighterThanTheZenith) {
  // Perez gradation term (1 + A·e^{B/cos θ}) with A < 0: a clear sky brightens towards the
  // horizon. Sun at 45°: the zenith and the horizon below the sun are both 45° away from it.
  const sl::data::PreethamSky model(sky(45.0, 0.0));
  EXPECT_GT(lum(model.radiance(from_angles(0.5, 0.0))), 1.5 * lum(model.radiance({0, 1, 0})));
  // High sun at 80°: (20°, towards the sun) and (40°, away from it) are both 60° from the sun;
  // the lower one is brighter.
  const sl::data::PreethamSky high(sky(80.0, 0.0));
  EXPECT_GT(lum(high.radiance(from_angles(20.0, 0.0))), 1.2 * lum(high.radiance(from_angles(40.0, 180.0))));
}

TEST(SkyModel, LowSunGivesARedderHorizonNearTheSun) {
  const sl::data::PreethamSky low(sky(2.0, 0.0)), high(sky(60.0, 0.0));
  const glm::dvec3 l = low.radiance(from_angles(3.0, 10.0)), h = high.radiance(from_angles(3.0, 10.0));
  EXPECT_GT(l.x / l.z, h.x / h.z);
  // A clear high-sun sky is blue at the zenith.
  const glm::dvec3 z = high.radiance({0, 1, 0});
  EXPECT_GT(z.z, z.x);
}

TEST(SkyModel, GroundIsAlbedoTimesIrradianceOverPi) {
  sl::data::SkyParams p = sky(35.0, 50.0);
  p.ground_albedo = 0.3;
  const sl::data::PreethamSky model(p);
  const sl::Tensor pano = model.render(128, 256);
  // Irradiance on the ground from the rendered upper hemisphere (sky + disk).
  glm::dvec3 e(0.0);
  for (int i = 0; i < 64; ++i)
    for (int j = 0; j < 256; ++j) {
      const auto d = sl::render::equirect::uv_to_direction(j + 0.5, i + 0.5, 256, 128);
      const double w = d.y * sl::render::equirect::pixel_solid_angle(i, 256, 128);
      for (int c = 0; c < 3; ++c) e[c] += pano.at({c, i, j}) * w;
    }
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(pano.at({c, 100, 10}), 0.3 * e[c] / sl::kPi, 0.02 * 0.3 * e[c] / sl::kPi);
  }
}

TEST(SkyModel, CloudsAreSeededAndDimTheSky) {
  sl::data::SkyParams p = sky(40.0, 0.0);
  p.cloud_cover = 0.9;
  p.cloud_seed = 5;
  const sl::data::PreethamSky cloudy(p), clear(sky(40.0, 0.0));
  const sl::Tensor a = cloudy.render(32, 64), b = cloudy.render(32, 64);
  EXPECT_EQ(a.to_vector(), b.to_vector());
  p.cloud_seed = 6;
  EXPECT_NE(sl::data::PreethamSky(p).render(32, 64).to_vector(), a.to_vector());
  EXPECT_LE(lum(cloudy.sun_radiance()), lum(clear.sun_radiance()));
  double covered = 0;
  for (double az = -180; az < 180; az += 5)
    for (double el = 10; el < 90; el += 5) covered += cloudy.cloud_cover_at(from_angles(el, az)) > 0.5;
  EXPECT_GT(covered, 0.3 * 72 * 16);
  EXPECT_LT(sl::data::radiant_power(a, 1), sl::data::radiant_power(clear.render(32, 64), 1));
}

TEST(SkyModel, SampledParametersAreDeterministicAndValid) {
  for (uint64_t i = 0; i < 50; ++i) {
    const sl::data::SkyParams a = sl::data::sample_sky_params(7, i), b = sl::data::sample_sky_params(7, i);
    EXPECT_EQ(a.sun_azimuth_rad, b.sun_azimuth_rad);
    EXPECT_EQ(a.cloud_seed, b.cloud_seed);
    EXPECT_NO_THROW(sl::data::PreethamSky{a});
  }
  EXPECT_NE(sl::data::sample_sky_params(7, 0).sun_azimuth_rad, sl::data::sample_sky_params(8, 0).sun_azimuth_rad);
  sl::data::SkyParams bad;
  bad.turbidity = 0.5;
  try {
    sl::data::PreethamSky{bad};
    FAIL();
  } catch (const sl::Error& e) {
    EXPECT_NE(std::string(e.what()).find("turbidity"), std::string::npos);
  }
  bad = {};
  bad.sun_elevation_rad = -0.1;
  EXPECT_THROW(sl::data::PreethamSky{bad}, sl::Error);
}

}  // namespace sl::test
