// The unprojected RGBα volume of the lighting predictor's volume branch (Sec 3.2).
#include "train/unprojection.h"

#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

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

// The plain pixel loop unproject_rgba() replaced (issue 52): everything in float64, one thread.
Tensor plain_unprojection(const Tensor& image, const Tensor& depth, const Camera& camera, const VsgGrid& grid) {
  const int64_t h = image.size(1), w = image.size(2);
  const int64_t X = grid.dims[0], Y = grid.dims[1], Z = grid.dims[2], nvox = X * Y * Z;
  const std::vector<double> rgb = image.to(DType::F64).contiguous().to_vector();
  const std::vector<double> z = depth.to(DType::F64).contiguous().to_vector();
  std::vector<double> acc(static_cast<size_t>(4 * nvox), 0.0);
  for (int64_t r = 0; r < h; ++r)
    for (int64_t c = 0; c < w; ++c) {
      const double d = z[static_cast<size_t>(r * w + c)];
      if (!(std::isfinite(d) && d > 0)) continue;
      const glm::dvec3 p = camera.unproject(c + 0.5, r + 0.5, d);
      if (!grid.contains(p)) continue;
      const glm::dvec3 v = grid.to_voxel(p);
      const int64_t ix = std::clamp<int64_t>(static_cast<int64_t>(std::floor(v.x)), 0, X - 1);
      const int64_t iy = std::clamp<int64_t>(static_cast<int64_t>(std::floor(v.y)), 0, Y - 1);
      const int64_t iz = std::clamp<int64_t>(static_cast<int64_t>(std::floor(v.z)), 0, Z - 1);
      const int64_t vox = (ix * Y + iy) * Z + iz;
      for (int ch = 0; ch < 3; ++ch) acc[static_cast<size_t>(ch * nvox + vox)] += rgb[static_cast<size_t>((ch * h + r) * w + c)];
      acc[static_cast<size_t>(3 * nvox + vox)] += 1.0;
    }
  for (int64_t vox = 0; vox < nvox; ++vox) {
    double& count = acc[static_cast<size_t>(3 * nvox + vox)];
    if (count <= 0) continue;
    for (int ch = 0; ch < 3; ++ch) {
      double& v = acc[static_cast<size_t>(ch * nvox + vox)];
      v = std::isfinite(v / count) ? v / count : 0.0;
    }
    count = 1.0;
  }
  return Tensor::from_vector(acc, {4, X, Y, Z});
}

// The voxel of each pixel is found in parallel and the sums run in pixel order on one thread, so
// the result is the plain loop's, bit for bit, for float32 and float64 inputs and 1 or 2 threads
// (with holes: 0, negative, NaN and inf depths, and points outside the grid).
TEST(Unprojection, EqualsThePlainPixelLoopBitForBit) {
  const int64_t H = 48, W = 96;
  const Camera cam(intrinsics_from_fov(1.2, W, H), rotation_from_yaw_pitch_roll(0.3, 0.05, 0), {2, 1.6, -1});
  VsgGrid grid;
  grid.dims = {16, 16, 8};
  grid.center = {2, 1.6, -1};
  const Tensor image = Tensor::uniform({3, H, W}, 0.0, 1.0, 5);
  Tensor depth = Tensor::uniform({H, W}, -5.0, 400.0, 6);
  float* d = depth.data<float>();
  d[3] = 0.0f, d[7] = std::numeric_limits<float>::quiet_NaN(), d[11] = std::numeric_limits<float>::infinity();
  const int threads = omp_get_max_threads();
  for (const DType t : {DType::F32, DType::F64}) {
    const Tensor im = image.to(t), dp = depth.to(t);
    const Tensor expect = plain_unprojection(im, dp, cam, grid);
    ASSERT_GT(sum(select(expect, 0, 3)).item(), 10.0);  // enough occupied voxels to mean something
    for (const int n : {1, 2}) {
      omp_set_num_threads(n);
      const Tensor got = unproject_rgba(im, dp, cam, grid);
      EXPECT_EQ(got.dtype(), DType::F32);
      EXPECT_EQ(max(abs(sub(got, expect))).item(), 0.0) << "threads " << n;
    }
  }
  omp_set_num_threads(threads);
}

}  // namespace
}  // namespace sl::test
