// Pinhole camera: the ONE place camera conventions live (docs/DESIGN.md, "Camera frame").
//
// Conventions:
// - Camera frame is OpenCV: x right, y down, z forward. World frame is right-handed, metres, +Y up.
// - Continuous pixel coordinates (u, v): pixel (col, row) covers [col, col+1) × [row, row+1), so
//   its centre is (col + 0.5, row + 0.5). A point at camera coordinates (x, y, z), z > 0, lands at
//   u = fx·x/z + cx, v = fy·y/z + cy. Dataset intrinsics (KITTI, nuScenes, OpenCV) put pixel
//   centres at integers; the converters below keep their numbers unchanged (the half-pixel
//   difference is below their calibration accuracy and keeps values comparable with the
//   datasets' own tools). Call `shift_to_pixel_centres()` to apply the +0.5 explicitly.
// - "Depth" is the camera-frame z (distance along the optical axis), as in KITTI depth maps,
//   not the distance along the ray.
// - Pose: camera-to-world rotation R (columns are the camera axes in world coordinates) and
//   the camera centre t in world coordinates: p_world = R·p_cam + t.
// - Orientation from yaw/pitch/roll (radians): yaw = 0, pitch = 0, roll = 0 looks down world −Z
//   with image-down = world −Y, so the view's forward direction has panorama azimuth = yaw and
//   elevation = pitch (render/equirect.h). Positive roll turns the camera clockwise as seen
//   from behind it (its right side goes down), i.e. a rotation about the camera +z axis.
//
// Requires: fx, fy > 0, width, height > 0; R orthonormal (checked to 1e-6).
// Guarantees: ray() returns unit world directions; project(unproject(u, v, d)) == (u, v) with
//   depth d; points at or behind the camera plane (z ≤ 1e-12) are flagged, never divided by.
// Throws: sl::Error naming the argument and value (bad intrinsics or rotation), or naming the
//   file and key (KITTI calibration parsing).
#pragma once
#include <array>
#include <string>

#include <glm/glm.hpp>

namespace sl::render {

struct Intrinsics {
  double fx = 1.0, fy = 1.0;  // focal lengths in pixels
  double cx = 0.0, cy = 0.0;  // principal point in continuous pixel coordinates
  int width = 1, height = 1;  // image size in pixels

  // Horizontal / vertical field of view across the full image width / height.
  double horizontal_fov_rad() const;
  double vertical_fov_rad() const;
  // Same camera with the principal point moved by +0.5 (integer-centred → centre-at-+0.5).
  Intrinsics shift_to_pixel_centres() const;
  // The same camera on an image resized by (sx, sy) (e.g. 0.5 for half resolution).
  Intrinsics scaled(double sx, double sy) const;
};

void validate(const Intrinsics& k, const char* where);

// A camera centred in the image with the given horizontal field of view and square pixels.
Intrinsics intrinsics_from_fov(double horizontal_fov_rad, int width, int height);

// nuScenes-style 3×3 row-major K = [fx s cx; 0 fy cy; 0 0 1]. Rejects skew |s| > 1e-6·fx and a
// last row other than (0, 0, 1).
Intrinsics intrinsics_from_matrix3x3(const std::array<double, 9>& k_row_major, int width,
                                     int height);

// A KITTI 3×4 projection matrix P = K·[I | t], as read from a calibration file.
struct KittiProjection {
  Intrinsics intrinsics;
  glm::dvec3 translation{0.0};  // t = K⁻¹·P[:, 3]: rectified-camera-0 → this camera offset (m)
};

// Parses P from a KITTI text file. Accepted layouts: lines `KEY: 12 numbers` (object benchmark
// calib files, key e.g. "P2"), or a bare list of 12 numbers (3×4) or 16 numbers (4×4 whose last
// row must be 0 0 0 1). Image size is not in the file, so it is passed in.
KittiProjection kitti_projection_from_file(const std::string& path, int width, int height,
                                           const std::string& key = "P2");
KittiProjection kitti_projection_from_values(const std::array<double, 12>& p_row_major,
                                             int width, int height, const char* where);

// Camera-to-world rotation for an OpenCV camera with the given yaw, pitch and roll (see above).
glm::dmat3 rotation_from_yaw_pitch_roll(double yaw_rad, double pitch_rad, double roll_rad);

struct CameraRay {
  glm::dvec3 origin;
  glm::dvec3 direction;  // unit, world frame
};

struct Projection {
  glm::dvec2 pixel{0.0};  // continuous (u, v); (0, 0) when !in_front
  double depth = 0.0;     // camera-frame z in metres (negative behind the camera)
  bool in_front = false;  // z > 1e-12; pixel is meaningful only then
  bool in_image = false;  // in_front and 0 ≤ u < width, 0 ≤ v < height
};

class Camera {
 public:
  Camera() = default;
  Camera(const Intrinsics& intrinsics, const glm::dmat3& rotation_cam_to_world,
         const glm::dvec3& position_world);

  const Intrinsics& intrinsics() const { return k_; }
  const glm::dmat3& rotation() const { return r_; }  // camera-to-world
  const glm::dvec3& position() const { return t_; }

  // Ray through continuous pixel coordinates (u, v); pixel (col, row) is (col + 0.5, row + 0.5).
  CameraRay ray(double u, double v) const;
  CameraRay pixel_ray(int col, int row) const { return ray(col + 0.5, row + 0.5); }
  // Direction in the camera frame, NOT normalised: (x/z, y/z, 1).
  glm::dvec3 camera_direction(double u, double v) const;
  // World point at camera-frame depth z along the ray through (u, v).
  glm::dvec3 unproject(double u, double v, double depth_z) const;

  glm::dvec3 world_to_camera(const glm::dvec3& p_world) const;
  glm::dvec3 camera_to_world(const glm::dvec3& p_cam) const;
  Projection project(const glm::dvec3& p_world) const;

 private:
  Intrinsics k_;
  glm::dmat3 r_{1.0};
  glm::dvec3 t_{0.0};
};

}  // namespace sl::render
