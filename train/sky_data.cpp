// Sky autoencoder data. See sky_data.h.
#include "train/sky_data.h"

#include <algorithm>
#include <cmath>

#include "data/hdri_folder.h"
#include "data/panorama.h"
#include "data/sky_model.h"
#include "data/sun_extraction.h"
#include "util/random.h"

using sl::data::augment_panorama;
using sl::data::check_panorama;
using sl::data::extract_sun;
using sl::data::HdriAugmentation;
using sl::data::HdriFolder;
using sl::data::PreethamSky;
using sl::data::resize_area;
using sl::data::sample_sky_params;
using sl::data::SunEstimate;
using sl::data::to_ldr;

namespace sl::train {

namespace {

double upper_median_luminance(const Tensor& hdr) {
  const int64_t h = hdr.size(1), w = hdr.size(2), plane = h * w;
  const float* p = hdr.data<float>();
  std::vector<double> lum;
  lum.reserve(static_cast<size_t>(plane / 2 + 1));
  for (int64_t i = 0; i < std::max<int64_t>(h / 2, 1); ++i)
    for (int64_t j = 0; j < w; ++j) {
      const int64_t k = i * w + j;
      lum.push_back(luminance(p[k], p[plane + k], p[2 * plane + k]));
    }
  std::nth_element(lum.begin(), lum.begin() + static_cast<std::ptrdiff_t>(lum.size() / 2), lum.end());
  return lum[lum.size() / 2];
}

}  // namespace

SkySample make_sky_sample(const Tensor& hdr_in, double ldr_key, double exposure_stops, double jitter) {
  check_panorama(hdr_in, "make_sky_sample");
  SL_CHECK(hdr_in.size(0) == 3, "make_sky_sample: expected an RGB panorama, got ", hdr_in.describe());
  const Tensor hdr = hdr_in.contiguous();
  const double med = upper_median_luminance(hdr);
  const double exposure = ldr_key / std::max(med, 1e-8) * std::exp2(jitter * exposure_stops);
  SkySample s;
  s.hdr = Tensor::empty(hdr.shape());
  const float* src = hdr.data<float>();
  float* dst = s.hdr.data<float>();
  for (int64_t i = 0; i < hdr.numel(); ++i) {
    const double v = static_cast<double>(src[i]) * exposure;
    dst[i] = std::isfinite(v) && v > 0 ? static_cast<float>(v) : 0.0f;
  }
  s.ldr = to_ldr(s.hdr, 1.0);
  const SunEstimate sun = extract_sun(s.hdr);
  s.sun_direction = sun.direction;
  s.sun_intensity = sun.radiance_rgb;
  return s;
}

SkyDataSource::SkyDataSource(const SkyDataOptions& options) : opt_(options) {
  if (opt_.hdri_dir.empty() && opt_.hdri_paths.empty()) return;
  const HdriFolder folder = opt_.hdri_paths.empty() ? HdriFolder(opt_.hdri_dir) : HdriFolder(opt_.hdri_paths);
  for (size_t i = 0; i < folder.size(); ++i)
    hdris_.push_back(resize_area(folder.load(i), static_cast<int>(opt_.height), static_cast<int>(opt_.width)));
}

SkySample SkyDataSource::sample(uint64_t seed, uint64_t index) const {
  Rng rng(seed, index);
  const bool use_hdri = !hdris_.empty() && rng.uniform() < opt_.hdri_fraction;
  const double jitter = rng.uniform(-1.0, 1.0);
  Tensor hdr;
  bool from_hdri = false;
  if (use_hdri) {
    const size_t k = static_cast<size_t>(rng.randint(static_cast<int64_t>(hdris_.size())));
    HdriAugmentation aug;
    aug.exposure_stops = 0.0;  // exposure is jittered below, for both sources alike
    hdr = augment_panorama(hdris_[k], mix64(seed ^ 0x4844524931ULL), index, aug).image;
    from_hdri = true;
  } else {
    hdr = PreethamSky(sample_sky_params(seed, index)).render(static_cast<int>(opt_.height), static_cast<int>(opt_.width));
  }
  SkySample s = make_sky_sample(hdr, opt_.ldr_key, opt_.exposure_stops, jitter);
  s.from_hdri = from_hdri;
  return s;
}

}  // namespace sl::train
