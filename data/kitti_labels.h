// KITTI object-benchmark label files (label_2/<id>.txt) and full calibration files
// (calib/<id>.txt), as an augmented dataset must carry them through (paper Sec 4.4).
//
// Contract:
// - parse_kitti_label(line, where): the 15 fields `type truncated occluded alpha x1 y1 x2 y2
//   h w l x y z ry` plus an optional 16th `score`; throws sl::Error naming `where` (file:line)
//   and the field when a field is missing or not a number. read_kitti_labels() reads a file
//   (blank lines skipped); format_kitti_label() writes the same fields back (2 decimals, the
//   benchmark's own precision; a score keeps 4).
// - occlusion_level(hidden_fraction): KITTI's occlusion states 0 fully visible (< 5% hidden),
//   1 partly (< 50%), 2 largely occluded. cover_label(): an input label whose 2D box an inserted
//   object now covers by `covered_fraction` keeps the larger of its own state and that level;
//   the unknown state 3 stays 3. Truncation is KITTI's fraction of the object outside the image
//   bounds, which an insertion does not change, so it is carried through unchanged.
// - kitti_calibration_text(path): the full KITTI calibration file for a frame — P0, P1, P2, P3,
//   R0_rect, Tr_velo_to_cam, Tr_imu_to_velo — from a KITTI text calibration (copied line for line
//   when it already has all seven keys), an mmdetection3d JSON (data_list[0].images.CAM0-3
//   cam2img, images.R0_rect, lidar_points.Tr_velo_to_cam / Tr_imu_to_velo), or bare intrinsics
//   (kitti_calibration_from_intrinsics: P0-P3 = K·[I|0], identity R0_rect, and identity-rotation
//   lidar/IMU transforms, for inputs such as nuScenes front cameras that have no KITTI rig).
//   Throws sl::Error naming the file and the missing key.
#pragma once
#include <array>
#include <string>
#include <vector>

#include "render/camera.h"

namespace sl::data {

struct KittiLabel {
  std::string type;
  double truncated = 0.0;
  int occluded = 0;
  double alpha = 0.0;
  std::array<double, 4> box2d{};  // x1 y1 x2 y2 (pixels)
  std::array<double, 7> box3d{};  // h w l x y z ry (camera frame, metres / radians)
  bool has_score = false;
  double score = 0.0;
};

KittiLabel parse_kitti_label(const std::string& line, const std::string& where);
std::vector<KittiLabel> read_kitti_labels(const std::string& path);
std::string format_kitti_label(const KittiLabel& label);

int occlusion_level(double hidden_fraction);
void cover_label(KittiLabel& label, double covered_fraction);
// Whether the bird's-eye footprints (x-z rectangles) of two 3D boxes (h w l x y z ry) overlap
// once `a`'s is grown by `margin` metres on every side (a separating-axis test).
bool footprints_within(const std::array<double, 7>& a, const std::array<double, 7>& b, double margin);

std::string kitti_calibration_text(const std::string& path);
std::string kitti_calibration_from_intrinsics(const render::Intrinsics& k);

}  // namespace sl::data
