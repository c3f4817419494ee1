// streetlight-bench visible-sun: the visible-sun cue (data/visible_sun.h) on the real-sky
// benchmark's crops of one split: how often it fires where the sun is in the crop, how far its
// ray is from the labelled sun, how often it fires where the sun is not, and for each missed sun
// which test its best clipped component failed. For choosing VisibleSunParams on the training and
// validation splits (never on test).
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <fstream>

#include <nlohmann/json.hpp>

#include "autodiff/ops.h"
#include "data/image_io.h"
#include "data/panorama.h"
#include "data/sun_labels.h"
#include "data/visible_sun.h"
#include "tools/bench/bench.h"
#include "tools/bench/ldr_panorama_radiance.h"
#include "tools/common/cli.h"
#include "train/metrics.h"
#include "train/real_sky_benchmark.h"
#include "util/error.h"
#include "util/math.h"
#include "util/random.h"

namespace sl::bench {
namespace {

// The tests a candidate fails, as a short list ("area", "compact", ...); "" when it passes.
std::string failed_tests(const data::VisibleSun& s, const data::VisibleSunParams& p, int64_t pixels) {
  std::string f;
  auto add = [&](const char* t) { f += (f.empty() ? "" : ",") + std::string(t); };
  if (s.area_px < p.min_area_fraction * pixels) add("small");
  if (s.area_px > p.max_area_fraction * pixels) add("large");
  if (s.compactness < p.min_compactness) add("compact");
  if (s.border_fraction > p.max_border_fraction) add("border");
  if (s.halo < p.min_halo) add("halo");
  if (s.falloff < p.min_falloff) add("falloff");
  if (s.elevation_deg < p.min_elevation_deg) add("elevation");
  return f;
}


// K crops of one labelled LDR panorama aimed so that its sun falls inside each: 256×128, a
// horizontal fov uniform in [50°, 80°], the sun at a uniform place in the middle 80% of the view
// (yaw and pitch follow), roll 0; resampled in linear radiance (codes^2.2) and re-encoded, as the
// benchmark's crops are. The panorama is read at 1024 wide (the benchmark's working width).
struct AimedCrop {
  Tensor ldr;
  render::Camera camera;
  glm::dvec3 sun;
};
std::vector<AimedCrop> aimed_crops(const std::string& path, const data::SunLabels& labels,
                                   const data::PanoramaSunLabel& label, int k_crops, uint64_t seed) {
  const Tensor pano = read_ldr_panorama_radiance(path);
  const glm::dvec3 d = labels.direction(label, int(pano.size(2)), int(pano.size(1)));
  const double az = std::atan2(d.x, -d.z), el = std::asin(std::clamp(d.y, -1.0, 1.0));
  std::vector<AimedCrop> out;
  for (int k = 0; k < k_crops; ++k) {
    data::PerspectiveCropParams cp;
    cp.horizontal_fov_rad = (50.0 + 30.0 * uniform01(seed, uint64_t(k), 0)) * kDegToRad;
    const double half_h = 0.5 * cp.horizontal_fov_rad;
    const double half_v = std::atan(std::tan(half_h) * cp.height / cp.width);
    cp.yaw_rad = az + 0.8 * half_h * (2.0 * uniform01(seed, uint64_t(k), 1) - 1.0);
    cp.pitch_rad = std::clamp(el + 0.8 * half_v * (2.0 * uniform01(seed, uint64_t(k), 2) - 1.0), -1.2, 1.2);
    const data::PerspectiveCrop crop = data::crop_perspective(pano, cp);
    const render::Projection pr = crop.camera.project(crop.camera.position() + 1e3 * d);
    if (!pr.in_image) continue;
    out.push_back({data::to_ldr(crop.image, 1.0).contiguous(), crop.camera, d});
  }
  return out;
}

int run_visible_sun(const std::vector<std::string>& args) {
  std::string data_dir, split_file, split = "val", misses;
  int64_t crops = 8, aimed = 0;
  data::VisibleSunParams p;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    auto value = [&]() -> std::string {
      SL_CHECK(i + 1 < args.size(), "visible-sun: ", a, " needs a value");
      return args[++i];
    };
    auto number = [&]() {
      const std::string v = value();
      char* end = nullptr;
      const double x = std::strtod(v.c_str(), &end);
      SL_CHECK(end && *end == '\0' && std::isfinite(x), "visible-sun: ", a, " must be a number, got '", v, "'");
      return x;
    };
    if (a == "--help" || a == "-h") {
      std::printf(
          "usage: streetlight-bench visible-sun --data DIR [--split-file FILE] [--split train|val] [--crops K]\n"
          "                                    [--saturation X] [--min-area X] [--max-area X] [--min-compactness X]\n"
          "                                    [--min-halo X] [--min-falloff X] [--misses OUT] [--aimed K]\n\n"
          "The visible-sun cue (data/visible_sun.h) on the real-sky benchmark's crops of one split of DIR (HDR skies\n"
          "or labelled LDR panoramas, as streetlight-eval --data; K crops per panorama, default 8): one line per crop\n"
          "whose sun is in the view (fired or missed, the angle to the labelled sun, the best clipped component's\n"
          "measurements and the tests it failed), one line per false fire, then the counts: suns in view, fired within 5 degrees, fired\n"
          "farther, and false fires where the sun is outside the view. The flags set VisibleSunParams (defaults\n"
          "%.2f, %.4f, %.2f, %.2f, %.2f, %.2f). --split test is refused: thresholds are chosen on train and val.\n"
          "--misses OUT writes each missed crop as OUT/<n>_<panorama>.png. --aimed K (labelled LDR panoramas): instead\n"
          "of the benchmark's crops, K crops of every panorama with a sun position, aimed so that the sun is in view.\n",
          p.saturation, p.min_area_fraction, p.max_area_fraction, p.min_compactness, p.min_halo, p.min_falloff);
      return 0;
    }
    if (a == "--data") data_dir = value();
    else if (a == "--split-file") split_file = value();
    else if (a == "--split") split = value();
    else if (a == "--crops") crops = cli::parse_integer("visible-sun: --crops", value(), 1, 1024);
    else if (a == "--saturation") p.saturation = number();
    else if (a == "--min-area") p.min_area_fraction = number();
    else if (a == "--max-area") p.max_area_fraction = number();
    else if (a == "--min-compactness") p.min_compactness = number();
    else if (a == "--min-halo") p.min_halo = number();
    else if (a == "--min-falloff") p.min_falloff = number();
    else if (a == "--misses") misses = value();
    else if (a == "--aimed") aimed = cli::parse_integer("visible-sun: --aimed", value(), 1, 1024);
    else SL_CHECK(false, "visible-sun: unknown option '", a, "' (try --help)");
  }
  SL_CHECK(!data_dir.empty(), "visible-sun: --data DIR is required");
  SL_CHECK(split == "train" || split == "val", "visible-sun: --split must be train or val, got '", split,
           "' (thresholds are never chosen on test)");
  if (!misses.empty()) std::filesystem::create_directories(misses);
  // The crops to score: the benchmark's (as streetlight-eval draws them) or, with --aimed, crops
  // aimed at each labelled sun.
  struct Item {
    Tensor ldr;
    render::Camera camera;
    glm::dvec3 sun;
    bool in_crop;
    std::string panorama, label;
  };
  std::vector<Item> items;
  const bool ldr = train::is_ldr_panorama_folder(data_dir);
  const std::string labels_file = (std::filesystem::path(data_dir) / "sun_labels.csv").string();
  if (aimed > 0) {
    SL_CHECK(ldr, "visible-sun: --aimed needs labelled LDR panoramas (", data_dir, " has no sun_labels.csv)");
    SL_CHECK(!split_file.empty(), "visible-sun: --aimed needs --split-file");
    std::ifstream in(split_file);
    SL_CHECK(in.good(), "visible-sun: cannot read --split-file '", split_file, "'");
    const nlohmann::json sj = nlohmann::json::parse(in, nullptr, false);
    SL_CHECK(!sj.is_discarded() && sj.contains(split) && sj[split].is_array(), "visible-sun: '", split_file,
             "' has no list '", split, "'");
    const data::SunLabels labels = data::read_sun_labels(labels_file);
    for (const auto& name : sj[split]) {
      const data::PanoramaSunLabel* l = labels.find(name.get<std::string>());
      if (!l || !l->has_position || l->sun != data::SunVisibility::Visible) continue;
      for (AimedCrop& c : aimed_crops((std::filesystem::path(data_dir) / name.get<std::string>()).string(), labels, *l,
                                      int(aimed), hash_counter(0x61696d6564ULL, std::hash<std::string>{}(name))))
        items.push_back({c.ldr, c.camera, c.sun, true, name.get<std::string>(), data::to_string(l->confidence)});
    }
  } else {
    const train::RealSkyFolder f =
        ldr ? train::load_ldr_panorama_folder(data_dir, labels_file, split_file, split, int(crops))
            : train::load_hdr_sky_folder(data_dir, split_file, split, int(crops));
    for (const train::RealSkyCrop& c : f.test) {
      if (!c.sun_known || c.sample.views.empty()) continue;
      const data::StreetView& v = c.sample.views[0];
      // The view's camera and the sample's sun share the sample's world frame.
      items.push_back({v.ldr, v.camera, c.sample.sun_direction, c.sun_in_crop, c.panorama,
                       c.label_sun + " " + c.label_confidence});
    }
  }
  int in_crop = 0, hit = 0, wrong_hit = 0, outside = 0, false_fire = 0;
  for (const Item& c : items) {
    const data::VisibleSun s = data::find_visible_sun(c.ldr, c.camera, p);
    const double err = s.found ? train::angular_error_deg(s.direction, c.sun) : 180.0;
    if (c.in_crop) {
      ++in_crop;
      if (s.found) {
        hit += err <= 5.0;
        wrong_hit += err > 5.0;
      }
      const int64_t pixels = c.ldr.size(1) * c.ldr.size(2);
      std::printf("%-6s %-60s err %6.1f  best: area %5d compact %.2f border %.2f halo %.2f falloff %.2f el %5.1f  %s  (%s)\n",
                  s.found ? "FIRED" : "missed", c.panorama.substr(0, 60).c_str(), err, s.area_px, s.compactness,
                  s.border_fraction, s.halo, s.falloff, s.elevation_deg,
                  s.candidate_count == 0 ? "no-clipped-pixels" : failed_tests(s, p, pixels).c_str(), c.label.c_str());
      if (!s.found && !misses.empty()) {
        const std::string name = std::to_string(in_crop) + "_" + std::filesystem::path(c.panorama).stem().string() + ".png";
        data::write_image((std::filesystem::path(misses) / name).string(), c.ldr);
      }
    } else {
      ++outside;
      false_fire += s.found;
      if (s.found)
        std::printf("false  %-60s err %6.1f  area %5d compact %.2f halo %.2f falloff %.2f el %5.1f  (%s)\n",
                    c.panorama.substr(0, 60).c_str(), err, s.area_px, s.compactness, s.halo, s.falloff, s.elevation_deg,
                    c.label.c_str());
    }
  }
  std::printf("%s split %s, %d %s crops/panorama: sun in crop %d, fired %d (%d within 5 deg, %d farther); sun outside "
              "%d, fired %d\n",
              data_dir.c_str(), split.c_str(), int(aimed > 0 ? aimed : crops), aimed > 0 ? "aimed" : "benchmark", in_crop,
              hit + wrong_hit, hit, wrong_hit, outside, false_fire);
  return 0;
}

const Registrar reg("visible-sun", "the visible-sun cue on the real-sky benchmark's crops: hits, misses, false fires",
                    &run_visible_sun);

}  // namespace
}  // namespace sl::bench
