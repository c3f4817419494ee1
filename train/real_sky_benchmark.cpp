// The real-sky benchmark. See real_sky_benchmark.h.
#include "train/real_sky_benchmark.h"

#include <algorithm>
#include <filesystem>

#include "autodiff/ops.h"
#include "data/augment.h"
#include "data/hdri_folder.h"
#include "data/hdri_split.h"
#include "data/image_io.h"
#include "data/ldr_panorama_sample.h"
#include "data/panorama.h"
#include "train/metrics.h"
#include "train/sample_source.h"
#include "train/street_batch.h"
#include "util/error.h"
#include "util/file_kind.h"

using sl::data::HdriFolder;
using sl::data::ImageReadOptions;
using sl::data::read_image;
using sl::data::resize_area;
using sl::data::rotate_azimuth;
using sl::data::rotate_direction_azimuth;
using sl::data::StreetSample;
using sl::data::StreetView;
using sl::data::Transfer;
using sl::data::panorama_street_sample;
using sl::data::PanoramaSampleOptions;
using sl::data::sanitized_panorama;
using sl::render::Camera;
using sl::render::Projection;

namespace sl::train {

PanoramaSampleOptions real_sky_crop_options(int width, int height) {
  PanoramaSampleOptions o;
  o.crop.width = width;
  o.crop.height = height;
  o.flip = false;
  o.white_balance_stops = 0.0;
  o.exposure_stops = 0.0;
  return o;
}

std::vector<RealSkyCrop> real_sky_crops(const std::vector<std::string>& paths, int crops_per_panorama, uint64_t seed,
                                        const PanoramaSampleOptions& options) {
  SL_CHECK(crops_per_panorama > 0, "real-sky benchmark: crops per panorama must be positive, got ", crops_per_panorama);
  std::vector<RealSkyCrop> out;
  if (paths.empty()) return out;
  const HdriFolder folder(paths);
  for (size_t i = 0; i < folder.size(); ++i) {
    const std::string name = std::filesystem::path(folder.path(i)).filename().string();
    const Tensor pano = sanitized_panorama(folder.load(i), folder.path(i));
    for (int k = 0; k < crops_per_panorama; ++k) {
      RealSkyCrop c;
      c.panorama = name;
      c.sample = panorama_street_sample(pano, crop_sample_id(SampleOrigin::HdrCrop, name, static_cast<uint64_t>(k)), seed, static_cast<uint64_t>(k),
                                        options);
      const Camera& cam = c.sample.views[0].camera;
      c.sun_canonical = canonical_frame(cam).direction(c.sample.sun_direction);
      c.sun_known = c.sample.sun_known;
      const Projection p = cam.project(cam.position() + 1e3 * c.sample.sun_direction);
      c.sun_in_crop = p.in_image;
      out.push_back(std::move(c));
    }
  }
  return out;
}

LdrPanoramaCrops ldr_panorama_crops(const std::vector<std::string>& paths, const data::SunLabels& labels,
                                    int crops_per_panorama, uint64_t seed, const PanoramaSampleOptions& options,
                                    bool keep_images, int working_width) {
  SL_CHECK(crops_per_panorama > 0, "real-sky benchmark: crops per panorama must be positive, got ", crops_per_panorama);
  SL_CHECK(working_width >= 2 && working_width % 2 == 0, "real-sky benchmark: LDR working width must be even, got ",
           working_width);
  LdrPanoramaCrops out;
  std::vector<std::string> sorted = paths;
  std::sort(sorted.begin(), sorted.end());
  const glm::dvec3 centre(0.0, options.camera_height_m, 0.0);
  for (const std::string& path : sorted) {
    const std::string name = std::filesystem::path(path).filename().string();
    const data::PanoramaSunLabel* label = labels.find(name);
    SL_CHECK(label != nullptr, "LDR panorama '", path, "' has no row in the sun labels '", labels.path, "'");
    if (!label->has_position) {
      out.not_scored.push_back(label);
      continue;
    }
    out.scored.push_back(label);
    ImageReadOptions ro;
    ro.transfer = Transfer::Linear;  // codes / 255: the estimator's LDR (see the header)
    ro.channels = 3;
    const Tensor full = read_image(path, ro);
    SL_CHECK(full.size(2) == 2 * full.size(1), "LDR panorama '", path, "' is ", full.size(2), "x", full.size(1),
             "; an equirectangular panorama is 2:1 (width = 2 x height)");
    const int fw = static_cast<int>(full.size(2)), fh = static_cast<int>(full.size(1));
    data::LdrPanorama pano;
    pano.ldr = resize_area(full, working_width / 2, working_width).contiguous();
    pano.sun_known = true;
    pano.sun_direction = labels.direction(*label, fw, fh);
    for (int k = 0; k < crops_per_panorama; ++k) {
      RealSkyCrop c;
      c.panorama = name;
      c.label_sun = data::to_string(label->sun);
      c.label_confidence = data::to_string(label->confidence);
      c.scene = data::to_string(label->scene);
      c.sample = data::ldr_panorama_street_sample(pano, crop_sample_id(SampleOrigin::LdrCrop, name, static_cast<uint64_t>(k)), seed,
                                                  static_cast<uint64_t>(k), options, keep_images);
      const StreetSample& s = c.sample;
      const Camera& cam = s.views[0].camera;
      c.sun_canonical = canonical_frame(cam).direction(s.sun_direction);
      c.sun_known = true;
      c.sun_in_crop = cam.project(cam.position() + 1e3 * s.sun_direction).in_image;
      out.crops.push_back(std::move(c));
    }
  }
  return out;
}

glm::dvec3 constant_baseline_direction(const std::vector<RealSkyCrop>& crops) {
  glm::dvec3 sum(0.0);
  for (const auto& c : crops)
    if (c.sun_known) sum += c.sun_canonical;
  const double len = glm::length(sum);
  return len > 1e-12 ? sum / len : glm::dvec3(0.0, 1.0, 0.0);
}

SunErrorStats sun_error_stats(const std::vector<double>& e) {
  SunErrorStats s;
  s.count = e.size();
  if (e.empty()) return s;
  s.median_deg = median(e);
  s.mean_deg = mean_of(e);
  for (double v : e) {
    s.within_15 += v <= 15.0;
    s.within_30 += v <= 30.0;
    s.within_45 += v <= 45.0;
  }
  const double n = static_cast<double>(e.size());
  s.within_15 /= n, s.within_30 /= n, s.within_45 /= n;
  return s;
}

namespace {
void keep_first(std::vector<std::string>& paths, int64_t limit) {
  if (limit > 0 && static_cast<size_t>(limit) < paths.size()) paths.resize(static_cast<size_t>(limit));
}
std::string file_name(const std::string& path) { return std::filesystem::path(path).filename().string(); }
}  // namespace

RealSkyFolder load_hdr_sky_folder(const std::string& folder, const std::string& split_file, const std::string& split,
                                  int crops_per_panorama, int64_t limit) {
  RealSkyFolder r;
  std::vector<std::string> test_paths;
  if (split_file.empty()) {
    test_paths = data::HdriFolder(folder).paths();
  } else {
    const data::HdriSplit hs = data::read_hdri_split(split_file);
    test_paths = hs.split_paths(folder, split);
    if (hs.has("train")) {
      const auto train_paths = hs.split_paths(folder, "train");
      r.baseline = constant_baseline_direction(real_sky_crops(train_paths, crops_per_panorama, kRealSkySeed));
      r.has_baseline = true;
      for (const auto& p : train_paths) r.baseline_from.push_back(file_name(p));
    }
  }
  keep_first(test_paths, limit);
  r.test = real_sky_crops(test_paths, crops_per_panorama, kRealSkySeed);
  return r;
}

RealSkyFolder load_ldr_panorama_folder(const std::string& folder, const std::string& labels_file,
                                       const std::string& split_file, const std::string& split, int crops_per_panorama,
                                       int64_t limit) {
  SL_CHECK(std::filesystem::exists(labels_file), "LDR panorama folder '", folder, "': no sun labels '", labels_file,
           "' (give --sun-labels FILE)");
  const data::SunLabels labels = data::read_sun_labels(labels_file);
  RealSkyFolder r;
  r.ldr = true;
  r.labels = labels_file;
  std::vector<std::string> test_paths;
  if (split_file.empty()) {
    test_paths = files_with_extension(folder, {".jpg", ".jpeg", ".png"});
    SL_CHECK(!test_paths.empty(), "LDR panorama folder '", folder, "' holds no .jpg, .jpeg or .png files");
  } else {
    const data::HdriSplit hs = data::read_hdri_split(split_file);
    test_paths = hs.split_paths(folder, split);
    if (hs.has("train")) {
      // Only the crops' cameras and label suns are needed: the images are dropped at once.
      const LdrPanoramaCrops train = ldr_panorama_crops(hs.split_paths(folder, "train"), labels, crops_per_panorama,
                                                        kRealSkySeed, real_sky_crop_options(), false);
      r.baseline = constant_baseline_direction(train.crops);
      r.has_baseline = !train.scored.empty();
      for (const auto* l : train.scored) r.baseline_from.push_back(l->file);
    }
  }
  keep_first(test_paths, limit);
  LdrPanoramaCrops test = ldr_panorama_crops(test_paths, labels, crops_per_panorama, kRealSkySeed);
  r.test = std::move(test.crops);
  for (const auto* l : test.scored) {
    r.scored.push_back(l->file);
    if (l->confidence == data::LabelConfidence::Low) r.low_confidence.push_back(l->file);
  }
  for (const auto* l : test.not_scored) r.not_scored.push_back(*l);
  return r;
}

bool is_ldr_panorama_folder(const std::string& dir) {
  namespace fs = std::filesystem;
  if (fs::exists(fs::path(dir) / "sun_labels.csv")) return true;
  bool ldr = false;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    if (!e.is_regular_file(ec)) continue;
    if (has_extension(e.path().string(), {".hdr", ".exr"})) return false;
    ldr = ldr || has_extension(e.path().string(), {".jpg", ".jpeg", ".png"});
  }
  return ldr;
}

}  // namespace sl::train
