// 2D boxes and KITTI label lines. See object_labels.h.
#include "train/object_labels.h"

#include <cmath>
#include <cstdio>

#include "util/error.h"
#include "util/math.h"

namespace sl::train {

bool mask_box2d(const Tensor& mask, double threshold, std::array<double, 4>& box) {
  SL_CHECK(mask.dim() == 3 && mask.size(0) == 1, "mask_box2d: expected [1, H, W], got ", mask.describe());
  const Tensor m = mask.detach().to(DType::F32).contiguous();
  const int64_t h = m.size(1), w = m.size(2);
  const float* p = m.data<float>();
  int64_t x0 = w, y0 = h, x1 = -1, y1 = -1;
  for (int64_t r = 0; r < h; ++r)
    for (int64_t c = 0; c < w; ++c)
      if (p[r * w + c] > threshold) {
        x0 = std::min(x0, c), x1 = std::max(x1, c), y0 = std::min(y0, r), y1 = std::max(y1, r);
      }
  if (x1 < 0) return false;
  box = {static_cast<double>(x0), static_cast<double>(y0), static_cast<double>(x1 + 1), static_cast<double>(y1 + 1)};
  return true;
}

const std::string& check_kitti_class(const std::string& name, const std::string& what) {
  static const char* const kClasses[] = {"Car", "Van", "Truck", "Pedestrian", "Person_sitting", "Cyclist", "Tram", "Misc"};
  for (const char* c : kClasses)
    if (name == c) return name;
  fail(what, " '", name, "' is not a KITTI class: expected Car, Van, Truck, Pedestrian, Person_sitting, Cyclist, Tram or Misc");
}

std::string kitti_label_line(const std::string& type, double truncated, int occluded,
                             const std::array<double, 4>& b, const std::array<double, 7>& d) {
  double alpha = d[6] - std::atan2(d[3], d[5]);
  while (alpha > kPi) alpha -= 2 * kPi;
  while (alpha <= -kPi) alpha += 2 * kPi;
  char buf[512];
  std::snprintf(buf, sizeof buf, "%s %.2f %d %.2f %.2f %.2f %.2f %.2f %.2f %.2f %.2f %.2f %.2f %.2f %.2f",
                type.c_str(), truncated, occluded, alpha, b[0], b[1], b[2], b[3], d[0], d[1], d[2], d[3], d[4], d[5],
                d[6]);
  return buf;
}

}  // namespace sl::train
