#include "render/vsg_volume.h"

#include <algorithm>
#include <cmath>

#include "autodiff/ops.h"

namespace sl::render {
namespace {

// World axis feeding each voxel axis: X <- x, Y <- z, Z <- y.
constexpr int kWorldAxisOf[3] = {0, 2, 1};

double log_forward(double d, double h_neg, double h_pos, double r0) {
  if (d >= 0) return std::log1p(d / r0) / std::log1p(h_pos / r0);
  return -std::log1p(-d / r0) / std::log1p(h_neg / r0);
}

double log_inverse(double s, double h_neg, double h_pos, double r0) {
  if (s >= 0) return r0 * std::expm1(s * std::log1p(h_pos / r0));
  return -r0 * std::expm1(-s * std::log1p(h_neg / r0));
}

}  // namespace

void VsgGrid::validate() const {
  for (int a = 0; a < 3; ++a) {
    SL_CHECK(dims[a] >= 1, "VsgGrid: dims[", a, "] = ", dims[a], " must be >= 1");
    SL_CHECK(extent_neg[a] > 0 && extent_pos[a] > 0 && std::isfinite(extent_neg[a]) && std::isfinite(extent_pos[a]),
             "VsgGrid: extents must be positive and finite, got axis ", a, ": ", extent_neg[a], ", ", extent_pos[a]);
  }
  SL_CHECK(log_scale_m > 0 && std::isfinite(log_scale_m), "VsgGrid: log_scale_m = ", log_scale_m, " must be > 0");
}

glm::dvec3 VsgGrid::to_voxel(const glm::dvec3& world) const {
  glm::dvec3 v;
  for (int a = 0; a < 3; ++a) {
    const int w = kWorldAxisOf[a];
    const double s = log_forward(world[w] - center[w], extent_neg[w], extent_pos[w], log_scale_m);
    v[a] = (s + 1.0) * 0.5 * static_cast<double>(dims[a]);
  }
  return v;
}

glm::dvec3 VsgGrid::to_world(const glm::dvec3& voxel) const {
  glm::dvec3 p;
  for (int a = 0; a < 3; ++a) {
    const int w = kWorldAxisOf[a];
    const double s = voxel[a] / static_cast<double>(dims[a]) * 2.0 - 1.0;
    p[w] = center[w] + log_inverse(s, extent_neg[w], extent_pos[w], log_scale_m);
  }
  return p;
}

bool VsgGrid::contains(const glm::dvec3& world) const {
  for (int w = 0; w < 3; ++w) {
    const double d = world[w] - center[w];
    if (!(d >= -extent_neg[w] && d <= extent_pos[w])) return false;
  }
  return true;
}

bool VsgGrid::clip_ray(const glm::dvec3& origin, const glm::dvec3& dir, double& t0, double& t1) const {
  t0 = 0.0;
  t1 = std::numeric_limits<double>::infinity();
  for (int w = 0; w < 3; ++w) {
    const double lo = center[w] - extent_neg[w], hi = center[w] + extent_pos[w];
    if (std::abs(dir[w]) < 1e-300) {
      if (origin[w] < lo || origin[w] > hi) return false;
      continue;
    }
    double a = (lo - origin[w]) / dir[w], b = (hi - origin[w]) / dir[w];
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
  }
  return t1 > t0 && std::isfinite(t1);
}

Tensor vsg_activate(const Tensor& raw, int64_t channel_dim) {
  const int64_t d = normalize_dim("vsg_activate", channel_dim, raw.dim());
  SL_CHECK(raw.size(d) == 8, "vsg_activate: expected 8 channels in dim ", channel_dim, ", got ", raw.describe());
  const Tensor c = softplus(slice(raw, d, 0, 3));
  const Tensor mu = slice(raw, d, 3, 6);
  const Tensor sharp = add_scalar(softplus(slice(raw, d, 6, 7)), VsgGrid::kMinSharpness);
  const Tensor alpha = sigmoid(slice(raw, d, 7, 8));
  return concat({c, mu, sharp, alpha}, d);
}

}  // namespace sl::render
