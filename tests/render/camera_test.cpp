#include "render/camera.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include <unistd.h>

#include "render/equirect.h"
#include "util/error.h"
#include "util/math.h"

using sl::render::Camera;

namespace sl::test {

namespace {

sl::render::Camera test_camera() {
  sl::render::Intrinsics k;
  k.fx = 500.0;
  k.fy = 480.0;
  k.cx = 321.3;
  k.cy = 239.7;
  k.width = 640;
  k.height = 480;
  return sl::render::Camera(k, sl::render::rotation_from_yaw_pitch_roll(0.7, -0.2, 0.1), {1.0, 1.5, -2.0});
}

// Unique per process: test cases may run in parallel processes.
std::string temp_path(const std::string& name) {
  return (std::filesystem::temp_directory_path() / (std::to_string(::getpid()) + "_" + name)).string();
}

}  // namespace

TEST(Camera, ProjectingAPointOnAPixelRayReturnsThatPixel) {
  const sl::render::Camera cam = test_camera();
  for (double u : {0.0, 0.5, 100.25, 639.9})
    for (double v : {0.0, 17.5, 479.5})
      for (double depth : {0.1, 3.0, 250.0}) {
        const sl::render::CameraRay ray = cam.ray(u, v);
        EXPECT_NEAR(glm::length(ray.direction), 1.0, 1e-12);
        const glm::dvec3 p = cam.unproject(u, v, depth);
        const sl::render::Projection pr = cam.project(p);
        ASSERT_TRUE(pr.in_front);
        EXPECT_NEAR(pr.pixel.x, u, 1e-9);
        EXPECT_NEAR(pr.pixel.y, v, 1e-9);
        EXPECT_NEAR(pr.depth, depth, 1e-9 * depth);
        // The unprojected point lies on the ray.
        const glm::dvec3 along = p - ray.origin;
        EXPECT_NEAR(glm::length(glm::cross(along, ray.direction)), 0.0, 1e-9 * depth);
      }
}

TEST(Camera, PointsBehindTheCameraAreFlagged) {
  const sl::render::Camera cam = test_camera();
  const glm::dvec3 behind = cam.camera_to_world({0.3, -0.2, -5.0});
  const sl::render::Projection pr = cam.project(behind);
  EXPECT_FALSE(pr.in_front);
  EXPECT_FALSE(pr.in_image);
  EXPECT_LT(pr.depth, 0.0);
  EXPECT_FALSE(cam.project(cam.position()).in_front);  // the centre itself: never divided by
  EXPECT_TRUE(cam.project(cam.unproject(10, 10, 2.0)).in_image);
  EXPECT_FALSE(cam.project(cam.unproject(-10, 10, 2.0)).in_image);
}

TEST(Camera, PixelCentresAreAtHalfIntegers) {
  const sl::render::Intrinsics k = sl::render::intrinsics_from_fov(60.0 * sl::kDegToRad, 4, 2);
  const sl::render::Camera cam(k, glm::dmat3(1.0), glm::dvec3(0.0));
  // The optical axis passes between the four central pixels of a 4x2 image.
  const glm::dvec3 d = cam.pixel_ray(1, 0).direction + cam.pixel_ray(2, 1).direction;
  EXPECT_NEAR(d.x, 0.0, 1e-12);
  EXPECT_NEAR(d.y, 0.0, 1e-12);
  EXPECT_NEAR(cam.ray(2.0, 1.0).direction.z, 1.0, 1e-12);
  EXPECT_NEAR(k.horizontal_fov_rad(), 60.0 * sl::kDegToRad, 1e-12);
}

TEST(Camera, YawPitchRollFollowThePanoramaConvention) {
  const sl::render::Intrinsics k = sl::render::intrinsics_from_fov(90.0 * sl::kDegToRad, 64, 64);
  for (double yaw : {-170.0, -90.0, 0.0, 30.0, 179.0})
    for (double pitch : {-60.0, 0.0, 45.0}) {
      const sl::render::Camera cam(
          k, sl::render::rotation_from_yaw_pitch_roll(yaw * sl::kDegToRad, pitch * sl::kDegToRad, 0.3),
          glm::dvec3(0.0));
      const glm::dvec3 fwd = cam.ray(32.0, 32.0).direction;
      const auto uv = sl::render::equirect::direction_to_uv(fwd.x, fwd.y, fwd.z, 360, 180);
      EXPECT_NEAR(uv.u - 180.0, yaw, 1e-9);   // azimuth in degrees
      EXPECT_NEAR(90.0 - uv.v, pitch, 1e-9);  // elevation in degrees
    }
  // Identity orientation: looks down -Z, image-down is world -Y, image-right is world +X.
  const glm::dmat3 r = sl::render::rotation_from_yaw_pitch_roll(0, 0, 0);
  EXPECT_NEAR(glm::length(r * glm::dvec3(0, 0, 1) - glm::dvec3(0, 0, -1)), 0.0, 1e-15);
  EXPECT_NEAR(glm::length(r * glm::dvec3(0, 1, 0) - glm::dvec3(0, -1, 0)), 0.0, 1e-15);
  EXPECT_NEAR(glm::length(r * glm::dvec3(1, 0, 0) - glm::dvec3(1, 0, 0)), 0.0, 1e-15);
  // Positive roll: the camera's right side goes down.
  const glm::dmat3 rolled = sl::render::rotation_from_yaw_pitch_roll(0, 0, 10 * sl::kDegToRad);
  EXPECT_LT((rolled * glm::dvec3(1, 0, 0)).y, 0.0);
}

TEST(Camera, KittiProjectionFileGivesPublishedIntrinsics) {
  const std::string path = std::string(STREETLIGHT_SHARED_DATA) + "/street/kitti_000008/000008.txt";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "shared data absent: " << path;
  const sl::render::KittiProjection p = sl::render::kitti_projection_from_file(path, 1242, 375);
  EXPECT_DOUBLE_EQ(p.intrinsics.fx, 721.5377);
  EXPECT_DOUBLE_EQ(p.intrinsics.fy, 721.5377);
  EXPECT_DOUBLE_EQ(p.intrinsics.cx, 609.5593);
  EXPECT_DOUBLE_EQ(p.intrinsics.cy, 172.854);
  EXPECT_EQ(p.intrinsics.width, 1242);
  // P2's 4th column is K·t with t ≈ (0.06, -0.0003, 0.0027) m (camera 2 offset).
  EXPECT_NEAR(p.translation.x, (44.85728 - 609.5593 * 0.002745884) / 721.5377, 1e-12);
  EXPECT_NEAR(p.translation.z, 0.002745884, 1e-15);
}

TEST(Camera, KittiCalibFileWithKeysIsParsedAndBadFilesNameTheFile) {
  const std::string path = temp_path("sl_camera_test_calib.txt");
  {
    std::ofstream out(path);
    out << "P0: 7.0e+02 0 6.0e+02 0 0 7.0e+02 1.7e+02 0 0 0 1 0\n"
        << "P2: 721.5377 0 609.5593 44.85728 0 721.5377 172.854 0.2163791 0 0 1 0.002745884\n";
  }
  const sl::render::KittiProjection p = sl::render::kitti_projection_from_file(path, 1242, 375, "P2");
  EXPECT_DOUBLE_EQ(p.intrinsics.cx, 609.5593);
  try {
    sl::render::kitti_projection_from_file(path, 1242, 375, "P3");
    FAIL() << "expected an error for a missing key";
  } catch (const sl::Error& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("P3"), std::string::npos) << e.what();
  }
  {
    std::ofstream out(path);
    out << "1 2 3 4 5\n";
  }
  EXPECT_THROW(sl::render::kitti_projection_from_file(path, 10, 10), sl::Error);
  {
    std::ofstream out(path);
    out << "700 0 300 0 0 700 200 0 0 0 1 0 0 0 0 2\n";  // 4x4 with a bad last row
  }
  EXPECT_THROW(sl::render::kitti_projection_from_file(path, 10, 10), sl::Error);
  std::filesystem::remove(path);
  EXPECT_THROW(sl::render::kitti_projection_from_file(path, 10, 10), sl::Error);
}

TEST(Camera, NuScenesIntrinsicsAreReadAndInvalidOnesRejected) {
  const sl::render::Intrinsics k =
      sl::render::intrinsics_from_matrix3x3({1266.417, 0.0, 816.267, 0.0, 1266.417, 491.507, 0.0, 0.0, 1.0}, 1600, 900);
  EXPECT_DOUBLE_EQ(k.fx, 1266.417);
  EXPECT_DOUBLE_EQ(k.cy, 491.507);
  EXPECT_THROW(sl::render::intrinsics_from_matrix3x3({-1, 0, 1, 0, 1, 1, 0, 0, 1}, 10, 10), sl::Error);
  EXPECT_THROW(sl::render::intrinsics_from_matrix3x3({100, 5, 1, 0, 100, 1, 0, 0, 1}, 10, 10), sl::Error);
  EXPECT_THROW(sl::render::intrinsics_from_matrix3x3({100, 0, 1, 0, 100, 1, 0, 0, 1}, 0, 10), sl::Error);
  glm::dmat3 not_rotation(1.0);
  not_rotation[0][0] = 2.0;
  EXPECT_THROW(sl::render::Camera(k, not_rotation, glm::dvec3(0.0)), sl::Error);
}

TEST(Camera, ScalingIntrinsicsKeepsRaysThroughTheSameImagePoints) {
  const sl::render::Camera cam = test_camera();
  const sl::render::Camera half(cam.intrinsics().scaled(0.5, 0.5), cam.rotation(), cam.position());
  const glm::dvec3 a = cam.ray(100.0, 200.0).direction;
  const glm::dvec3 b = half.ray(50.0, 100.0).direction;
  EXPECT_NEAR(glm::length(a - b), 0.0, 1e-12);
}

}  // namespace sl::test
