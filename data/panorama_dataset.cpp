#include "data/panorama_dataset.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "data/panorama.h"
#include "util/error.h"
#include "util/math.h"
#include "util/random.h"

using sl::render::exposure_for_ldr_median;

namespace sl::data {

PanoramaDataset::PanoramaDataset(const std::string& folder, const CropRanges& crop, double ldr_median)
    : folder_(folder), crop_(crop), ldr_median_(ldr_median) {
  SL_CHECK(ldr_median > 0.0 && ldr_median < 1.0, "PanoramaDataset: ldr_median must be in (0, 1), got ", ldr_median);
}

PanoramaItem PanoramaDataset::load(size_t index, uint64_t seed) const {
  PanoramaItem item;
  item.file = folder_.path(index);
  Tensor pano = folder_.load(index).contiguous();
  float* p = pano.data<float>();
  for (int64_t i = 0; i < pano.numel(); ++i)
    if (!(p[i] >= 0.0f) || !std::isfinite(p[i])) p[i] = 0.0f;  // real files hold a few bad texels
  const int64_t W = pano.size(2);
  Rng rng(seed, 0xA0A0000ULL + index);
  const int64_t shift = rng.randint(W);
  item.azimuth_rad = 2.0 * kPi * static_cast<double>(shift) / static_cast<double>(W);
  item.pano_hdr = rotate_azimuth(pano, item.azimuth_rad).contiguous();
  item.sun = extract_sun(item.pano_hdr);
  item.crop = random_perspective_crop(item.pano_hdr, seed, 0xC0C0000ULL + index, crop_);
  const Tensor& c = item.crop.crop.image;
  item.exposure = exposure_for_ldr_median(c, ldr_median_);
  item.crop_ldr = to_ldr(c, item.exposure);
  return item;
}

}  // namespace sl::data
