// A folder of real HDR panoramas (Radiance .hdr and OpenEXR .exr) for training the sky
// autoencoder (Sec 3.4, "Sky Modeling Supervision"), with seeded augmentation.
//
// Random azimuth rotation is on by default: in many public HDRI sets the sun sits at the same
// column (../shared/data/MANIFEST.md), and a model trained without rotation learns that column.
// Exposure augmentation scales radiance by 2^s, s uniform in [−exposure_stops, exposure_stops].
//
// Requires: an existing folder with at least one .hdr/.exr file (extension case-insensitive).
// Guarantees: files are listed in byte-wise sorted order of their names, so index i names the
//   same file on every machine; augmentation of (index, seed) is a pure function of both
//   (util/random.h), and rotations are whole-pixel by default so they are exact.
// Throws: sl::Error naming the folder (missing, empty) or the file (unreadable, not RGB), or the
//   index when out of range.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "autodiff/tensor.h"

namespace sl::data {

struct HdriAugmentation {
  bool rotate = true;
  bool whole_pixel_rotation = true;  // exact column roll; otherwise any angle, interpolated
  double exposure_stops = 1.0;       // 0 disables exposure augmentation
};

struct AugmentedPanorama {
  Tensor image;              // [3, H, W], linear HDR
  double azimuth_rad = 0.0;  // content moved by this azimuth (data/panorama.h rotate_azimuth)
  double exposure = 1.0;     // radiance multiplier applied
};

class HdriFolder {
 public:
  explicit HdriFolder(const std::string& folder);
  // Exactly these files (full paths, e.g. HdriSplit::split_paths), in sorted order; each must
  // be a regular file (throws naming the missing one).
  explicit HdriFolder(std::vector<std::string> paths);

  size_t size() const { return paths_.size(); }
  const std::string& path(size_t index) const;
  const std::vector<std::string>& paths() const { return paths_; }

  Tensor load(size_t index) const;
  AugmentedPanorama load_augmented(size_t index, uint64_t seed,
                                   const HdriAugmentation& augmentation = {}) const;

 private:
  std::string folder_;
  std::vector<std::string> paths_;
};

// The augmentation that load_augmented applies to a W-column panorama (no file access).
AugmentedPanorama augment_panorama(const Tensor& pano, uint64_t seed, uint64_t stream,
                                   const HdriAugmentation& augmentation);

}  // namespace sl::data
