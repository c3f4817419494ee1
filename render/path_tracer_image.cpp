// Reference path tracer: the image loop (camera rays, sub-pixel jitter, auxiliary outputs).
// path_tracer.cpp holds the per-path estimator.
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "render/camera.h"
#include "render/path_tracer.h"
#include "util/error.h"
#include "util/random.h"

namespace sl::render {

PathTracerImage PathTracer::render(const Camera& camera, const PathTracerOptions& options) const {
  validate(options);
  const Intrinsics& k = camera.intrinsics();
  const int W = k.width, H = k.height;
  SL_CHECK(W >= 1 && H >= 1, "PathTracer::render: camera image size must be positive, got ", W, "x", H);

  PathTracerImage out;
  out.radiance = Tensor::zeros({3, H, W});
  out.depth = Tensor::zeros({1, H, W});
  out.normal = Tensor::zeros({3, H, W});
  out.mask = Tensor::zeros({1, H, W});
  float* rad = out.radiance.data<float>();
  float* depth = out.depth.data<float>();
  float* normal = out.normal.data<float>();
  float* mask = out.mask.data<float>();
  const size_t plane = static_cast<size_t>(H) * W;
  const glm::dvec3 forward = camera.rotation()[2];  // camera +z in world coordinates
  std::vector<int64_t> row_nonfinite(H, 0);

  // Rows are independent and every random number is keyed by (pixel, counter), so the
  // schedule cannot change a single bit of the result.
#pragma omp parallel for schedule(dynamic, 1)
  for (int row = 0; row < H; ++row) {
    for (int col = 0; col < W; ++col) {
      const uint64_t pixel = static_cast<uint64_t>(row) * W + col;
      const size_t o = pixel;
      glm::dvec3 sum(0.0);
      for (int k = 0; k < options.spp; ++k) {
        const uint64_t s = static_cast<uint64_t>(options.sample_offset) + k;
        const glm::vec2 jitter = pixel_jitter(pixel, s, options);
        const sl::render::CameraRay r = camera.ray(col + double(jitter.x), row + double(jitter.y));
        const glm::vec3 L = radiance(glm::vec3(r.origin), glm::vec3(r.direction), pixel, s, options);
        if (std::isfinite(L.x) && std::isfinite(L.y) && std::isfinite(L.z))
          sum += glm::dvec3(L);
        else
          ++row_nonfinite[row];
      }
      sum /= options.spp;
      // Finite samples can still sum past the float range (a 10^38 sun); keep the output finite.
      for (int ch = 0; ch < 3; ++ch) rad[ch * plane + o] = static_cast<float>(std::min(sum[ch], 3.0e38));

      const sl::render::CameraRay centre = camera.pixel_ray(col, row);
      const PrimaryHit h = first_hit(glm::vec3(centre.origin), glm::vec3(centre.direction));
      if (h.hit) {
        mask[o] = 1.0f;
        depth[o] = static_cast<float>(h.distance * glm::dot(centre.direction, forward));
        for (int ch = 0; ch < 3; ++ch) normal[ch * plane + o] = h.normal[ch];
      }
    }
  }
  for (int64_t n : row_nonfinite) out.nonfinite_samples += n;
  return out;
}

}  // namespace sl::render
