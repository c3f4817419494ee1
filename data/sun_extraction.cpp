#include "data/sun_extraction.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "data/panorama.h"
#include "render/equirect.h"
#include "util/math.h"
#include "util/parallel.h"

namespace sl::data {

namespace {

glm::dvec3 texel_direction(int row, int col, int w, int h) {
  const auto d = render::equirect::uv_to_direction(col + 0.5, row + 0.5, w, h);
  return {d.x, d.y, d.z};
}

}  // namespace

SunEstimate extract_sun(const Tensor& pano, const SunExtractionParams& params) {
  check_panorama(pano, "extract_sun");
  SL_CHECK(pano.size(0) == 3, "extract_sun: expected an RGB panorama [3, H, W], got ", pano.describe());
  SL_CHECK(params.threshold_fraction > 0.0 && params.threshold_fraction < 1.0,
           "extract_sun: threshold_fraction must be in (0, 1), got ", params.threshold_fraction);
  SL_CHECK(params.region_radius_rad >= 0.0 && params.region_radius_rad < kPi,
           "extract_sun: region_radius_rad must be in [0, pi), got ", params.region_radius_rad);
  const int h = static_cast<int>(pano.size(1)), w = static_cast<int>(pano.size(2));
  const int64_t plane = static_cast<int64_t>(h) * w;
  const float* p = pano.data<float>();

  std::vector<double> lum(static_cast<size_t>(plane));
  parallel_for(plane, 16384, [&](int64_t i0, int64_t i1) {
    for (int64_t i = i0; i < i1; ++i) {
      const double l = luminance(p[i], p[plane + i], p[2 * plane + i]);
      lum[static_cast<size_t>(i)] = std::isfinite(l) && l > 0.0 ? l : 0.0;
    }
  });

  // Seed: maximum of the 3×3 box-blurred luminance (azimuth wraps, rows clamp at the poles).
  // Each row's best is found in parallel and the rows are compared in order (deterministic).
  std::vector<double> row_best(static_cast<size_t>(h), -1.0);
  std::vector<int> row_best_col(static_cast<size_t>(h), 0);
  parallel_for(h, 4, [&](int64_t r0, int64_t r1) {
    for (int64_t i = r0; i < r1; ++i)
      for (int j = 0; j < w; ++j) {
        double s = 0.0;
        for (int di = -1; di <= 1; ++di) {
          const int64_t ii = std::clamp<int64_t>(i + di, 0, h - 1);
          for (int dj = -1; dj <= 1; ++dj) s += lum[static_cast<size_t>(ii * w + (j + dj + w) % w)];
        }
        if (s > row_best[static_cast<size_t>(i)]) {
          row_best[static_cast<size_t>(i)] = s;
          row_best_col[static_cast<size_t>(i)] = j;
        }
      }
  });
  int seed_row = 0;
  for (int i = 1; i < h; ++i)
    if (row_best[static_cast<size_t>(i)] > row_best[static_cast<size_t>(seed_row)]) seed_row = i;
  SunEstimate est;
  if (!(row_best[static_cast<size_t>(seed_row)] > 0.0)) return est;
  const glm::dvec3 seed = texel_direction(seed_row, row_best_col[static_cast<size_t>(seed_row)], w, h);

  const double radius = params.region_radius_rad > 0.0
                            ? params.region_radius_rad
                            : std::max(3.0 * kPi / 180.0, 4.0 * kPi / h);
  const double cos_radius = std::cos(radius);
  // Rows that can hold texels within `radius` of the seed (plus one row of slack).
  const int row_span = static_cast<int>(std::ceil(radius / (kPi / h))) + 1;
  const int row0 = std::max(0, seed_row - row_span), row1 = std::min(h - 1, seed_row + row_span);
  struct Texel {
    int64_t index;
    glm::dvec3 direction;
    double solid_angle;
  };
  std::vector<Texel> region;
  double peak = 0.0;
  for (int i = row0; i <= row1; ++i) {
    const double omega = render::equirect::pixel_solid_angle(i, w, h);
    for (int j = 0; j < w; ++j) {
      const glm::dvec3 d = texel_direction(i, j, w, h);
      if (glm::dot(d, seed) < cos_radius) continue;
      const int64_t idx = static_cast<int64_t>(i) * w + j;
      region.push_back({idx, d, omega});
      peak = std::max(peak, lum[static_cast<size_t>(idx)]);
    }
  }
  // A user radius smaller than a texel can leave no positive texel in the region; the seed
  // direction is the answer then.
  const double threshold = params.threshold_fraction * peak;
  glm::dvec3 dir_acc(0.0), power(0.0);
  double omega_sum = 0.0;
  for (const Texel& t : region) {
    const double l = lum[static_cast<size_t>(t.index)];
    if (l <= threshold) continue;
    dir_acc += (l - threshold) * t.solid_angle * t.direction;
    const glm::dvec3 rgb(std::max(0.0f, p[t.index]), std::max(0.0f, p[plane + t.index]),
                         std::max(0.0f, p[2 * plane + t.index]));
    power += rgb * t.solid_angle;
    omega_sum += t.solid_angle;
    ++est.texel_count;
  }
  est.found = true;
  est.direction = glm::length(dir_acc) > 0.0 ? glm::normalize(dir_acc) : seed;
  est.elevation_rad = std::asin(std::clamp(est.direction.y, -1.0, 1.0));
  est.azimuth_rad = std::atan2(est.direction.x, -est.direction.z);
  est.power_rgb = power;
  est.radiance_rgb = omega_sum > 0.0 ? power / omega_sum : glm::dvec3(0.0);
  est.peak_luminance = peak;
  return est;
}

}  // namespace sl::data
