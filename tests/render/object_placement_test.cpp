// render/object_placement.h: the placement under a pixel lands on the point the pixel's ray meets
// at the depth map's depth, round-trips through the camera's ground frame (streetlight-insert's
// --at-pixel and --at agree), and a pixel that sees nothing is one error naming it.
#include "render/object_placement.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "util/error.h"
#include "util/math.h"

namespace sl::test {
namespace {

using render::Camera;
using render::Intrinsics;

Camera pitched_camera(double yaw_deg, double pitch_deg) {
  const Intrinsics k{.fx = 50, .fy = 50, .cx = 40, .cy = 30, .width = 80, .height = 60};
  return Camera(k, render::rotation_from_yaw_pitch_roll(yaw_deg * kPi / 180.0, pitch_deg * kPi / 180.0, 0.0),
                glm::dvec3(3.0, 1.65, -2.0));
}

// The camera-frame depth of the ground y = 0 through every pixel centre; 0 where the ray misses it.
Tensor ground_depth(const Camera& cam) {
  const Intrinsics& k = cam.intrinsics();
  Tensor d = Tensor::zeros({k.height, k.width}, DType::F64);
  double* p = d.data<double>();
  for (int r = 0; r < k.height; ++r)
    for (int c = 0; c < k.width; ++c) {
      const render::CameraRay ray = cam.pixel_ray(c, r);
      if (ray.direction.y >= -1e-9) continue;
      const glm::dvec3 g = ray.origin - ray.direction * (ray.origin.y / ray.direction.y);
      p[r * k.width + c] = cam.world_to_camera(g).z;
    }
  return d;
}

TEST(PixelPlacement, StandsOnThePixelsGroundPointAndRoundTripsThroughTheGroundFrame) {
  for (const auto& [yaw, pitch] : {std::pair{0.0, 0.0}, std::pair{35.0, -8.0}, std::pair{-120.0, 5.0}}) {
    SCOPED_TRACE(std::to_string(yaw) + "/" + std::to_string(pitch));
    const Camera cam = pitched_camera(yaw, pitch);
    const Tensor depth = ground_depth(cam);
    for (const auto& [col, row] : {std::pair{40, 59}, std::pair{5, 50}, std::pair{77, 45}}) {
      const render::CameraRay ray = cam.pixel_ray(col, row);
      ASSERT_LT(ray.direction.y, 0.0);
      const glm::dvec3 g = ray.origin - ray.direction * (ray.origin.y / ray.direction.y);
      const render::PixelPlacement at = render::placement_at_pixel(cam, depth, col, row, 70.0, 1.5);
      EXPECT_NEAR(at.placement.x_m, g.x, 1e-9);
      EXPECT_NEAR(at.placement.z_m, g.z, 1e-9);
      EXPECT_EQ(at.placement.yaw_deg, 70.0);
      EXPECT_EQ(at.placement.scale, 1.5);
      const render::Placement back = render::placement_in_camera_ground_frame(cam, at.right_m, at.forward_m, 70.0);
      EXPECT_NEAR(back.x_m, g.x, 1e-9);
      EXPECT_NEAR(back.z_m, g.z, 1e-9);
      EXPECT_GT(at.forward_m, 0.0) << "a ground point in view lies ahead of the camera";
    }
  }
}

TEST(PixelPlacement, APixelThatSeesNothingOrLiesOutsideIsOneErrorNamingIt) {
  const Camera cam = pitched_camera(0.0, 0.0);
  Tensor depth = ground_depth(cam);
  EXPECT_THROW(render::placement_at_pixel(cam, depth, 40, 5, 90.0), Error);  // sky: depth 0
  double* p = depth.data<double>();
  for (double bad : {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity(), -2.0}) {
    p[59 * 80 + 40] = bad;
    try {
      render::placement_at_pixel(cam, depth, 40, 59, 90.0);
      ADD_FAILURE() << "accepted depth " << bad;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("pixel (40, 59)"), std::string::npos) << e.what();
    }
  }
  for (const auto& [col, row] : {std::pair{-1, 10}, std::pair{80, 10}, std::pair{10, 60}}) {
    try {
      render::placement_at_pixel(cam, depth, col, row, 90.0);
      ADD_FAILURE() << "accepted pixel " << col << ", " << row;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("outside the 80x60 image"), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(render::placement_at_pixel(cam, Tensor::zeros({30, 80}), 40, 20, 90.0), Error);  // another size
}

}  // namespace
}  // namespace sl::test
