#include "tools/bench/sun_glare_crops.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>

#include "autodiff/ops.h"
#include "data/image_io.h"
#include "data/panorama.h"
#include "data/panorama_sample.h"
#include "render/exposure.h"
#include "tools/bench/ldr_panorama_radiance.h"
#include "train/real_sky_benchmark.h"
#include "train/street_batch.h"
#include "train/sun_glare.h"
#include "util/math.h"
#include "util/random.h"

namespace sl::bench {
namespace {

// The sun's azimuth φ = atan2(x, −z) in the camera's canonical frame and the azimuth head's weight
// for it: the label's (half for a low-confidence label) times cos(elevation), since a sun near the
// zenith has no azimuth to tell.
void set_azimuth(GlareCrop& g, double label_weight) {
  const glm::dvec3 c = train::canonical_frame(g.camera).direction(g.sun);
  g.azimuth = std::atan2(c.x, -c.z);
  g.azimuth_weight = label_weight * std::sqrt(std::max(0.0, 1.0 - std::clamp(c.y, -1.0, 1.0) * std::clamp(c.y, -1.0, 1.0)));
}

}  // namespace

Tensor jitter_ldr(const Tensor& ldr, const Jitter& j, uint64_t seed) {
  if (!j.on()) return ldr;
  auto draw = [&](uint64_t k, double stops) { return stops * (2.0 * uniform01(seed, k, 0) - 1.0); };
  double gain[3];
  for (int c = 0; c < 3; ++c) gain[c] = std::exp2(draw(uint64_t(c), j.white_balance));
  const double grey = luminance(gain[0], gain[1], gain[2]), exposure = std::exp2(draw(3, j.exposure));
  const float tone = float(std::exp2(draw(4, j.tone)));
  float g[3];
  for (int c = 0; c < 3; ++c) g[c] = float(exposure * gain[c] / grey);
  Tensor out = ldr.contiguous().clone();
  float* v = out.data<float>();
  const int64_t n = out.size(1) * out.size(2);
  for (int64_t i = 0; i < n; ++i) {
    if (v[i] >= 0.98f && v[n + i] >= 0.98f && v[2 * n + i] >= 0.98f) continue;
    for (int c = 0; c < 3; ++c) {
      float& x = v[c * n + i];
      const float lin = std::pow(std::max(x, 0.0f), float(kLdrGamma)) * g[c];
      x = std::pow(std::min(1.0f, std::pow(lin, 1.0f / float(kLdrGamma))), tone);
    }
  }
  return out;
}

namespace {

// A crop's glare input (and, with keep_ldr, its LDR image) at `exposure` (data/panorama.h to_ldr), and
// the sun's pixel when `visible` and it projects inside the image.
GlareCrop make_crop(const data::PerspectiveCrop& crop, bool visible, const glm::dvec3& sun, bool keep_ldr,
                    const Jitter& jitter = {}, uint64_t jitter_seed = 0, double exposure = 1.0) {
  GlareCrop g;
  const Tensor ldr = jitter_ldr(data::to_ldr(crop.image, exposure).contiguous(), jitter, jitter_seed);
  g.input = train::glare_input(ldr);
  if (keep_ldr) g.ldr = ldr;
  g.camera = crop.camera;
  g.sun = sun;
  if (visible) {
    const render::Projection pr = crop.camera.project(crop.camera.position() + 1e3 * sun);
    if (pr.in_image) g.sun_pixel = pr.pixel;
  }
  return g;
}

// Views toward a sun at azimuth az and elevation el (world frame), shared by the LDR panoramas' and the
// HDR skies' crops. fov_u in [0, 1) draws the horizontal fov uniform in [50°, 80°].
// - aimed_view: the view's centre `across` half-widths beside the sun's azimuth and `up` half-heights
//   off its elevation (the sun in the middle |across|, |up| of the view's width and height when both
//   are below 1), the pitch clamped to ±1.2 rad;
// - level_view: the view's centre `across` half-widths beside the sun's azimuth at the caller's pitch
//   (the benchmark's level range), so the sun is in view when its elevation allows.
double fov_of(double fov_u) { return (50.0 + 30.0 * fov_u) * kDegToRad; }

data::PerspectiveCropParams aimed_view(double fov_u, double az, double el, double across, double up) {
  data::PerspectiveCropParams cp;
  cp.horizontal_fov_rad = fov_of(fov_u);
  const double half_h = 0.5 * cp.horizontal_fov_rad, half_v = std::atan(std::tan(half_h) * cp.height / cp.width);
  cp.yaw_rad = az + across * half_h;
  cp.pitch_rad = std::clamp(el + up * half_v, -1.2, 1.2);
  return cp;
}

data::PerspectiveCropParams level_view(double fov_u, double az, double across, double pitch_rad) {
  data::PerspectiveCropParams cp;
  cp.horizontal_fov_rad = fov_of(fov_u);
  cp.yaw_rad = az + 0.5 * cp.horizontal_fov_rad * across;
  cp.pitch_rad = pitch_rad;
  return cp;
}

}  // namespace

std::vector<GlareCrop> panorama_crops(const std::string& dir, const data::SunLabels& labels,
                                      const std::vector<std::string>& names, int aimed, int near, int random,
                                      uint64_t seed, bool keep_ldr, int azimuth_crops, const Jitter& jitter, int level,
                                      double aimed_span) {
  std::vector<std::vector<GlareCrop>> per(names.size());
#pragma omp parallel for schedule(dynamic, 1)
  for (int64_t i = 0; i < int64_t(names.size()); ++i) {
    const data::PanoramaSunLabel* l = labels.find(names[size_t(i)]);
    if (!l) continue;
    const Tensor pano = read_ldr_panorama_radiance((std::filesystem::path(dir) / l->file).string());
    const bool visible = l->has_position && l->sun == data::SunVisibility::Visible;
    const glm::dvec3 d = l->has_position ? labels.direction(*l, int(pano.size(2)), int(pano.size(1))) : glm::dvec3(0, 1, 0);
    const double az = std::atan2(d.x, -d.z), el = std::asin(std::clamp(d.y, -1.0, 1.0));
    const uint64_t s = hash_counter(seed, std::hash<std::string>{}(l->file));
    const double w = l->confidence == data::LabelConfidence::Low ? 0.5 : 1.0;
    int k = 0;
    auto params = [&](double yaw_offset_halves, double pitch_offset_halves, bool at_sun) {
      if (at_sun) return aimed_view(uniform01(s, uint64_t(k), 0), az, el, yaw_offset_halves, pitch_offset_halves);
      data::PerspectiveCropParams cp;
      cp.horizontal_fov_rad = fov_of(uniform01(s, uint64_t(k), 0));
      cp.yaw_rad = 2.0 * kPi * uniform01(s, uint64_t(k), 1);
      cp.pitch_rad = (-5.0 + 30.0 * uniform01(s, uint64_t(k), 2)) * kDegToRad;
      return cp;
    };
    if (visible) {
      for (int a = 0; a < aimed; ++a, ++k) {
        const auto cp = params(aimed_span * (2.0 * uniform01(s, uint64_t(k), 1) - 1.0),
                               aimed_span * (2.0 * uniform01(s, uint64_t(k), 2) - 1.0), true);
        per[size_t(i)].push_back(make_crop(data::crop_perspective(pano, cp), true, d, keep_ldr, jitter, hash_counter(s, uint64_t(k), 7)));
        per[size_t(i)].back().weight = w;
      }
      for (int a = 0; a < near; ++a, ++k) {
        const double side = uniform01(s, uint64_t(k), 3) < 0.5 ? -1.0 : 1.0;
        const auto cp = params(side * (1.1 + 0.5 * uniform01(s, uint64_t(k), 1)), 0.6 * (2.0 * uniform01(s, uint64_t(k), 2) - 1.0), true);
        per[size_t(i)].push_back(make_crop(data::crop_perspective(pano, cp), true, d, keep_ldr, jitter, hash_counter(s, uint64_t(k), 7)));
      }
    }
    // Level crops toward the sun: the benchmark's pitch range, the sun anywhere across the view's width.
    // Drawn from a stream of their own, so the other crops stay what they were without them.
    if (visible)
      for (int a = 0; a < level; ++a) {
        const uint64_t ls = hash_counter(s, 0x6c6576656cULL, uint64_t(a));
        const auto cp = level_view(uniform01(ls, 0, 0), az, 2.0 * uniform01(ls, 0, 1) - 1.0,
                                   (-10.0 + 20.0 * uniform01(ls, 0, 2)) * kDegToRad);
        per[size_t(i)].push_back(make_crop(data::crop_perspective(pano, cp), true, d, keep_ldr, jitter, hash_counter(ls, 0, 7)));
        if (per[size_t(i)].back().sun_pixel) per[size_t(i)].back().weight = w;
      }
    const size_t first_random = per[size_t(i)].size();
    for (int a = 0; a < random; ++a, ++k) {
      const auto cp = params(0, 0, false);
      per[size_t(i)].push_back(make_crop(data::crop_perspective(pano, cp), visible, d, keep_ldr, jitter, hash_counter(s, uint64_t(k), 7)));
      if (per[size_t(i)].back().sun_pixel) per[size_t(i)].back().weight = w;
    }
    // More random crops where the sun's position is known, for the azimuth head.
    if (l->has_position)
      for (int a = 0; a < azimuth_crops; ++a, ++k) {
        const auto cp = params(0, 0, false);
        per[size_t(i)].push_back(make_crop(data::crop_perspective(pano, cp), visible, d, keep_ldr, jitter, hash_counter(s, uint64_t(k), 7)));
        if (per[size_t(i)].back().sun_pixel) per[size_t(i)].back().weight = w;
      }
    // The azimuth head learns from the random crops only: the aimed, near and level crops all face
    // the sun, and would teach it that the sun is mostly in front.
    if (l->has_position)
      for (size_t c = first_random; c < per[size_t(i)].size(); ++c) set_azimuth(per[size_t(i)][c], w);
  }
  std::vector<GlareCrop> out;
  for (auto& v : per)
    for (auto& c : v) out.push_back(std::move(c));
  return out;
}

// The benchmark's own crops of a folder's split (LDR panoramas or HDR skies).
std::vector<GlareCrop> benchmark_crops(const std::string& dir, const std::string& split_file, const std::string& split,
                                       int crops, bool keep_ldr, const Jitter& jitter) {
  const bool ldr = train::is_ldr_panorama_folder(dir);
  const train::RealSkyFolder f =
      ldr ? train::load_ldr_panorama_folder(dir, (std::filesystem::path(dir) / "sun_labels.csv").string(), split_file, split, crops)
          : train::load_hdr_sky_folder(dir, split_file, split, crops);
  std::vector<GlareCrop> out;
  for (const train::RealSkyCrop& c : f.test) {
    if (c.sample.views.empty()) continue;
    const data::StreetView& v = c.sample.views[0];
    GlareCrop g;
    g.input = train::glare_input(jitter_ldr(v.ldr, jitter, hash_counter(0x6a6974746572ULL, uint64_t(out.size()), 0)));
    if (keep_ldr) g.ldr = v.ldr;
    g.camera = v.camera;
    g.sun = c.sample.sun_direction;
    // An LDR panorama's occluded sun is not a glare in view.
    const bool glare = c.sun_known && c.sun_in_crop && (!ldr || c.label_sun == "visible");
    if (c.sun_known) set_azimuth(g, 1.0);
    if (glare) {
      const render::Projection pr = v.camera.project(v.camera.position() + 1e3 * c.sample.sun_direction);
      if (pr.in_image) g.sun_pixel = pr.pixel;
    }
    out.push_back(std::move(g));
  }
  return out;
}

std::vector<GlareCrop> hdr_sun_crops(const std::string& dir, const std::vector<std::string>& names, int k,
                                     double exposure_stops, uint64_t seed, const Jitter& jitter) {
  std::vector<std::vector<GlareCrop>> per(names.size());
#pragma omp parallel for schedule(dynamic, 1)
  for (int64_t i = 0; i < int64_t(names.size()); ++i) {
    const std::string path = (std::filesystem::path(dir) / names[size_t(i)]).string();
    data::ImageReadOptions ro;
    ro.channels = 3;
    const Tensor pano = data::sanitized_panorama(data::read_image(path, ro).to(DType::F32).contiguous(), path);
    const data::SunHardness h = data::sun_hardness(pano);
    if (!h.hard) continue;
    const glm::dvec3 d = h.sun.direction;
    const double az = std::atan2(d.x, -d.z), el = std::asin(std::clamp(d.y, -1.0, 1.0));
    const uint64_t s = hash_counter(seed, std::hash<std::string>{}(names[size_t(i)]));
    for (int a = 0; a < k; ++a) {
      const double fov_u = uniform01(s, uint64_t(a), 0);
      const double across = 2.0 * uniform01(s, uint64_t(a), 1) - 1.0, up = 2.0 * uniform01(s, uint64_t(a), 2) - 1.0;
      const data::PerspectiveCropParams cp =
          a % 2 == 0 ? aimed_view(fov_u, az, el, 0.8 * across, 0.8 * up)  // the sun in the middle 80% of the view
                     : level_view(fov_u, az, across, 10.0 * up * kDegToRad);  // the benchmark's pitch range
      const data::PerspectiveCrop crop = data::crop_perspective(pano, cp);
      const double exposure = render::exposure_for_ldr_median(crop.image, 0.4) *
                              std::exp2(exposure_stops * (2.0 * uniform01(s, uint64_t(a), 3) - 1.0));
      per[size_t(i)].push_back(make_crop(crop, true, d, false, jitter, hash_counter(s, uint64_t(a), 7), exposure));
    }
  }
  std::vector<GlareCrop> out;
  for (auto& v : per)
    for (auto& c : v) out.push_back(std::move(c));
  return out;
}

int weigh_low_suns(std::vector<GlareCrop>& crops, double weight, double below_deg) {
  const double below = std::sin(below_deg * kDegToRad);
  int n = 0;
  for (GlareCrop& c : crops)
    if (c.sun_pixel && c.sun.y < below) c.weight *= weight, ++n;
  return n;
}

}  // namespace sl::bench
