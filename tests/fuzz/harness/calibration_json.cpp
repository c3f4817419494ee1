// Harness: the calibration JSON, read by data/kitti.h read_kitti_calibration (mmdetection3d
// layout) and train/photo_input.h read_intrinsics ({fx, fy, cx, cy[, width, height]}).
// Invariant: returned intrinsics are finite, positive focal lengths, the requested image size.
#include <cmath>

#include "data/kitti.h"
#include "tests/fuzz/harness/fuzz_harness.h"
#include "train/photo_input.h"

using sl::data::KittiCalibration;
using sl::data::read_kitti_calibration;
using sl::render::Intrinsics;

namespace sl::test {

namespace {
void check(const Intrinsics& k, const char* what) {
  if (!(std::isfinite(k.fx) && std::isfinite(k.fy) && std::isfinite(k.cx) && std::isfinite(k.cy) && k.fx > 0 &&
        k.fy > 0) ||
      k.width != 64 || k.height != 32)
    violation("calibration_json", std::string(what) + " returned invalid intrinsics");
}
}  // namespace

void fuzz_calibration_json(const uint8_t* data, size_t size) {
  const char* target = "calibration_json";
  const std::string path = write_scratch("calib.json", data, size);
  refuses_cleanly_or_runs(target, [&] {
    const KittiCalibration c = read_kitti_calibration(path, 64, 32);
    check(c.p2.intrinsics, "read_kitti_calibration");
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j)
        if (!std::isfinite(c.lidar_to_cam[i][j])) violation(target, "lidar_to_cam is not finite");
  });
  refuses_cleanly_or_runs(target, [&] { check(train::read_intrinsics(path, 64, 32), "read_intrinsics"); });
}

}  // namespace sl::test
