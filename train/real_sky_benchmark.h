// The real-sky benchmark (Table 1 on real panoramas): K seeded perspective crops of every
// panorama of one split of ../shared/data/hdri (configs/hdri_split.json), each with its true sun
// in the crop camera's canonical frame (street_batch.h), and the trivial baseline that every
// sun-direction figure is reported beside: the best CONSTANT direction, i.e. the normalised mean
// of the canonical sun directions of the TRAINING split's crops.
//
// Crops come from panorama_street_sample (data/panorama_sample.h) with rotation (always), a crop
// camera drawn from the given ranges, and no flip or colour/exposure jitter; crop k of a
// panorama uses stream k, so the set is a pure function of (files, K, seed). Only panoramas
// whose sun is hard (the same criterion as training) contribute sun errors; the others are
// listed with sun_known = false. sun_in_crop: the sun projects inside the crop's image.
// SunErrorStats: count, median and mean (degrees), and the share within 15°, 30° and 45°.
// Throws: sl::Error naming the panorama (unreadable, not 2:1).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "data/panorama_sample.h"

namespace sl::train {

struct RealSkyCrop {
  std::string panorama;  // file name
  data::StreetSample sample;  // one view: the crop (its camera at the panorama's centre)
  glm::dvec3 sun_canonical{0.0, 1.0, 0.0};
  bool sun_known = false, sun_in_crop = false;
};

data::PanoramaSampleOptions real_sky_crop_options(int width = 256, int height = 128);

std::vector<RealSkyCrop> real_sky_crops(const std::vector<std::string>& paths, int crops_per_panorama, uint64_t seed,
                                        const data::PanoramaSampleOptions& options = real_sky_crop_options());

// Normalised mean of sun_canonical over the crops with a known sun (+Y when there is none).
glm::dvec3 constant_baseline_direction(const std::vector<RealSkyCrop>& training_crops);

struct SunErrorStats {
  size_t count = 0;
  double median_deg = 0, mean_deg = 0, within_15 = 0, within_30 = 0, within_45 = 0;
};
SunErrorStats sun_error_stats(const std::vector<double>& errors_deg);

}  // namespace sl::train
