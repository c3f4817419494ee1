// RGBα unprojection onto the VSG grid. See unprojection.h.
#include "train/unprojection.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "util/parallel.h"

using sl::render::Camera;
using sl::render::VsgGrid;

namespace sl::train {

Tensor unproject_rgba(const Tensor& image, const Tensor& depth, const Camera& camera, const VsgGrid& grid) {
  SL_CHECK(image.dim() == 3 && image.size(0) == 3, "unproject_rgba: image must be [3, H, W], got ", image.describe());
  SL_CHECK(depth.dim() == 2 && depth.size(0) == image.size(1) && depth.size(1) == image.size(2),
           "unproject_rgba: depth ", depth.describe(), " does not match image ", image.describe());
  const auto& k = camera.intrinsics();
  SL_CHECK(k.width == image.size(2) && k.height == image.size(1), "unproject_rgba: camera is ", k.width, "×", k.height,
           ", image ", image.describe());
  grid.validate();
  const int64_t h = image.size(1), w = image.size(2);
  const int64_t X = grid.dims[0], Y = grid.dims[1], Z = grid.dims[2], nvox = X * Y * Z;
  // Values are read as doubles (float -> double is exact, so F32 inputs are read in place).
  const Tensor rgb_t = image.dtype() == DType::F32 ? image.contiguous() : image.to(DType::F64).contiguous();
  const Tensor z_t = depth.dtype() == DType::F32 ? depth.contiguous() : depth.to(DType::F64).contiguous();
  const bool rgb_f32 = rgb_t.dtype() == DType::F32, z_f32 = z_t.dtype() == DType::F32;
  const auto rgb = [&](int64_t i) {
    return rgb_f32 ? static_cast<double>(rgb_t.data<float>()[i]) : rgb_t.data<double>()[i];
  };
  const auto zval = [&](int64_t i) { return z_f32 ? static_cast<double>(z_t.data<float>()[i]) : z_t.data<double>()[i]; };
  // Each pixel's voxel (-1: a hole or outside the grid), in parallel: the projection is the cost.
  // The sums below then run in pixel order on one thread, so the result does not depend on the
  // thread count (and equals the plain loop's bits).
  std::vector<int64_t> voxel(static_cast<size_t>(h * w));
  const render::VoxelMapper to_voxel(grid);  // grid.to_voxel, bit for bit, its constants computed once
  // Chunks of at least 64K pixels (as nn/functional/work_grain.h): a training view (256×128) stays
  // on the calling thread, a KITTI photo (1242×375) is 8 chunks.
  parallel_for(h, std::max<int64_t>(1, (int64_t{1} << 16) / std::max<int64_t>(w, 1)), [&](int64_t r0, int64_t r1) {
    for (int64_t r = r0; r < r1; ++r)
      for (int64_t c = 0; c < w; ++c) {
        int64_t& out = voxel[static_cast<size_t>(r * w + c)];
        out = -1;
        const double d = zval(r * w + c);
        if (!(std::isfinite(d) && d > 0)) continue;
        const glm::dvec3 p = camera.unproject(c + 0.5, r + 0.5, d);
        if (!grid.contains(p)) continue;
        const glm::dvec3 v = to_voxel(p);
        const int64_t ix = std::clamp<int64_t>(static_cast<int64_t>(std::floor(v.x)), 0, X - 1);
        const int64_t iy = std::clamp<int64_t>(static_cast<int64_t>(std::floor(v.y)), 0, Y - 1);
        const int64_t iz = std::clamp<int64_t>(static_cast<int64_t>(std::floor(v.z)), 0, Z - 1);
        out = (ix * Y + iy) * Z + iz;
      }
  });
  std::vector<double> acc(static_cast<size_t>(4 * nvox), 0.0);
  for (int64_t i = 0; i < h * w; ++i) {
    const int64_t vox = voxel[static_cast<size_t>(i)];
    if (vox < 0) continue;
    for (int ch = 0; ch < 3; ++ch) acc[static_cast<size_t>(ch * nvox + vox)] += rgb(ch * h * w + i);
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

}  // namespace sl::train
