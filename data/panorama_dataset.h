// Folders of real HDR panoramas for evaluation (data/hdri_folder.h): each item is the panorama
// rotated by a seeded random azimuth (whole columns, exact), its true sun from peak extraction
// (data/sun_extraction.h) on the rotated map, and a perspective crop at a seeded random yaw,
// with the crop's camera, HDR and the paper's LDR at an exposure that maps the crop's median
// luminance to `ldr_median`.
//
// Rotation is always on: in many public HDRI sets the sun sits at one column
// (../shared/data/MANIFEST.md), so scoring on unrotated copies would reward memorising it.
// Determinism: item (index, seed) is a pure function of both; files are in sorted order.
// Throws: sl::Error naming the folder or file (via HdriFolder) or the bad parameter.
#pragma once
#include <cstdint>
#include <string>

#include <glm/glm.hpp>

#include "autodiff/tensor.h"
#include "data/augment.h"
#include "data/hdri_folder.h"
#include "data/sun_extraction.h"

namespace sl::data {

struct PanoramaItem {
  std::string file;
  Tensor pano_hdr;                  // [3, H, W] rotated
  double azimuth_rad = 0.0;         // rotation applied (data/panorama.h rotate_azimuth)
  SunEstimate sun;                  // on the rotated panorama
  RandomCrop crop;                  // HDR crop and its camera (at the origin)
  Tensor crop_ldr;                  // [3, h, w]
  double exposure = 1.0;
};

class PanoramaDataset {
 public:
  PanoramaDataset(const std::string& folder, const CropRanges& crop = {}, double ldr_median = 0.4);
  size_t size() const { return folder_.size(); }
  const HdriFolder& folder() const { return folder_; }
  PanoramaItem load(size_t index, uint64_t seed) const;

 private:
  HdriFolder folder_;
  CropRanges crop_;
  double ldr_median_;
};

}  // namespace sl::data
