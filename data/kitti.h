// The KITTI layout: a left colour image, its 3×4 projection P2, and optional velodyne points
// turned into sparse metric depth, plus a densification for object insertion.
//
// Calibration files: an mmdetection3d-style JSON (data_list[0].images.CAM2 with cam2img and
// lidar2cam, 4×4 row-major — the layout of ../shared/data/street/kitti_000008/) or a KITTI text
// file (object-benchmark calib with `P2:`, optionally `R0_rect:` and `Tr_velo_to_cam:`, or a
// bare list of 12/16 numbers holding P2 alone; render/camera.h parses P2).
// Depth: a lidar point p becomes X = lidar_to_cam · p in the rectified reference camera, then
// (u·z, v·z, z) = P2 · X; z is camera-2's depth (KITTI's camera-frame z). Each pixel keeps its
// nearest point (KITTI puts pixel centres at integer u, v, so the pixel is round(u), round(v)).
// Points with z ≤ 0.5 m or outside the image are dropped. Missing depth is 0.
// Densification (documented choice): (1) nearest-neighbour fill — a missing pixel takes the
// depth of the nearest valid pixel within radius_px (ties: the nearer surface), which fills the
// gaps between lidar scan lines without blurring depth edges; (2) ground-plane fill — a plane
// y = a·x + b·z + c (camera frame, y down) is fitted to the lidar points by seeded RANSAC over
// points below the camera and refined by least squares; still-missing pixels whose rays hit it
// in front of the camera (below the horizon) within max_ground_distance_m take its depth. Sky
// and far structure above the horizon stay 0.
// Camera: the image's intrinsics with a level pose in the world frame of docs/DESIGN.md (+Y up):
// yaw = pitch = roll = 0 at (0, camera_height_m, 0); KITTI's camera is mounted ~1.65 m high.
// Throws: sl::Error naming the file and the key or byte count (bad JSON, missing key, a
// velodyne file whose size is not a multiple of 16 bytes, an unreadable image).
#pragma once
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "autodiff/tensor.h"
#include "render/camera.h"

namespace sl::data {

struct KittiCalibration {
  render::KittiProjection p2;  // intrinsics and t = K⁻¹·P2[:, 3]
  std::array<double, 12> p2_row_major{};
  glm::dmat4 lidar_to_cam{1.0};       // lidar → rectified reference camera (R0_rect · Tr_velo_to_cam)
  bool has_lidar = false;
};

KittiCalibration read_kitti_calibration(const std::string& path, int width, int height);

// x y z intensity per point, lidar frame (float32 little-endian, 16 bytes each).
std::vector<glm::vec4> read_velodyne(const std::string& path);

// [H, W] metres (camera-2 z), 0 where no point lands.
Tensor lidar_depth(const std::vector<glm::vec4>& points, const KittiCalibration& calib);

struct GroundPlane {
  bool found = false;
  double a = 0.0, b = 0.0, c = 0.0;  // y = a·x + b·z + c, camera frame (y down), metres
  int inliers = 0;
};
GroundPlane fit_ground_plane(const std::vector<glm::dvec3>& camera_points, uint64_t seed = 0);

struct DensifyParams {
  int radius_px = 6;
  bool ground_plane = true;
  double max_ground_distance_m = 80.0;
};
// `camera_points` feed the ground-plane fit (may be empty to skip it).
Tensor densify_depth(const Tensor& sparse_depth, const render::Intrinsics& intrinsics,
                     const std::vector<glm::dvec3>& camera_points, const DensifyParams& params = {},
                     GroundPlane* plane = nullptr);

// A velodyne scan seen from camera 2 of a width x height image.
struct KittiLidar {
  KittiCalibration calibration;
  std::vector<glm::vec4> points;          // empty without a velodyne file
  std::vector<glm::dvec3> camera_points;  // the points in camera-2 coordinates (z > 0.5 m)
  Tensor sparse_depth;                    // [H, W], undefined without a velodyne file
};

// The calibration and, when velodyne_path is not empty, the scan's points and sparse depth, for an
// image already read. Throws when the principal point lies outside width x height (a calibration of
// another image, or a photo turned by its EXIF orientation), and when a scan is given but the
// calibration has no lidar-to-camera transform.
KittiLidar load_kitti_lidar(const std::string& calibration_path, const std::string& velodyne_path, int width,
                            int height);

struct KittiFrame : KittiLidar {
  Tensor image;  // [3, H, W] stored 8-bit values in [0, 1] (sRGB-encoded, not decoded)
  render::Camera camera;
};

KittiFrame load_kitti_frame(const std::string& image_path, const std::string& calibration_path,
                            const std::string& velodyne_path = "", double camera_height_m = 1.65);

}  // namespace sl::data
