// Harness: data/kitti.h. The first byte picks the file: even = a KITTI calibration text file
// (read_kitti_calibration, then lidar_depth through it with fixed points), odd = a velodyne .bin
// (read_velodyne, then lidar_depth and densify_depth with a fixed calibration); the rest of the
// input is the file. label_2 files are only written by the project (train/object_labels.h),
// never read, so there is no label loader to fuzz.
// Invariant: a calibration has finite positive focal lengths and the requested image size;
// depth maps are [H, W], finite and non-negative.
#include <cmath>

#include "data/kitti.h"
#include "tests/fuzz/harness/fuzz_harness.h"

using sl::data::densify_depth;
using sl::data::KittiCalibration;
using sl::data::lidar_depth;
using sl::data::read_kitti_calibration;
using sl::data::read_velodyne;
using sl::render::Intrinsics;
using sl::render::kitti_projection_from_values;

namespace sl::test {

namespace {

constexpr int kWidth = 48, kHeight = 16;

void check_depth(const Tensor& depth, const char* what) {
  if (depth.shape() != Shape{kHeight, kWidth}) violation("kitti", std::string(what) + " has shape " + depth.describe());
  const float* d = depth.data<float>();
  for (int64_t i = 0; i < depth.numel(); ++i)
    if (!std::isfinite(d[i]) || d[i] < 0.0f) violation("kitti", std::string(what) + " holds " + std::to_string(d[i]));
}

KittiCalibration fixed_calibration() {
  KittiCalibration c;
  c.p2_row_major = {40.0, 0.0, 24.0, 0.0, 0.0, 40.0, 8.0, 0.0, 0.0, 0.0, 1.0, 0.0};
  c.p2 = kitti_projection_from_values(c.p2_row_major, kWidth, kHeight, "fuzz");
  // KITTI's velodyne axes: x forward, y left, z up -> camera x right, y down, z forward.
  c.lidar_to_cam = glm::dmat4(glm::dvec4(0, 0, 1, 0), glm::dvec4(-1, 0, 0, 0), glm::dvec4(0, -1, 0, 0),
                              glm::dvec4(0, 1.65, 0, 1));
  c.has_lidar = true;
  return c;
}

}  // namespace

void fuzz_kitti(const uint8_t* data, size_t size) {
  const char* target = "kitti";
  if (size == 0) return;
  if (data[0] % 2 == 0) {
    const std::string path = write_scratch("calib.txt", data + 1, size - 1);
    refuses_cleanly_or_runs(target, [&] {
      const KittiCalibration c = read_kitti_calibration(path, kWidth, kHeight);
      const Intrinsics& k = c.p2.intrinsics;
      if (!(std::isfinite(k.fx) && std::isfinite(k.fy) && k.fx > 0 && k.fy > 0) || k.width != kWidth ||
          k.height != kHeight)
        violation(target, "calibration returned invalid intrinsics");
      if (c.has_lidar) {
        const std::vector<glm::vec4> points = {{5, 0, -1, 0}, {10, 1, -1.5f, 0}, {1e30f, 0, 0, 0}, {-3, 0, 0, 0}};
        check_depth(lidar_depth(points, c), "lidar_depth");
      }
    });
  } else {
    const std::string path = write_scratch("points.bin", data + 1, size - 1);
    refuses_cleanly_or_runs(target, [&] {
      const std::vector<glm::vec4> points = read_velodyne(path);
      if (points.size() * 16 != size - 1) violation(target, "read_velodyne returned the wrong number of points");
      const KittiCalibration c = fixed_calibration();
      const Tensor sparse = lidar_depth(points, c);
      check_depth(sparse, "lidar_depth");
      std::vector<glm::dvec3> camera_points;
      for (const glm::vec4& p : points) {
        const glm::dvec3 x(c.lidar_to_cam * glm::dvec4(p.x, p.y, p.z, 1.0));
        if (x.z > 0.5 && std::isfinite(x.x + x.y + x.z)) camera_points.push_back(x);
      }
      check_depth(densify_depth(sparse, c.p2.intrinsics, camera_points), "densify_depth");
    });
  }
}

}  // namespace sl::test
