#include "data/hdri_folder.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>

#include "data/image_io.h"
#include "data/panorama.h"
#include "util/math.h"
#include "util/random.h"

namespace sl::data {

namespace fs = std::filesystem;

HdriFolder::HdriFolder(const std::string& folder) : folder_(folder) {
  std::error_code ec;
  SL_CHECK(fs::is_directory(folder, ec), "HdriFolder: '", folder, "' is not a folder");
  for (const auto& entry : fs::directory_iterator(folder, ec)) {
    if (!entry.is_regular_file(ec)) continue;
    std::string ext = entry.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (ext == ".hdr" || ext == ".exr") paths_.push_back(entry.path().string());
  }
  SL_CHECK(!ec, "HdriFolder: '", folder, "': cannot list: ", ec.message());
  std::sort(paths_.begin(), paths_.end());
  SL_CHECK(!paths_.empty(), "HdriFolder: '", folder, "' holds no .hdr or .exr files");
}

HdriFolder::HdriFolder(std::vector<std::string> paths) : paths_(std::move(paths)) {
  SL_CHECK(!paths_.empty(), "HdriFolder: an empty list of panoramas");
  for (const auto& p : paths_) {
    std::error_code ec;
    SL_CHECK(fs::is_regular_file(p, ec), "HdriFolder: panorama '", p, "' does not exist");
  }
  std::sort(paths_.begin(), paths_.end());
  folder_ = fs::path(paths_[0]).parent_path().string();
}

const std::string& HdriFolder::path(size_t index) const {
  SL_CHECK(index < paths_.size(), "HdriFolder: index ", index, " out of range for ", paths_.size(),
           " files in '", folder_, "'");
  return paths_[index];
}

Tensor HdriFolder::load(size_t index) const {
  const std::string& p = path(index);
  ImageReadOptions options;
  options.channels = 3;
  options.transfer = Transfer::Linear;
  return read_image(p, options);
}

AugmentedPanorama augment_panorama(const Tensor& pano, uint64_t seed, uint64_t stream,
                                   const HdriAugmentation& augmentation) {
  check_panorama(pano, "augment_panorama");
  SL_CHECK(augmentation.exposure_stops >= 0.0 && std::isfinite(augmentation.exposure_stops),
           "augment_panorama: exposure_stops must be finite and >= 0, got ",
           augmentation.exposure_stops);
  Rng rng(seed, stream);
  const int64_t width = pano.size(2);
  // Draw both numbers unconditionally so each choice is independent of the other's flag.
  const double column = static_cast<double>(rng.randint(width));
  const double angle = rng.uniform(-0.5 * kTwoPi, 0.5 * kTwoPi);
  const double stops = rng.uniform(-1.0, 1.0) * augmentation.exposure_stops;
  AugmentedPanorama out;
  out.azimuth_rad = !augmentation.rotate ? 0.0
                    : augmentation.whole_pixel_rotation ? column * kTwoPi / static_cast<double>(width)
                                                        : angle;
  out.exposure = std::exp2(stops);
  out.image = out.azimuth_rad != 0.0 ? rotate_azimuth(pano, out.azimuth_rad) : pano.clone();
  if (out.exposure != 1.0) {
    float* p = out.image.data<float>();
    const float e = static_cast<float>(out.exposure);
    for (int64_t i = 0; i < out.image.numel(); ++i) p[i] *= e;
  }
  return out;
}

AugmentedPanorama HdriFolder::load_augmented(size_t index, uint64_t seed,
                                             const HdriAugmentation& augmentation) const {
  return augment_panorama(load(index), seed, index, augmentation);
}

}  // namespace sl::data
