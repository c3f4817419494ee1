#include "render/vsg_volume.h"

#include <algorithm>
#include <cmath>

#include "autodiff/ops.h"
#include "autodiff/tape.h"
#include "autodiff/vector_math.h"
#include "util/parallel.h"

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

VoxelMapper::VoxelMapper(const VsgGrid& g) : center_(g.center), r0_(g.log_scale_m) {
  for (int a = 0; a < 3; ++a) {
    const int w = kWorldAxisOf[a];
    denom_neg_[a] = std::log1p(g.extent_neg[w] / r0_);
    denom_pos_[a] = std::log1p(g.extent_pos[w] / r0_);
    dims_[a] = static_cast<double>(g.dims[a]);
  }
}

glm::dvec3 VoxelMapper::operator()(const glm::dvec3& world) const {
  glm::dvec3 v;
  for (int a = 0; a < 3; ++a) {
    // log_forward with its denominator log1p(h/r0) precomputed: the same operations on the same
    // values, so the same bits.
    const double d = world[kWorldAxisOf[a]] - center_[kWorldAxisOf[a]];
    const double s = d >= 0 ? std::log1p(d / r0_) / denom_pos_[a] : -std::log1p(-d / r0_) / denom_neg_[a];
    v[a] = (s + 1.0) * 0.5 * dims_[a];
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

namespace {

// Which activation channel k of the 8 takes.
enum class VsgChannel { Softplus, Identity, SoftplusFloor, Sigmoid };
VsgChannel vsg_channel(int64_t k) {
  return k < 3 ? VsgChannel::Softplus : k < 6 ? VsgChannel::Identity : k == 6 ? VsgChannel::SoftplusFloor : VsgChannel::Sigmoid;
}

// Float32 contiguous input: all four activations as ONE op, a pass over each channel row with
// the vectorised kernels the separate ops use (vm::softplus, vm::sigmoid; the backward
// vm::softplus_backward and sigmoid's g·y·(1 - y)), so values and gradients are bitwise those
// of the composite path below, without its slices, concat and the zero-filled slice gradients.
Tensor vsg_activate_rows(const Tensor& raw, int64_t d) {
  int64_t outer = 1, inner = 1;
  for (int64_t a = 0; a < d; ++a) outer *= raw.size(a);
  for (int64_t a = d + 1; a < raw.dim(); ++a) inner *= raw.size(a);
  const Tensor x = raw.detach();
  Tensor y = Tensor::empty(raw.shape(), DType::F32);
  const float floor_add = static_cast<float>(VsgGrid::kMinSharpness);
  {
    const float* px = x.data<float>();
    float* py = y.data<float>();
    parallel_for(outer * 8, std::max<int64_t>(1, 32768 / std::max<int64_t>(inner, 1)), [&](int64_t r0, int64_t r1) {
      for (int64_t r = r0; r < r1; ++r) {
        const float* xr = px + r * inner;
        float* yr = py + r * inner;
        switch (vsg_channel(r % 8)) {
          case VsgChannel::Softplus: vm::softplus(xr, yr, inner); break;
          case VsgChannel::Identity: std::copy(xr, xr + inner, yr); break;
          case VsgChannel::SoftplusFloor:
            vm::softplus(xr, yr, inner);
            for (int64_t i = 0; i < inner; ++i) yr[i] = yr[i] + floor_add;  // add_scalar's float add
            break;
          case VsgChannel::Sigmoid: vm::sigmoid(xr, yr, inner); break;
        }
      }
    });
  }
  if (!needs_grad({raw})) return y;
  const Tensor yd = y.detach();
  record("vsg_activate", {raw}, {y}, [x, yd, outer, inner](const TensorList& grads) {
    const Tensor g = grads[0].contiguous();
    Tensor dx = Tensor::empty(x.shape(), DType::F32);
    const float *pg = g.data<float>(), *px = x.data<float>(), *py = yd.data<float>();
    float* pdx = dx.data<float>();
    parallel_for(outer * 8, std::max<int64_t>(1, 32768 / std::max<int64_t>(inner, 1)), [&](int64_t r0, int64_t r1) {
      for (int64_t r = r0; r < r1; ++r) {
        const int64_t o = r * inner;
        switch (vsg_channel(r % 8)) {
          case VsgChannel::Softplus:
          case VsgChannel::SoftplusFloor: vm::softplus_backward(pg + o, px + o, pdx + o, inner); break;
          case VsgChannel::Identity: std::copy(pg + o, pg + o + inner, pdx + o); break;
          case VsgChannel::Sigmoid: {
            const float *gr = pg + o, *yr = py + o;
            float* dr = pdx + o;
            for (int64_t i = 0; i < inner; ++i) dr[i] = gr[i] * yr[i] * (1.0f - yr[i]);
            break;
          }
        }
      }
    });
    return TensorList{dx};
  });
  return y;
}

}  // namespace

Tensor vsg_activate(const Tensor& raw, int64_t channel_dim) {
  const int64_t d = normalize_dim("vsg_activate", channel_dim, raw.dim());
  SL_CHECK(raw.size(d) == 8, "vsg_activate: expected 8 channels in dim ", channel_dim, ", got ", raw.describe());
  if (raw.dtype() == DType::F32 && raw.is_contiguous()) return vsg_activate_rows(raw, d);
  const Tensor c = softplus(slice(raw, d, 0, 3));
  const Tensor mu = slice(raw, d, 3, 6);
  const Tensor sharp = add_scalar(softplus(slice(raw, d, 6, 7)), VsgGrid::kMinSharpness);
  const Tensor alpha = sigmoid(slice(raw, d, 7, 8));
  return concat({c, mu, sharp, alpha}, d);
}

}  // namespace sl::render
