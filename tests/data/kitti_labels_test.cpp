// data/kitti_labels.h: the bird's-eye footprint test that keeps inserted objects off labelled ones.
#include "data/kitti_labels.h"

#include <gtest/gtest.h>

#include <cmath>

namespace sl::test {
namespace {

using sl::data::footprints_within;

// h w l x y z ry: a car 1.8 m wide and 4.5 m long at (x, z), heading ry.
std::array<double, 7> car(double x, double z, double ry) { return {1.5, 1.8, 4.5, x, 1.6, z, ry}; }

TEST(KittiLabels, FootprintsOverlapWithinTheMarginAndNotBeyond) {
  // Side by side along x (length along x at ry = 0): centres 4.5 m apart touch; 4.6 m apart are
  // 0.1 m apart, inside a 0.3 m margin and outside a 0.05 m one.
  EXPECT_TRUE(footprints_within(car(0, 10, 0), car(4.4, 10, 0), 0.0));
  EXPECT_FALSE(footprints_within(car(0, 10, 0), car(4.6, 10, 0), 0.0));
  EXPECT_TRUE(footprints_within(car(0, 10, 0), car(4.6, 10, 0), 0.3));
  EXPECT_FALSE(footprints_within(car(0, 10, 0), car(4.6, 10, 0), 0.05));
  // Across z the width counts: 1.8 m apart touch, 2.0 m apart do not.
  EXPECT_TRUE(footprints_within(car(0, 10, 0), car(0, 11.7, 0), 0.0));
  EXPECT_FALSE(footprints_within(car(0, 10, 0), car(0, 12.0, 0), 0.0));
  // Turned by 90°, the second car's length runs along z: 4.6 m apart in x no longer separates them
  // by length, only by half a length plus half a width (2.25 + 0.9 = 3.15 m).
  EXPECT_FALSE(footprints_within(car(0, 10, 0), car(3.3, 10, M_PI / 2), 0.0));
  EXPECT_TRUE(footprints_within(car(0, 10, 0), car(3.1, 10, M_PI / 2), 0.0));
  // A diagonal gap the axis-aligned boxes would not see: both at 45°, offset along their own width.
  const double d = 2.0 / std::sqrt(2.0);
  EXPECT_FALSE(footprints_within(car(0, 10, M_PI / 4), car(d, 10 + d, M_PI / 4), 0.0));
  EXPECT_TRUE(footprints_within(car(0, 10, M_PI / 4), car(d, 10 + d, M_PI / 4), 0.3));
}

}  // namespace
}  // namespace sl::test
