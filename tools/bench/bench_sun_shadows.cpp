// streetlight-bench sun-from-shadows: how well the photo's own cast shadows give the sun
// (data/sun_from_shadows.h), on generated streets whose true sun is known, and its time.
//
// For every sample of the split whose sun is a usable label, view 0's LDR, depth and camera go
// to fit_sun_from_shadows(); the angular error is against the sample's sun_direction. Rows: the
// crops where the fit is confident (found), all crops (the best guess even when not found), and
// the coverage (found / all). One JSON object per sample with --json, then a summary object.
#include <unistd.h>

#include <algorithm>
#include <memory>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "data/image_io.h"
#include "data/street_dataset.h"
#include "data/sun_from_shadows.h"
#include "tools/bench/bench.h"
#include "tools/bench/kitti_frame.h"
#include "train/inference.h"
#include "train/photo_input.h"
#include "util/error.h"
#include "util/math.h"

namespace sl::bench {
namespace {

double angle_deg(const glm::dvec3& a, const glm::dvec3& b) {
  const double c = glm::dot(glm::normalize(a), glm::normalize(b));
  return std::acos(std::clamp(c, -1.0, 1.0)) * 180.0 / kPi;
}

double median_of(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double share_within(const std::vector<double>& v, double limit) {
  if (v.empty()) return NAN;
  return double(std::count_if(v.begin(), v.end(), [&](double e) { return e <= limit; })) / double(v.size());
}

// The view with the shadow test of one direction laid over it: blocked ground red, lit ground green.
void write_overlay(const std::string& path, const data::StreetView& v, const glm::dvec3& sun,
                   const data::ShadowSunOptions& options) {
  if (path.empty()) return;
  const Tensor mask = data::shadow_sun_mask(v.ldr, v.depth, v.camera, sun, options);
  Tensor out = v.ldr.to(DType::F32).contiguous().clone();
  const int64_t plane = out.size(1) * out.size(2);
  float* o = out.data<float>();
  const float* m = mask.data<float>();
  for (int64_t i = 0; i < plane; ++i) {
    if (m[i] == 0.0f) continue;
    const int c = m[i] == 1.0f ? 0 : 1;
    o[c * plane + i] = 0.5f * o[c * plane + i] + 0.5f;
  }
  data::write_image(path, out);
}

int run_sun_from_shadows(const std::vector<std::string>& args) {
  std::string dir, split = "test", debug_dir, kitti, checkpoint;
  int64_t limit = 0;
  bool json = false, landscape = false;
  data::ShadowSunOptions options;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    auto value = [&]() -> std::string {
      SL_CHECK(i + 1 < args.size(), "sun-from-shadows: ", a, " needs a value");
      return args[++i];
    };
    if (a == "--help" || a == "-h") {
      std::printf(
          "usage: streetlight-bench sun-from-shadows (--data DIR [--split NAME] [--limit N] [--checkpoint CKPT] | --kitti DIR [--landscape])\n"
          "                                         [--min-score R]\n"
          "                                         [--debug-dir OUT] [--json]\n\n"
          "Sun direction from the photo's own cast shadows and its depth (data/sun_from_shadows.h), on the\n"
          "generated streets in DIR (streetlight-datagen output; split NAME of its index.json, default test).\n"
          "Prints the median angular error against each sample's true sun, for the confident fits and for all,\n"
          "the share within 15/30/45 degrees, the coverage, and the time per image. --min-score sets the\n"
          "confidence threshold (default %.2f); --limit N stops after N samples. --checkpoint CKPT adds the rows of\n"
          "that lighting model's own sun on the same views (the found samples and all), for comparison. --debug-dir OUT writes, per\n"
          "sample, the view with the shadow test of the true and of the fitted sun laid over it (blocked ground\n"
          "red, lit ground green): OUT/<id>_true.png, OUT/<id>_fit.png.\n"
          "--kitti DIR fits one KITTI frame instead (DIR/000008.png, 000008.txt, 000008_calib.json,\n"
          "000008_velodyne.bin, as in ../shared/data/street/kitti_000008) and prints the fit; with --debug-dir,\n"
          "OUT/kitti_fit.png. It has no true sun to compare with. --landscape also prints the score of every\n"
          "direction of the coarse grid, one JSON object per line.\n",
          options.min_score);
      return 0;
    } else if (a == "--data") {
      dir = value();
    } else if (a == "--split") {
      split = value();
    } else if (a == "--limit") {
      const std::string s = value();
      limit = std::atoll(s.c_str());
      SL_CHECK(limit >= 1, "sun-from-shadows: --limit must be a positive integer, got '", s, "'");
    } else if (a == "--min-score") {
      const std::string s = value();
      char* end = nullptr;
      options.min_score = std::strtod(s.c_str(), &end);
      SL_CHECK(end && *end == '\0' && std::isfinite(options.min_score), "sun-from-shadows: --min-score must be a number, got '",
               s, "'");
    } else if (a == "--checkpoint") {
      checkpoint = value();
    } else if (a == "--landscape") {
      landscape = true;
    } else if (a == "--kitti") {
      kitti = value();
    } else if (a == "--debug-dir") {
      debug_dir = value();
    } else if (a == "--json") {
      json = true;
    } else {
      fail("sun-from-shadows: unknown argument '", a, "' (try sun-from-shadows --help)");
    }
  }
  if (!kitti.empty()) {
    const train::PhotoSources src = kitti_000008(kitti);
    const train::Photo photo = train::load_photo(src);
    const data::ShadowSunFit fit = data::fit_sun_from_shadows(photo.ldr, photo.depth, photo.camera, options);
    std::printf("{\"photo\":\"%s\",\"found\":%s,\"score\":%.4f,\"azimuth_deg\":%.2f,\"elevation_deg\":%.2f,"
                "\"shadow_ratio\":%.4f,\"ground_samples\":%d,\"shadow_samples\":%d,\"spread_deg\":%.1f,\"ms\":%.2f}\n",
                src.image.c_str(), fit.found ? "true" : "false", fit.score, fit.azimuth_deg, fit.elevation_deg,
                fit.shadow_ratio, fit.ground_samples, fit.shadow_samples, fit.spread_deg, fit.time_ms);
    if (landscape)
      for (const auto& c : fit.coarse)
        std::printf("{\"azimuth_deg\":%.1f,\"elevation_deg\":%.1f,\"score\":%.4f}\n", c[0], c[1], c[2]);
    if (!debug_dir.empty()) {
      data::StreetView v;
      v.ldr = photo.ldr, v.depth = photo.depth, v.camera = photo.camera;
      write_overlay(debug_dir + "/kitti_fit.png", v, fit.direction, options);
    }
    return 0;
  }
  SL_CHECK(!dir.empty(), "sun-from-shadows: --data DIR is required (try sun-from-shadows --help)");
  const data::StreetDataset ds(dir, split);
  std::vector<double> err_found, err_all, ms, net_found, net_all;
  std::unique_ptr<train::LightingEstimator> net;
  if (!checkpoint.empty()) net = std::make_unique<train::LightingEstimator>(checkpoint);
  const bool tty = isatty(fileno(stderr));
  size_t n = ds.size();
  if (limit > 0) n = std::min<size_t>(n, static_cast<size_t>(limit));
  for (size_t i = 0; i < n; ++i) {
    const data::SunLabel label = ds.load_sun_label(i);
    if (!label.sun_known) continue;
    const data::StreetSample s = ds.load(i);
    const data::StreetView& v = s.views.at(0);
    const data::ShadowSunFit fit = data::fit_sun_from_shadows(v.ldr, v.depth, v.camera, options);
    const double e = angle_deg(fit.direction, s.sun_direction);
    if (!debug_dir.empty()) {
      write_overlay(debug_dir + "/" + s.id + "_true.png", v, s.sun_direction, options);
      write_overlay(debug_dir + "/" + s.id + "_fit.png", v, fit.direction, options);
    }
    err_all.push_back(e);
    if (fit.found) err_found.push_back(e);
    double e_net = NAN;
    if (net) {
      const train::EstimatedLighting l = net->estimate({{v.ldr, v.depth, v.camera}});
      e_net = angle_deg(l.sun_direction_world(), s.sun_direction);
      net_all.push_back(e_net);
      if (fit.found) net_found.push_back(e_net);
    }
    ms.push_back(fit.time_ms);
    if (json)
      std::printf(
          "{\"sample\":\"%s\",\"found\":%s,\"error_deg\":%.3f,\"score\":%.4f,\"azimuth_deg\":%.2f,\"elevation_deg\":%.2f,"
          "\"shadow_ratio\":%.4f,\"ground_samples\":%d,\"shadow_samples\":%d,\"ms\":%.2f,\"spread_deg\":%.1f,\"network_error_deg\":%s}\n",
          s.id.c_str(), fit.found ? "true" : "false", e, fit.score, fit.azimuth_deg, fit.elevation_deg, fit.shadow_ratio,
          fit.ground_samples, fit.shadow_samples, fit.time_ms, fit.spread_deg, net ? std::to_string(e_net).c_str() : "null");
    else if (tty)
      std::fprintf(stderr, "\r%zu/%zu", i + 1, n);
  }
  if (!json && tty) std::fprintf(stderr, "\n");
  const double coverage = err_all.empty() ? NAN : double(err_found.size()) / double(err_all.size());
  if (json) {
    std::printf(
        "{\"summary\":true,\"samples\":%zu,\"found\":%zu,\"median_found_deg\":%.3f,\"median_all_deg\":%.3f,"
        "\"within15_found\":%.4f,\"within30_found\":%.4f,\"within45_found\":%.4f,\"ms_median\":%.2f}\n",
        err_all.size(), err_found.size(), median_of(err_found), median_of(err_all), share_within(err_found, 15),
        share_within(err_found, 30), share_within(err_found, 45), median_of(ms));
  } else {
    std::printf("%-10s %7s %10s %6s %6s %6s\n", "fits", "n", "median °", "≤15°", "≤30°", "≤45°");
    std::printf("%-10s %7zu %10.1f %6.2f %6.2f %6.2f\n", "found", err_found.size(), median_of(err_found),
                share_within(err_found, 15), share_within(err_found, 30), share_within(err_found, 45));
    std::printf("%-10s %7zu %10.1f %6.2f %6.2f %6.2f\n", "all", err_all.size(), median_of(err_all),
                share_within(err_all, 15), share_within(err_all, 30), share_within(err_all, 45));
    if (net) {
      std::printf("%-10s %7zu %10.1f %6.2f %6.2f %6.2f   (%s, same views)\n", "net found", net_found.size(),
                  median_of(net_found), share_within(net_found, 15), share_within(net_found, 30), share_within(net_found, 45),
                  checkpoint.c_str());
      std::printf("%-10s %7zu %10.1f %6.2f %6.2f %6.2f\n", "net all", net_all.size(), median_of(net_all),
                  share_within(net_all, 15), share_within(net_all, 30), share_within(net_all, 45));
    }
    std::printf("coverage %.2f, median %.1f ms per image\n", coverage, median_of(ms));
  }
  return 0;
}

const Registrar reg("sun-from-shadows", "sun direction from the photo's cast shadows, against generated streets' true sun",
                    &run_sun_from_shadows);

}  // namespace
}  // namespace sl::bench
