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
//
// LDR panoramas (ldr_panorama_crops; ../shared/data/pano_ldr, 8-bit sRGB-encoded JPEGs whose sun
// is hand-labelled in sun_labels.csv, data/sun_labels.h): the panorama area-resized to
// ldr_working_width × width/2 (the HDR skies' 1024 × 512, so a crop's pixels are as sharp), then
// crop k is data/ldr_panorama_sample.h's sample (seed, k) without flip or jitter: the azimuth
// shift and crop stream of draw_panorama_sample, the crop resampled in linear radiance codes^2.2
// and re-encoded, the true sun from the label rotated with the panorama. The image is the 8-bit
// codes / 255 (Transfer::Linear): the estimator's input is "an 8-bit photo read without an sRGB
// curve" (train/inference.h), as streetlight-insert reads a photo, and it is not re-exposed (a
// photo is scored at the exposure its camera chose); exposure is 1.
// Panoramas labelled none, or occluded without a position, give no crops and are listed in
// not_scored; each crop carries its label's class, confidence and scene.
// Throws: sl::Error naming the panorama (unreadable, not 2:1) or, for a panorama without a label,
// the panorama and the labels file.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "data/panorama_sample.h"
#include "data/sun_labels.h"

namespace sl::train {

struct RealSkyCrop {
  std::string panorama;  // file name
  data::StreetSample sample;  // one view: the crop (its camera at the panorama's centre)
  glm::dvec3 sun_canonical{0.0, 1.0, 0.0};
  bool sun_known = false, sun_in_crop = false;
  // LDR panoramas only: the label's sun class, confidence and scene (data/sun_labels.h names).
  std::string label_sun, label_confidence, scene;
};

data::PanoramaSampleOptions real_sky_crop_options(int width = 256, int height = 128);

std::vector<RealSkyCrop> real_sky_crops(const std::vector<std::string>& paths, int crops_per_panorama, uint64_t seed,
                                        const data::PanoramaSampleOptions& options = real_sky_crop_options());

struct LdrPanoramaCrops {
  std::vector<RealSkyCrop> crops;  // K per scored panorama, panoramas in sorted path order
  std::vector<const data::PanoramaSunLabel*> scored, not_scored;  // into the labels given
};
inline constexpr int kLdrWorkingWidth = 1024;
// keep_images = false drops each crop's images once its camera and sun are known (enough for the
// constant baseline).
LdrPanoramaCrops ldr_panorama_crops(const std::vector<std::string>& paths, const data::SunLabels& labels,
                                    int crops_per_panorama, uint64_t seed,
                                    const data::PanoramaSampleOptions& options = real_sky_crop_options(),
                                    bool keep_images = true, int ldr_working_width = kLdrWorkingWidth);

// Normalised mean of sun_canonical over the crops with a known sun (+Y when there is none).
glm::dvec3 constant_baseline_direction(const std::vector<RealSkyCrop>& training_crops);

// A benchmark folder as streetlight-eval scores it, at the benchmark's fixed seed kRealSkySeed:
// the K crops of every panorama of `split` of split_file (of every panorama when split_file is
// empty; the first `limit` when limit > 0) and, when the split file has a "train" list, the
// constant baseline from that list's crops (has_baseline; baseline_from names its panoramas).
// - load_hdr_sky_folder: HDR panoramas (data/hdri_folder.h), real_sky_crops.
// - load_ldr_panorama_folder: labelled LDR panoramas, ldr_panorama_crops with the labels file
//   (sun_labels.csv format); without a split file, every .jpg/.jpeg/.png of the folder. The test
//   panoramas scored, those not scored (no sun position) and the scored ones whose label has low
//   confidence are listed.
// - is_ldr_panorama_folder: the folder has a sun_labels.csv, or holds 8-bit images and no HDR ones.
// Throws: sl::Error naming the folder (no images, no labels file) or, as the crops do, the panorama.
inline constexpr uint64_t kRealSkySeed = 0x7265616c736b79ULL;  // one fixed set of crops for every run

struct RealSkyFolder {
  std::vector<RealSkyCrop> test;
  bool has_baseline = false;
  glm::dvec3 baseline{0.0, 1.0, 0.0};
  std::vector<std::string> baseline_from;  // training panoramas (file names)
  bool ldr = false;
  std::string labels;  // LDR: the labels file
  std::vector<std::string> scored, low_confidence;
  std::vector<data::PanoramaSunLabel> not_scored;
};

RealSkyFolder load_hdr_sky_folder(const std::string& folder, const std::string& split_file, const std::string& split,
                                  int crops_per_panorama, int64_t limit = 0);
RealSkyFolder load_ldr_panorama_folder(const std::string& folder, const std::string& labels_file,
                                       const std::string& split_file, const std::string& split, int crops_per_panorama,
                                       int64_t limit = 0);
bool is_ldr_panorama_folder(const std::string& dir);

struct SunErrorStats {
  size_t count = 0;
  double median_deg = 0, mean_deg = 0, within_15 = 0, within_30 = 0, within_45 = 0;
};
SunErrorStats sun_error_stats(const std::vector<double>& errors_deg);

}  // namespace sl::train
