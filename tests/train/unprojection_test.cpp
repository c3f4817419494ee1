// The unprojected RGBα volume of the lighting predictor's volume branch (Sec 3.2).
#include "train/unprojection.h"

#include <gtest/gtest.h>

#include "autodiff/ops.h"
#include "render/camera.h"
#include "render/vsg_volume.h"

using sl::render::Camera;
using sl::render::intrinsics_from_fov;
using sl::render::rotation_from_yaw_pitch_roll;
using sl::render::VsgGrid;

namespace sl::test {
using train::unproject_rgba;

namespace {

TEST(Unprojection, APixelLandsInItsVoxelWithUnitAlpha) {
  const Camera cam(intrinsics_from_fov(1.2, 4, 2), rotation_from_yaw_pitch_roll(0, 0, 0), {0, 1.6, 0});
  VsgGrid grid;
  grid.dims = {8, 8, 4};
  grid.center = {0, 1.6, 0};
  Tensor image = Tensor::zeros({3, 2, 4});
  image.data<float>()[0] = 0.5f;  // red of pixel (0, 0)
  Tensor depth = Tensor::zeros({2, 4});
  depth.data<float>()[0] = 10.0f;  // only pixel (0, 0) has depth
  const Tensor v = unproject_rgba(image, depth, cam, grid);
  ASSERT_EQ(v.shape(), (Shape{4, 8, 8, 4}));
  const glm::dvec3 vox = grid.to_voxel(cam.unproject(0.5, 0.5, 10.0));
  const int64_t ix = static_cast<int64_t>(vox.x), iy = static_cast<int64_t>(vox.y), iz = static_cast<int64_t>(vox.z);
  EXPECT_FLOAT_EQ(v.at({3, ix, iy, iz}), 1.0f);
  EXPECT_FLOAT_EQ(v.at({0, ix, iy, iz}), 0.5f);
  EXPECT_DOUBLE_EQ(sum(select(v, 0, 3)).item(), 1.0);
}

}  // namespace
}  // namespace sl::test
