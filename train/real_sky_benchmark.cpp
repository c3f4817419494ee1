// The real-sky benchmark. See real_sky_benchmark.h.
#include "train/real_sky_benchmark.h"

#include <filesystem>

#include "data/hdri_folder.h"
#include "train/metrics.h"
#include "train/street_batch.h"

using sl::data::HdriFolder;
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
      c.sample = panorama_street_sample(pano, "hdri:" + name + "#" + std::to_string(k), seed, static_cast<uint64_t>(k),
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

}  // namespace sl::train
