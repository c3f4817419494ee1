// Training data of the sky autoencoder (Sec 3.4, "Sky Modeling Supervision"): HDR skies from
// the Preetham model (data/sky_model.h) and real HDRIs (data/hdri_folder.h) rotated by a random
// azimuth, each turned into an (LDR, HDR) pair with its ground-truth sun (data/sun_extraction.h).
//
// Exposure: each panorama is scaled to exposure-normalised units (sky_autoencoder.h) by
// exposure = ldr_key / (median luminance of its upper hemisphere) · 2^j, j uniform in
// [−exposure_stops, exposure_stops]; then ldr = clip(hdr^(1/2.2), 0, 1) (data/panorama.h).
//
// Contract: sample(seed, index) is a pure function of (seed, index) and the folder's sorted file
// list: the same on every machine and thread count. HDRIs are read and area-resized to the dome
// once, at construction. Throws sl::Error naming the folder when hdri_dir is set but unusable.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "autodiff/tensor.h"

namespace sl::train {

struct SkySample {
  Tensor hdr;  // [3, H, W] exposure-normalised radiance
  Tensor ldr;  // [3, H, W] in [0, 1]
  glm::dvec3 sun_direction{0.0, 1.0, 0.0};
  glm::dvec3 sun_intensity{0.0};  // mean radiance of the sun texels (the peak, f_intensity)
  bool from_hdri = false;
};

struct SkyDataOptions {
  int64_t height = 32, width = 128;
  std::string hdri_dir;         // empty: sky model only
  std::vector<std::string> hdri_paths;  // when non-empty: exactly these files (a split)
  double hdri_fraction = 0.3;   // share of samples drawn from the HDRIs (when any)
  double ldr_key = 0.25;
  double exposure_stops = 1.0;
};

// (LDR, HDR, sun) from one HDR panorama at the dome size; `jitter` in [−1, 1] scales the stops.
SkySample make_sky_sample(const Tensor& hdr, double ldr_key, double exposure_stops, double jitter);

class SkyDataSource {
 public:
  explicit SkyDataSource(const SkyDataOptions& options);
  SkySample sample(uint64_t seed, uint64_t index) const;
  const SkyDataOptions& options() const { return opt_; }

 private:
  SkyDataOptions opt_;
  std::vector<Tensor> hdris_;  // resized to the dome
};

}  // namespace sl::train
