#include "data/panorama.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "render/equirect.h"
#include "util/math.h"
#include "util/parallel.h"

using sl::render::Camera;
using sl::render::Intrinsics;
using sl::render::intrinsics_from_fov;
using sl::render::rotation_from_yaw_pitch_roll;

namespace sl::data {

namespace {

struct Dims {
  int c, h, w;
};

Dims dims_of(const Tensor& pano) {
  return {static_cast<int>(pano.size(0)), static_cast<int>(pano.size(1)),
          static_cast<int>(pano.size(2))};
}

int wrap(int64_t j, int w) {
  const int64_t m = j % w;
  return static_cast<int>(m < 0 ? m + w : m);
}

// One input interval's share of an output interval: (input index, weight).
struct Overlap {
  int index;
  double weight;
};

// For output cells [k·n/m, (k+1)·n/m) over n input cells, the overlapping input cells with a
// weight measure(a, b) of each overlap [a, b] (in input-cell units).
template <class Measure>
std::vector<std::vector<Overlap>> overlaps(int n, int m, Measure measure) {
  std::vector<std::vector<Overlap>> out(static_cast<size_t>(m));
  const double scale = static_cast<double>(n) / m;
  for (int k = 0; k < m; ++k) {
    const double a = k * scale, b = (k + 1) * scale;
    for (int i = static_cast<int>(std::floor(a)); i < n && i < b; ++i) {
      const double lo = std::max(a, static_cast<double>(i)), hi = std::min(b, i + 1.0);
      if (hi > lo) out[static_cast<size_t>(k)].push_back({i, measure(lo, hi)});
    }
  }
  return out;
}

}  // namespace

void check_panorama(const Tensor& pano, const char* op) {
  SL_CHECK(pano.defined() && pano.dim() == 3, op, ": expected a panorama [C, H, W], got ",
           pano.defined() ? pano.describe() : "undefined");
  SL_CHECK(pano.dtype() == DType::F32, op, ": expected an F32 panorama, got ", pano.describe());
  SL_CHECK(pano.size(0) >= 1 && pano.size(1) >= 1 && pano.size(2) >= 1, op,
           ": empty panorama ", pano.describe());
  SL_CHECK(pano.is_contiguous(), op, ": expected a contiguous panorama, got a strided view of ",
           pano.describe());
}

glm::dvec3 rotate_direction_azimuth(const glm::dvec3& d, double delta) {
  // φ = atan2(x, −z): a rotation about +Y by −delta adds delta to every azimuth.
  const double c = std::cos(delta), s = std::sin(delta);
  return {d.x * c - d.z * s, d.y, d.z * c + d.x * s};
}

Tensor rotate_azimuth(const Tensor& pano, double delta_rad) {
  check_panorama(pano, "rotate_azimuth");
  SL_CHECK(std::isfinite(delta_rad), "rotate_azimuth: delta_rad must be finite, got ", delta_rad);
  const Dims d = dims_of(pano);
  // u_out = u_in + shift, so out(j) = in(j − shift).
  double shift = std::fmod(delta_rad / kTwoPi * d.w, static_cast<double>(d.w));
  if (shift < 0) shift += d.w;
  const double whole = std::nearbyint(shift);
  const bool exact = std::fabs(shift - whole) < 1e-9;
  const int64_t base = static_cast<int64_t>(std::floor(shift));
  const float frac = static_cast<float>(shift - std::floor(shift));
  Tensor out = Tensor::empty(pano.shape(), DType::F32);
  const float* src = pano.data<float>();
  float* dst = out.data<float>();
  parallel_for(static_cast<int64_t>(d.c) * d.h, 8, [&](int64_t r0, int64_t r1) {
    for (int64_t r = r0; r < r1; ++r) {
      const float* in = src + r * d.w;
      float* o = dst + r * d.w;
      for (int j = 0; j < d.w; ++j) {
        if (exact) {
          o[j] = in[wrap(j - static_cast<int64_t>(whole), d.w)];
        } else {
          // out(j) = (1−f)·in(j − base) + f·in(j − base − 1)
          o[j] = (1.0f - frac) * in[wrap(j - base, d.w)] + frac * in[wrap(j - base - 1, d.w)];
        }
      }
    }
  });
  return out;
}

Tensor resize_area(const Tensor& pano, int out_h, int out_w) {
  check_panorama(pano, "resize_area");
  SL_CHECK(out_h >= 1 && out_w >= 1, "resize_area: output size must be ≥ 1, got ", out_h, "x",
           out_w);
  const Dims d = dims_of(pano);
  // Row weights in solid angle: a band [v0, v1] of input rows has measure sin θ(v0) − sin θ(v1).
  const auto rows = overlaps(d.h, out_h, [&](double a, double b) {
    return std::sin((0.5 - a / d.h) * kPi) - std::sin((0.5 - b / d.h) * kPi);
  });
  const auto cols = overlaps(d.w, out_w, [](double a, double b) { return b - a; });
  Tensor out = Tensor::empty({d.c, out_h, out_w}, DType::F32);
  const float* src = pano.data<float>();
  float* dst = out.data<float>();
  parallel_for(static_cast<int64_t>(d.c) * out_h, 1, [&](int64_t r0, int64_t r1) {
    std::vector<double> row_acc(static_cast<size_t>(d.w));
    for (int64_t r = r0; r < r1; ++r) {
      const int c = static_cast<int>(r / out_h), k = static_cast<int>(r % out_h);
      std::fill(row_acc.begin(), row_acc.end(), 0.0);
      double row_weight = 0.0;
      for (const Overlap& ro : rows[static_cast<size_t>(k)]) {
        const float* in = src + (static_cast<int64_t>(c) * d.h + ro.index) * d.w;
        for (int j = 0; j < d.w; ++j) row_acc[static_cast<size_t>(j)] += ro.weight * in[j];
        row_weight += ro.weight;
      }
      float* o = dst + r * out_w;
      for (int l = 0; l < out_w; ++l) {
        double acc = 0.0, weight = 0.0;
        for (const Overlap& co : cols[static_cast<size_t>(l)]) {
          acc += co.weight * row_acc[static_cast<size_t>(co.index)];
          weight += co.weight;
        }
        o[l] = row_weight > 0.0 ? static_cast<float>(acc / (weight * row_weight)) : 0.0f;
      }
    }
  });
  return out;
}

double radiant_power(const Tensor& pano, int channel) {
  check_panorama(pano, "radiant_power");
  const Dims d = dims_of(pano);
  SL_CHECK(channel >= 0 && channel < d.c, "radiant_power: channel ", channel,
           " out of range for ", pano.describe());
  const float* p = pano.data<float>() + static_cast<int64_t>(channel) * d.h * d.w;
  return deterministic_sum(static_cast<int64_t>(d.h) * d.w, [&](int64_t i) {
    return p[i] * render::equirect::pixel_solid_angle(static_cast<int>(i / d.w), d.w, d.h);
  });
}

void sample_bilinear(const float* pano, int channels, int height, int width, double u, double v,
                     float* out) {
  const double x = u - 0.5;
  const double y = std::clamp(v - 0.5, 0.0, static_cast<double>(height - 1));
  const double xf = std::floor(x), yf = std::floor(y);
  const float fx = static_cast<float>(x - xf), fy = static_cast<float>(y - yf);
  const int j0 = wrap(static_cast<int64_t>(xf), width), j1 = wrap(static_cast<int64_t>(xf) + 1, width);
  const int i0 = static_cast<int>(yf), i1 = std::min(i0 + 1, height - 1);
  const int64_t plane = static_cast<int64_t>(height) * width;
  for (int c = 0; c < channels; ++c) {
    const float* p = pano + c * plane;
    const float top = (1 - fx) * p[i0 * width + j0] + fx * p[i0 * width + j1];
    const float bottom = (1 - fx) * p[i1 * width + j0] + fx * p[i1 * width + j1];
    out[c] = (1 - fy) * top + fy * bottom;
  }
}

PerspectiveCrop crop_perspective(const Tensor& pano, const PerspectiveCropParams& params) {
  check_panorama(pano, "crop_perspective");
  SL_CHECK(params.width >= 1 && params.height >= 1, "crop_perspective: crop size must be ≥ 1, got ",
           params.width, "x", params.height);
  const Dims d = dims_of(pano);
  const Intrinsics k = intrinsics_from_fov(params.horizontal_fov_rad, params.width, params.height);
  PerspectiveCrop crop;
  crop.camera = Camera(k, rotation_from_yaw_pitch_roll(params.yaw_rad, params.pitch_rad, params.roll_rad),
                       glm::dvec3(0.0));
  crop.image = Tensor::empty({d.c, params.height, params.width}, DType::F32);
  const float* src = pano.data<float>();
  float* dst = crop.image.data<float>();
  const int64_t plane = static_cast<int64_t>(params.width) * params.height;
  parallel_for(params.height, 4, [&](int64_t r0, int64_t r1) {
    std::vector<float> value(static_cast<size_t>(d.c));
    for (int64_t row = r0; row < r1; ++row)
      for (int col = 0; col < params.width; ++col) {
        const glm::dvec3 dir = crop.camera.pixel_ray(col, static_cast<int>(row)).direction;
        const auto uv = render::equirect::direction_to_uv(dir.x, dir.y, dir.z, d.w, d.h);
        sample_bilinear(src, d.c, d.h, d.w, uv.u, uv.v, value.data());
        for (int c = 0; c < d.c; ++c) dst[c * plane + row * params.width + col] = value[static_cast<size_t>(c)];
      }
  });
  return crop;
}

Tensor to_ldr(const Tensor& hdr, double exposure) {
  SL_CHECK(hdr.defined() && hdr.dtype() == DType::F32 && hdr.is_contiguous(),
           "to_ldr: expected a contiguous F32 tensor, got ", hdr.defined() ? hdr.describe() : "undefined");
  SL_CHECK(std::isfinite(exposure) && exposure >= 0.0, "to_ldr: exposure must be finite and ≥ 0, got ",
           exposure);
  Tensor out = Tensor::empty(hdr.shape(), DType::F32);
  const float* src = hdr.data<float>();
  float* dst = out.data<float>();
  const float e = static_cast<float>(exposure);
  parallel_for(hdr.numel(), 16384, [&](int64_t i0, int64_t i1) {
    for (int64_t i = i0; i < i1; ++i) {
      const float x = e * src[i];
      dst[i] = x > 0.0f ? std::min(1.0f, std::pow(x, 1.0f / static_cast<float>(kLdrGamma))) : 0.0f;  // NaN fails x > 0
    }
  });
  return out;
}

Tensor estimate_sky_mask(const Tensor& pano, const SkyMaskParams& params) {
  check_panorama(pano, "estimate_sky_mask");
  const Dims d = dims_of(pano);
  SL_CHECK(d.c == 3, "estimate_sky_mask: expected an RGB panorama, got ", pano.describe());
  const int64_t plane = static_cast<int64_t>(d.h) * d.w;
  const float* p = pano.data<float>();
  const int upper_rows = d.h / 2;  // rows whose centre lies above the horizon
  std::vector<double> lum(static_cast<size_t>(upper_rows) * d.w);
  for (int64_t i = 0; i < static_cast<int64_t>(lum.size()); ++i)
    lum[static_cast<size_t>(i)] = luminance(p[i], p[plane + i], p[2 * plane + i]);
  std::vector<double> sorted = lum;
  double median = 0.0;
  if (!sorted.empty()) {
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    median = sorted[sorted.size() / 2];
  }
  Tensor mask = Tensor::zeros({1, d.h, d.w}, DType::F32);
  float* m = mask.data<float>();
  for (int64_t i = 0; i < static_cast<int64_t>(lum.size()); ++i) {
    const double l = lum[static_cast<size_t>(i)];
    if (!std::isfinite(l) || !(l > 0.0)) continue;
    const double sum = static_cast<double>(p[i]) + p[plane + i] + p[2 * plane + i];
    const double blue = p[2 * plane + i] / sum;
    const bool bright = l >= params.bright_ratio * median;
    const bool blue_sky = blue >= params.blue_share && l >= params.blue_min_ratio * median;
    m[i] = bright || blue_sky ? 1.0f : 0.0f;
  }
  return mask;
}

Tensor binarize_mask(Tensor m) {
  SL_CHECK(m.defined() && m.dtype() == DType::F32 && m.is_contiguous(), "binarize_mask: expected a contiguous F32 mask, got ",
           m.defined() ? m.describe() : "undefined");
  float* p = m.data<float>();
  for (int64_t i = 0; i < m.numel(); ++i) p[i] = p[i] >= 0.5f ? 1.0f : 0.0f;
  return m;
}

}  // namespace sl::data
