// train/sun_error_parts.h: the azimuth, elevation and front/back parts of a sun error, on suns
// placed by (azimuth, elevation) in the canonical frame (the view looks down −Z).
#include "train/sun_error_parts.h"

#include <gtest/gtest.h>

#include <cmath>

#include "util/error.h"

namespace sl::test {
namespace {

glm::dvec3 sun(double azimuth_deg, double elevation_deg) {
  const double a = azimuth_deg * M_PI / 180.0, e = elevation_deg * M_PI / 180.0;
  return {std::cos(e) * std::sin(a), std::sin(e), -std::cos(e) * std::cos(a)};
}

TEST(SunErrorParts, ExactSunsHaveNoPartsOfError) {
  const train::SunErrorParts p = train::sun_error_parts({sun(30, 20), sun(-150, 60)}, {sun(30, 20), sun(-150, 60)});
  EXPECT_EQ(p.count, 2u);
  EXPECT_EQ(p.azimuth_count, 2u);
  EXPECT_NEAR(p.azimuth_error_median_deg, 0.0, 1e-9);
  EXPECT_NEAR(p.elevation_bias_median_deg, 0.0, 1e-9);
  EXPECT_EQ(p.truth_front, 1u);
  EXPECT_EQ(p.truth_back, 1u);
  EXPECT_EQ(p.front_back_wrong(), 0u);
}

// A sun mirrored front to back keeps its elevation; a sun lifted keeps its azimuth; azimuth
// differences wrap (170° and −170° are 20° apart); medians are of all pairs.
TEST(SunErrorParts, SeparatesAzimuthElevationAndTheHalf) {
  const std::vector<glm::dvec3> truth = {sun(30, 20), sun(10, 10), sun(170, 40)};
  const std::vector<glm::dvec3> predicted = {sun(150, 20), sun(10, 60), sun(-170, 40)};
  const train::SunErrorParts p = train::sun_error_parts(predicted, truth);
  EXPECT_NEAR(p.azimuth_error_median_deg, 20.0, 1e-9);  // of {120, 0, 20}
  EXPECT_NEAR(p.elevation_bias_median_deg, 0.0, 1e-9);  // of {0, +50, 0}
  EXPECT_NEAR(p.true_elevation_median_deg, 20.0, 1e-9);
  EXPECT_NEAR(p.predicted_elevation_median_deg, 40.0, 1e-9);
  EXPECT_EQ(p.truth_front, 2u);
  EXPECT_EQ(p.truth_front_predicted_back, 1u);  // 30° mirrored to 150°
  EXPECT_EQ(p.truth_back, 1u);
  EXPECT_EQ(p.truth_back_predicted_front, 0u);
  EXPECT_EQ(p.front_back_wrong(), 1u);
}

// Near the zenith the azimuth is left out (but the elevation and the half still count); an even
// count takes the mean of the middle two; no pairs give NaN medians.
TEST(SunErrorParts, LeavesZenithSunsOutOfTheAzimuth) {
  const train::SunErrorParts p =
      train::sun_error_parts({sun(100, 88), sun(40, 30), sun(0, 30)}, {sun(0, 30), sun(0, 30), sun(0, 30)});
  EXPECT_EQ(p.azimuth_count, 2u);
  EXPECT_NEAR(p.azimuth_error_median_deg, 20.0, 1e-9);  // of {40, 0}
  EXPECT_NEAR(p.elevation_bias_median_deg, 0.0, 1e-9);  // of {58, 0, 0}
  EXPECT_EQ(p.truth_front_predicted_back, 1u);          // the zenith sun leans behind the view
  const train::SunErrorParts none = train::sun_error_parts({}, {});
  EXPECT_EQ(none.count, 0u);
  EXPECT_TRUE(std::isnan(none.azimuth_error_median_deg));
  EXPECT_TRUE(std::isnan(none.elevation_bias_median_deg));
}

TEST(SunErrorParts, RefusesMismatchedOrDegenerateInput) {
  EXPECT_THROW(train::sun_error_parts({sun(0, 10)}, {}), Error);
  EXPECT_THROW(train::sun_error_parts({glm::dvec3(0.0)}, {sun(0, 10)}), Error);
  EXPECT_THROW(train::sun_error_parts({sun(0, 10)}, {glm::dvec3(NAN, 0, 0)}), Error);
}

}  // namespace
}  // namespace sl::test
