// The residual filter of object insertion (see insertion_denoise.h).
#include "render/insertion_denoise.h"

#include <cmath>

#include "util/parallel.h"

namespace sl::render::insertion {

std::vector<glm::vec3> denoise_residual(const std::vector<DenoisePixel>& px, const PixelWindow& window,
                                        const InsertionOptions& opt) {
  std::vector<glm::vec3> out(px.size());
  const int r = opt.denoise_radius;
  if (r <= 0) {
    for (size_t p = 0; p < px.size(); ++p) out[p] = px[p].residual;
    return out;
  }
  const float sn = float(opt.denoise_normal_sigma), sz = float(opt.denoise_depth_sigma);
  const float sv2 = float(opt.denoise_variance_sigma * opt.denoise_variance_sigma);
  // ρ = ΣR/ΣC and its variance v/(ΣC)², per pixel (ρ = 0, variance ∞ where C is 0).
  std::vector<float> ratio(px.size(), 0.0f), ratio_var(px.size(), INFINITY);
  for (size_t p = 0; p < px.size(); ++p) {
    const float c = px[p].control.x + px[p].control.y + px[p].control.z;
    if (!(c > 0.0f)) continue;
    ratio[p] = (px[p].residual.x + px[p].residual.y + px[p].residual.z) / c;
    ratio_var[p] = px[p].variance / (c * c);
  }
  parallel_for(int64_t(px.size()), 256, [&](int64_t b, int64_t e) {
    for (int64_t ip = b; ip < e; ++ip) {
      const size_t p = size_t(ip);
      const DenoisePixel& a = px[p];
      glm::vec3 sr(0.0f), sc(0.0f);
      window.for_neighbours(p, r, [&](size_t q) {
        const DenoisePixel& o = px[q];
        float x = (1.0f - glm::dot(a.normal, o.normal)) / sn;
        if (a.depth > 0.0f) x += std::abs(glm::dot(a.normal, o.position - a.position)) / (sz * a.depth);
        const float v = ratio_var[p] + ratio_var[q];
        if (sv2 > 0.0f && std::isfinite(v)) x += (ratio[p] - ratio[q]) * (ratio[p] - ratio[q]) / (sv2 * v + 1e-30f);
        const float w = q == p ? 1.0f : std::exp(-x);
        if (!(w > 0.0f)) return;
        sr += w * o.residual;
        sc += w * o.control;
      });
      for (int c = 0; c < 3; ++c) out[p][c] = sc[c] > 0.0f ? a.control[c] * sr[c] / sc[c] : a.residual[c];
      if (!std::isfinite(out[p].x + out[p].y + out[p].z)) out[p] = a.residual;
    }
  });
  return out;
}

}  // namespace sl::render::insertion
