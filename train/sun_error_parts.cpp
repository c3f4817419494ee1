#include "train/sun_error_parts.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "train/metrics.h"
#include "util/error.h"
#include "util/math.h"

namespace sl::train {
namespace {

// The median of the pairs counted, NaN when there are none (train/metrics.h's median gives 0).
double median_or_nan(std::vector<double> v) {
  return v.empty() ? std::numeric_limits<double>::quiet_NaN() : median(std::move(v));
}

struct Angles {
  double azimuth_deg, elevation_deg;
  bool front;
};

Angles angles(const glm::dvec3& d, const char* which, size_t i) {
  const double len = glm::length(d);
  SL_CHECK(std::isfinite(len) && len > 0.0, "sun_error_parts: ", which, " direction ", i, " is zero or not finite");
  const glm::dvec3 u = d / len;
  return {degrees(std::atan2(u.x, -u.z)), degrees(std::asin(std::clamp(u.y, -1.0, 1.0))), -u.z > 0.0};
}

}  // namespace

SunErrorParts sun_error_parts(const std::vector<glm::dvec3>& predicted, const std::vector<glm::dvec3>& truth) {
  SL_CHECK(predicted.size() == truth.size(), "sun_error_parts: ", predicted.size(), " predicted directions for ",
           truth.size(), " true ones");
  SunErrorParts p;
  p.count = truth.size();
  std::vector<double> azimuth, bias, true_el, predicted_el;
  for (size_t i = 0; i < truth.size(); ++i) {
    const Angles a = angles(predicted[i], "predicted", i), t = angles(truth[i], "true", i);
    bias.push_back(a.elevation_deg - t.elevation_deg);
    true_el.push_back(t.elevation_deg);
    predicted_el.push_back(a.elevation_deg);
    if (a.elevation_deg < kAzimuthMaxElevationDeg && t.elevation_deg < kAzimuthMaxElevationDeg) {
      const double d = std::fabs(std::remainder(a.azimuth_deg - t.azimuth_deg, 360.0));
      azimuth.push_back(d);
    }
    if (t.front) {
      ++p.truth_front;
      p.truth_front_predicted_back += !a.front;
    } else {
      ++p.truth_back;
      p.truth_back_predicted_front += a.front;
    }
  }
  p.azimuth_count = azimuth.size();
  p.azimuth_error_median_deg = median_or_nan(std::move(azimuth));
  p.elevation_bias_median_deg = median_or_nan(std::move(bias));
  p.true_elevation_median_deg = median_or_nan(std::move(true_el));
  p.predicted_elevation_median_deg = median_or_nan(std::move(predicted_el));
  return p;
}

}  // namespace sl::train
