// The crops that `streetlight-bench sun-glare` trains and scores the learned sun-glare detector
// (train/sun_glare.h) on. Every crop is 256×128, roll 0, resampled in linear radiance as the
// benchmark's crops are, and carries glare_input of itself, its camera, and where the sun is.
//
// Crops of the labelled LDR panoramas (panorama_crops; horizontal fov uniform in [50°, 80°]):
// - a panorama with a visible sun: `aimed` crops with the sun in the middle `aimed_span` of the
//   view's width and height (1 puts it anywhere up to the edges), `near` crops aimed 1.1-1.6
//   half-fovs beside it (the sun just out of view: the glare's spill without the sun), `level`
//   crops drawn as the benchmark draws its views (pitch uniform in ±10°) with the yaw put so that
//   the sun is anywhere across the view's width, in view when its height allows, and `random`
//   crops (yaw uniform, pitch uniform in [−5°, 25°]); a crop's sun is in view when it projects
//   inside the image;
// - any other panorama (sun occluded or absent): `random` crops, none with a sun in view;
// - `azimuth_crops` more random crops of each panorama whose sun position is known. The azimuth
//   head learns from the random crops only (set_azimuth): the aimed, near and level crops all face
//   the sun, and would teach it that the sun is mostly in front.
// A low-confidence label weighs half.
//
// benchmark_crops: the benchmark's own crops of one split of a folder of LDR panoramas or HDR skies
// (train/real_sky_benchmark.h), as streetlight-eval draws them; an LDR panorama's occluded sun is
// not a glare in view.
//
// hdr_sun_crops (issue 53: the low suns that level views show): per HDR sky of the list whose sun
// is hard (data/panorama_sample.h sun_hardness), `k` crops toward its sun, alternately aimed (the
// sun in the middle 80%) and level (the benchmark's pitch range, the sun anywhere across the width,
// in view when it is low enough). Each crop has its own exposure: the benchmark's (the crop's
// median luminance at LDR 0.4) times 2^s, s uniform in ±exposure_stops, so one sun is seen from a
// small clipped disk to a wide blown-out glare. No azimuth label (they face the sun).
//
// weigh_low_suns: multiplies the weight of every crop with the sun in view whose elevation is
// below below_deg by `weight` (the benchmark's level views show only suns below about 33°); returns
// how many it weighed.
//
// Crops are a pure function of the files, the counts and the seed (util/random.h), whatever the
// thread count. Throws sl::Error naming a panorama that cannot be read.
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "autodiff/tensor.h"
#include "data/sun_labels.h"
#include "render/camera.h"

namespace sl::bench {

struct GlareCrop {
  Tensor input;  // glare_input of the crop
  Tensor ldr;    // the crop itself (validation only, for the disk test)
  render::Camera camera;
  std::optional<glm::dvec2> sun_pixel;  // in view
  glm::dvec3 sun{0.0, 1.0, 0.0};        // world frame
  double weight = 1.0;
  // The sun's azimuth in the crop camera's canonical frame (train/street_batch.h), where the sun's
  // position is known (in view or not), for the azimuth head; its weight there.
  std::optional<double> azimuth;
  double azimuth_weight = 0.0;
};

// Photometric jitter of a training crop (--jitter-*): the crops are drawn once, so each gets its own
// camera: exposure 2^s, white-balance gains 2^u_c (scaled so grey keeps its Rec. 709 luminance) and a
// tone curve v^(2^t), with s, u_c, t uniform in ±stops. Applied to the LDR crop in linear radiance
// (v^2.2); a pixel clipped in every channel (≥ 0.98, as data/visible_sun.h) stays as it is, since a
// sun's core clips under any exposure a street photo would use.
struct Jitter {
  double exposure = 0.0, white_balance = 0.0, tone = 0.0;
  bool on() const { return exposure > 0.0 || white_balance > 0.0 || tone > 0.0; }
};
Tensor jitter_ldr(const Tensor& ldr, const Jitter& j, uint64_t seed);

std::vector<GlareCrop> panorama_crops(const std::string& dir, const data::SunLabels& labels,
                                      const std::vector<std::string>& names, int aimed, int near, int random,
                                      uint64_t seed, bool keep_ldr, int azimuth_crops = 0, const Jitter& jitter = {},
                                      int level = 0, double aimed_span = 0.8);

std::vector<GlareCrop> benchmark_crops(const std::string& dir, const std::string& split_file, const std::string& split,
                                       int crops, bool keep_ldr, const Jitter& jitter = {});

std::vector<GlareCrop> hdr_sun_crops(const std::string& dir, const std::vector<std::string>& names, int k,
                                     double exposure_stops, uint64_t seed, const Jitter& jitter = {});

int weigh_low_suns(std::vector<GlareCrop>& crops, double weight, double below_deg);

}  // namespace sl::bench
