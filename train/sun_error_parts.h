// A sun error taken apart (issue 39: where does a real-sky error come from?). Given predicted and
// true sun directions in the input camera's canonical frame (train/street_batch.h: the view looks
// down −Z, +Y up), with azimuth φ = atan2(x, −z) and elevation θ = asin(y) (render/equirect.h):
// - azimuth_error: |φ_predicted − φ_true| wrapped to [0°, 180°], over the pairs whose suns are
//   both below kAzimuthMaxElevationDeg (near the zenith the azimuth means nothing);
// - elevation_bias: θ_predicted − θ_true (positive: the predicted sun is too high);
// - front/back: a sun is in front when it lies in the half-space the view looks into (−z > 0).
//   The counts say how often the predicted sun is in the other half than the true one, split by
//   where the true sun is. A model that cannot tell the two halves apart fails here however good
//   its elevation.
// Medians are of the pairs counted (NaN when there are none). Directions need not be unit length.
// Deterministic; no allocation beyond the inputs' size.
// Throws: sl::Error when the two lists differ in length, or a direction is zero or not finite.
#pragma once
#include <cstddef>
#include <vector>

#include <glm/glm.hpp>

namespace sl::train {

inline constexpr double kAzimuthMaxElevationDeg = 85.0;

struct SunErrorParts {
  size_t count = 0;          // pairs
  size_t azimuth_count = 0;  // pairs with both suns below kAzimuthMaxElevationDeg
  double azimuth_error_median_deg = 0.0, elevation_bias_median_deg = 0.0;
  double true_elevation_median_deg = 0.0, predicted_elevation_median_deg = 0.0;
  size_t truth_front = 0, truth_front_predicted_back = 0;
  size_t truth_back = 0, truth_back_predicted_front = 0;
  size_t front_back_wrong() const { return truth_front_predicted_back + truth_back_predicted_front; }
};

SunErrorParts sun_error_parts(const std::vector<glm::dvec3>& predicted, const std::vector<glm::dvec3>& truth);

}  // namespace sl::train
