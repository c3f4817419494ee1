// A tiny folder of labelled LDR panoramas for the tools' tests (eval, bench sun-glare).
#pragma once
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "autodiff/tensor.h"
#include "data/image_io.h"

namespace sl::test {

// DIR/ldr: LDR panoramas (8-bit JPEGs, 128×64): grey ground, lighter sky and, where the panorama
// is labelled with a position, a white 3×3 sun at the label. sun_labels.csv beside them (label
// frame 2048×1024, 16× the image), and DIR/ldr_split.json. Test: a (visible, street, high),
// b (occluded with a position, other, low), c (none), d (occluded without a position); train:
// t1 (visible street), t2 (visible other).
struct LdrSun {
  const char* file;
  const char* sun;
  int col, row;  // the sun texel (−1: no position)
  const char* confidence;
  const char* scene;
};
inline constexpr LdrSun kLdrSuns[] = {{"a.jpg", "visible", 30, 27, "high", "street"},
                                      {"b.jpg", "occluded", 90, 25, "low", "other"},
                                      {"c.jpg", "none", -1, -1, "high", "street"},
                                      {"d.jpg", "occluded", -1, -1, "medium", "street"},
                                      {"t1.jpg", "visible", 70, 25, "high", "street"},
                                      {"t2.jpg", "visible", 110, 8, "medium", "other"}};

inline std::string tiny_ldr_folder(const std::string& dir) {
  const std::string folder = dir + "/ldr";
  std::filesystem::create_directories(folder);
  std::ofstream labels(folder + "/sun_labels.csv");
  labels << "file,sun,u,v,confidence,scene,note\n";
  for (const LdrSun& s : kLdrSuns) {
    sl::Tensor img = sl::Tensor::empty({3, 64, 128});
    float* p = img.data<float>();
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 64; ++r)
        for (int x = 0; x < 128; ++x) {
          const bool sun = s.col >= 0 && std::abs(x - s.col) <= 1 && std::abs(r - s.row) <= 1;
          p[(c * 64 + r) * 128 + x] = sun ? 1.0f : r < 32 ? 0.55f + 0.1f * c : 0.25f;
        }
    sl::data::ImageWriteOptions wo;
    wo.transfer = sl::data::Transfer::Linear;  // the values are the 8-bit codes
    sl::data::write_image(folder + "/" + s.file, img, wo);
    labels << s.file << "," << s.sun << ",";
    if (s.col >= 0) labels << (s.col + 0.5) * 16 << "," << (s.row + 0.5) * 16;
    else labels << ",";
    labels << "," << s.confidence << "," << s.scene << ",\"note, with a comma\"\n";
  }
  std::ofstream(dir + "/ldr_split.json")
      << R"({"train": ["t1.jpg", "t2.jpg"], "test": ["a.jpg", "b.jpg", "c.jpg", "d.jpg"]})";
  return folder;
}

}  // namespace sl::test
