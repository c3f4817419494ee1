// Does a sun estimate's confidence rank its errors? (issue 39: users who make augmented data skip
// the photos the model would light wrongly.) Given each labelled image's confidence measure (a
// spread in degrees: smaller is more confident, e.g. train/inference.h sun_flip_spread_deg), its
// sun error and its group (the real panorama its crop came from, or the street's id):
// - confidence_halves: the images sorted by spread (ties keep their order); the most confident
//   half is the floor(n/2) smallest spreads, the rest the uncertain half. Each half's median
//   error carries a 95% percentile-bootstrap interval that resamples whole groups
//   (train/bootstrap.h), so the eight crops of one sky do not count as eight skies.
//   valid = false with fewer than 2 images or when any spread is not finite (not measured).
// - pooled_median: the median of values gathered from several data sets (e.g. the "sun in crop"
//   rows of the real HDR and LDR test splits) with its grouped interval.
// Deterministic (the bootstrap's fixed seed).
// Throws: sl::Error when the three lists differ in length, or an error is not finite.
#pragma once
#include <string>
#include <vector>

#include "train/bootstrap.h"

namespace sl::train {

struct GroupedMedian {
  size_t count = 0;
  double median = 0.0;
  Interval ci;
};

struct ConfidenceHalves {
  bool valid = false;
  double spread_median = 0.0;
  GroupedMedian confident, uncertain;
  double confident_spread_max = 0.0, uncertain_spread_min = 0.0;
};

ConfidenceHalves confidence_halves(const std::vector<double>& spread, const std::vector<double>& error,
                                   const std::vector<std::string>& group);

GroupedMedian pooled_median(const std::vector<double>& values, const std::vector<std::string>& group);

}  // namespace sl::train
