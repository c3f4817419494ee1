// The constant baseline that streetlight-eval scores beside every checkpoint: the best CONSTANT
// sun direction, the normalised mean of the training split's canonical sun directions, scored on
// the same samples as the checkpoints. A model that does not beat it has learned nothing.
//
// - street datasets: from the TRAIN split's samples whose sun is hard (meta.json alone);
// - real panorama folders: train/real_sky_benchmark.h's baseline (RealSkyFolder::baseline),
//   scored on the folder's crops, split like the checkpoints' rows (tools/common/eval_sun_stats.h).
// Throws: sl::Error naming the dataset when the evaluated split cannot be read.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

#include "train/real_sky_benchmark.h"

namespace sl::cli {

struct StreetBaseline {
  bool has = false;  // false when the train split is missing or holds no hard sun
  glm::dvec3 direction{0.0, 1.0, 0.0};
  std::string from;  // the dataset folder
  size_t samples = 0;
};
StreetBaseline street_baseline(const std::string& dir);

// The baseline row on a street dataset's evaluated split (its first `limit` samples when > 0).
nlohmann::json street_baseline_json(const StreetBaseline& b, const std::string& data, const std::string& split,
                                    int64_t limit);
// The baseline row on a real folder's crops.
nlohmann::json real_sky_baseline_json(const train::RealSkyFolder& r);

}  // namespace sl::cli
