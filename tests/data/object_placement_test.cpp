// Placement of object-frame meshes and the KITTI-style boxes that describe it.
#include <gtest/gtest.h>

#include <cmath>

#include "data/object_placement.h"
#include "data/procedural_car.h"
#include "render/primitives.h"
#include "util/error.h"
#include "util/math.h"

using sl::data::FootprintXZ;
using sl::data::kitti_box3d;
using sl::data::make_procedural_car;
using sl::data::placed_footprint;
using sl::data::scale_to_length;
using sl::data::to_object_frame;
using sl::render::Bounds3;
using sl::render::Camera;
using sl::render::intrinsics_from_fov;
using sl::render::make_box;
using sl::render::Mesh;
using sl::render::placed_mesh;
using sl::render::Placement;
using sl::render::rotation_from_yaw_pitch_roll;

namespace sl::test {
namespace {

TEST(ObjectPlacement, CarDrivingAwayHasKittiRotationMinusHalfPi) {
  const Mesh car = make_procedural_car();
  Placement p;
  p.x_m = 2.0;
  p.z_m = -10.0;
  p.yaw_deg = 90.0;  // length down the street (−Z), away from the camera
  const Camera cam(intrinsics_from_fov(1.2, 128, 64), rotation_from_yaw_pitch_roll(0, 0, 0), {0.0, 1.6, 0.0});
  const auto box = kitti_box3d(car, p, cam);
  EXPECT_NEAR(box[0], 1.5, 1e-5);          // h
  EXPECT_NEAR(box[1], 1.8, 0.05);          // w
  EXPECT_NEAR(box[2], 4.5, 0.15);          // l
  EXPECT_NEAR(box[3], 2.0, 1e-5);          // x right
  EXPECT_NEAR(box[4], 1.6, 1e-5);          // y down: the bottom is 1.6 m below the camera
  EXPECT_NEAR(box[5], 10.0, 1e-5);         // z forward
  EXPECT_NEAR(box[6], -kPi / 2, 1e-6);     // KITTI: heading along +z is ry = −π/2
  const FootprintXZ f = placed_footprint(car, p);
  EXPECT_NEAR(f.z1 - f.z0, 4.5, 0.15);
  EXPECT_NEAR(f.x1 - f.x0, 1.8, 0.05);
  const Bounds3 b = placed_mesh(car, p).bounds();
  EXPECT_NEAR(b.lo.y, 0.0, 1e-5);
  EXPECT_NEAR(0.5 * (b.lo.z + b.hi.z), -10.0, 0.05);
}

TEST(ObjectPlacement, ObjectFrameTurnsLengthOntoXAndSitsOnTheGround) {
  const Mesh m = make_box({3.0f, 1.0f, -2.0f}, {4.0f, 2.0f, 4.0f});
  const Mesh o = to_object_frame(m);
  const Bounds3 b = o.bounds();
  EXPECT_NEAR(b.extent().x, 6.0, 1e-5);
  EXPECT_NEAR(b.extent().z, 1.0, 1e-5);
  EXPECT_NEAR(b.lo.y, 0.0, 1e-6);
  EXPECT_NEAR(b.lo.x + b.hi.x, 0.0, 1e-5);
  EXPECT_NEAR(scale_to_length(o, 3.0), 0.5, 1e-9);
  EXPECT_THROW(to_object_frame(Mesh{}), Error);
  Placement bad;
  bad.scale = 0.0;
  EXPECT_THROW(placed_mesh(o, bad), Error);
}

}  // namespace
}  // namespace sl::test
