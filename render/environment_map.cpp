#include "render/environment_map.h"

#include <algorithm>
#include <cmath>

#include "autodiff/tape.h"
#include "render/equirect.h"
#include "util/math.h"
#include "util/parallel.h"

namespace sl::render {
namespace {

bool all_finite3(const glm::vec3& d) { return std::isfinite(d.x) && std::isfinite(d.y) && std::isfinite(d.z); }

// ((i % n) + n) % n, the column i wrapped into [0, n), without a division for the columns a
// lookup meets (within one period of the panorama); the rest keep the modulo. Three dependent
// 64-bit divisions were most of env_bilinear_taps_unit's time under perf (Intel Xeon, where one
// takes about 18 cycles), and it runs for every probe read and sky lookup of the insertion.
template <class I>
I wrap_column(I i, I n) {
  if (i >= 0 && i < n) return i;
  if (i < 0 && i >= -n) return i + n;
  return ((i % n) + n) % n;
}
// (i + 1) % n for i in [0, n).
template <class I>
I next_column(I i, I n) {
  return i + 1 == n ? I(0) : i + 1;
}

// sin(elevation) at the top edge of row i (row 0 starts at the zenith, sin = 1).
double row_top_sin(int i, int height) { return std::sin((0.5 - static_cast<double>(i) / height) * kPi); }

}  // namespace

EnvTaps env_bilinear_taps(double x, double y, double z, int width, int height) {
  return env_bilinear_taps_unit(equirect::direction_to_uv(x, y, z, 1, 1), width, height);
}

// width · (φ/2π + ½) is the same product whether direction_to_uv forms it or this does.
EnvTaps env_bilinear_taps_unit(const equirect::UV& unit, int width, int height) {
  const equirect::UV uv{width * unit.u, height * unit.v};
  const double fu = uv.u - 0.5, fv = uv.v - 0.5;
  const double jf = std::floor(fu), iff = std::floor(fv);
  const double fx = fu - jf, fy = fv - iff;
  const int64_t j = static_cast<int64_t>(jf), i = static_cast<int64_t>(iff);
  const int64_t j0 = wrap_column<int64_t>(j, width), j1 = next_column<int64_t>(j0, width);
  const int64_t i0 = std::clamp<int64_t>(i, 0, height - 1), i1 = std::clamp<int64_t>(i + 1, 0, height - 1);
  return EnvTaps{{i0 * width + j0, i0 * width + j1, i1 * width + j0, i1 * width + j1},
                 {(1 - fy) * (1 - fx), (1 - fy) * fx, fy * (1 - fx), fy * fx}};
}

EnvironmentMap::EnvironmentMap(const Tensor& radiance) {
  SL_CHECK(radiance.dim() == 3 && radiance.size(0) == 3, "EnvironmentMap: radiance must be [3, H, W], got ",
           radiance.describe());
  SL_CHECK(radiance.size(1) >= 1 && radiance.size(2) >= 2, "EnvironmentMap: panorama ", radiance.describe(),
           " is too small");
  radiance_ = radiance.detach().to(DType::F32).contiguous();
  height_ = static_cast<int>(radiance_.size(1));
  width_ = static_cast<int>(radiance_.size(2));
  const float* p = radiance_.data<float>();
  const int64_t plane = static_cast<int64_t>(height_) * width_;
  rgb_.resize(static_cast<size_t>(plane) * 3);
  for (int64_t k = 0; k < plane; ++k) {
    for (int c = 0; c < 3; ++c) {
      const float v = p[c * plane + k];
      SL_CHECK(std::isfinite(v) && v >= 0.0f, "EnvironmentMap: texel (row ", k / width_, ", col ", k % width_,
               ", channel ", c, ") has radiance ", v, "; expected finite and >= 0");
      rgb_[static_cast<size_t>(k) * 3 + c] = v;
    }
  }
  build_sampling();
}

glm::vec3 EnvironmentMap::texel(int row, int col) const {
  const size_t k = (static_cast<size_t>(row) * width_ + col) * 3;
  return {rgb_[k], rgb_[k + 1], rgb_[k + 2]};
}

glm::vec3 EnvironmentMap::lookup(const glm::vec3& d) const {
  if (!(std::isfinite(d.x) && std::isfinite(d.y) && std::isfinite(d.z)) || glm::dot(d, d) <= 0.0f)
    return glm::vec3(0.0f);
  return lookup_unit(equirect::direction_to_uv(d.x, d.y, d.z, 1, 1));
}

glm::vec3 EnvironmentMap::lookup_unit(const equirect::UV& unit) const {
  const EnvTaps t = env_bilinear_taps_unit(unit, width_, height_);
  glm::vec3 v(0.0f);
  for (int k = 0; k < 4; ++k) {
    const size_t o = static_cast<size_t>(t.index[k]) * 3;
    v += static_cast<float>(t.weight[k]) * glm::vec3(rgb_[o], rgb_[o + 1], rgb_[o + 2]);
  }
  return v;
}

namespace {

// Cell row k of an H-row map: its v range and the texel rows at its top and bottom corners.
struct CellRow {
  double v0, v1;
  int top, bottom;
};
CellRow cell_row(int k, int H) {
  return {std::max(0.0, k - 0.5), std::min(double(H), k + 0.5), std::max(k - 1, 0), std::min(k, H - 1)};
}

// Solid angle per unit (u, v) area at v: cos(elevation) · (2π / W) · (π / H).
double jacobian(double v, int W, int H) {
  return std::cos((0.5 - v / H) * kPi) * (kTwoPi / W) * (kPi / H);
}

// Inverse CDF of the density ∝ lerp(x, a, b) on [0, 1] (a, b ≥ 0, not both 0).
double sample_linear(double u, double a, double b) {
  if (a == b) return u;
  const double x = u * (a + b) / (a + std::sqrt(std::max(0.0, (1 - u) * a * a + u * b * b)));
  return std::clamp(x, 0.0, 1.0);
}

}  // namespace

void EnvironmentMap::build_bilinear_sampling() {
  const int H = height_, W = width_;
  lum_.resize(static_cast<size_t>(H) * W);
  for (int i = 0; i < H; ++i)
    for (int j = 0; j < W; ++j) {
      const glm::vec3 t = texel(i, j);
      lum_[static_cast<size_t>(i) * W + j] = float(luminance(t.r, t.g, t.b));
    }
  cell_prob_.assign(static_cast<size_t>(H + 1) * W, 0.0);
  cell_col_cdf_.assign(static_cast<size_t>(H + 1) * (W + 1), 0.0);
  cell_row_cdf_.assign(static_cast<size_t>(H) + 2, 0.0);
  for (int k = 0; k <= H; ++k) {
    const CellRow r = cell_row(k, H);
    const double area_weight = (r.v1 - r.v0) * jacobian(0.5 * (r.v0 + r.v1), W, H);
    double* cdf = &cell_col_cdf_[static_cast<size_t>(k) * (W + 1)];
    for (int c = 0; c < W; ++c) {
      const int c1 = (c + 1) % W;
      const double corners = lum_[size_t(r.top) * W + c] + lum_[size_t(r.top) * W + c1] +
                             lum_[size_t(r.bottom) * W + c] + lum_[size_t(r.bottom) * W + c1];
      const double m = 0.25 * corners * area_weight;
      cell_prob_[static_cast<size_t>(k) * W + c] = m;
      cdf[c + 1] = cdf[c] + m;
    }
    cell_row_cdf_[k + 1] = cell_row_cdf_[k] + cdf[W];
  }
  const double total = cell_row_cdf_[H + 1];
  if (!(total > 0.0)) {  // cannot happen when some texel is positive; fall back to the texel sampler
    cell_prob_.clear();
    return;
  }
  for (double& m : cell_prob_) m /= total;
  for (double& c : cell_row_cdf_) c /= total;
  for (int k = 0; k <= H; ++k) {
    double* cdf = &cell_col_cdf_[static_cast<size_t>(k) * (W + 1)];
    const double mass = cdf[W];
    for (int c = 0; c <= W; ++c) cdf[c] = mass > 0 ? cdf[c] / mass : static_cast<double>(c) / W;
  }
  auto guide = [](const double* cdf, int n, int* out) {
    int k = 0;
    for (int i = 0; i < n; ++i) {
      const double u = double(i) / n;
      while (k < n - 1 && cdf[k + 1] <= u) ++k;
      out[i] = k;
    }
  };
  cell_row_guide_.assign(static_cast<size_t>(H) + 1, 0);
  guide(cell_row_cdf_.data(), H + 1, cell_row_guide_.data());
  cell_col_guide_.assign(static_cast<size_t>(H + 1) * W, 0);
  for (int k = 0; k <= H; ++k)
    guide(&cell_col_cdf_[static_cast<size_t>(k) * (W + 1)], W, &cell_col_guide_[static_cast<size_t>(k) * W]);
}

EnvironmentMap::Sample EnvironmentMap::sample_bilinear(float u1, float u2) const {
  if (cell_prob_.empty()) return sample(u1, u2);  // black map: the uniform sphere (as pdf_bilinear)
  Sample s;
  s.direction = sample_bilinear_direction(u1, u2);
  s.radiance = lookup(s.direction);
  s.pdf = pdf_bilinear(s.direction);
  return s;
}

glm::vec3 EnvironmentMap::sample_bilinear_direction(float u1, float u2) const {
  equirect::UV unit;
  return sample_bilinear_direction(u1, u2, unit);
}

glm::vec3 EnvironmentMap::sample_bilinear_direction(float u1, float u2, equirect::UV& unit) const {
  if (cell_prob_.empty()) {
    const glm::vec3 d = sample(u1, u2).direction;
    unit = equirect::direction_to_uv(d.x, d.y, d.z, 1, 1);
    return d;
  }
  const int H = height_, W = width_;
  // The cell k with cdf[k] <= u < cdf[k + 1] (the last such k: upper_bound − 1, clamped to a
  // cell), searched forward from the guide table's entry for u.
  auto pick = [](const double* cdf, const int* guide, int n, double u, double& frac) {
    int k = guide[std::clamp(static_cast<int>(u * n), 0, n - 1)];
    while (k > 0 && cdf[k] > u) --k;  // u·n rounded up into the next entry
    while (k < n - 1 && cdf[k + 1] <= u) ++k;
    while (k > 0 && cdf[k + 1] - cdf[k] <= 0.0) --k;
    while (k < n - 1 && cdf[k + 1] - cdf[k] <= 0.0) ++k;
    const double w = cdf[k + 1] - cdf[k];
    frac = w > 0 ? std::clamp((u - cdf[k]) / w, 0.0, 1.0) : 0.5;
    return k;
  };
  double fr, fc;
  const int k = pick(cell_row_cdf_.data(), cell_row_guide_.data(), H + 1, u1, fr);
  const int c = pick(&cell_col_cdf_[static_cast<size_t>(k) * (W + 1)], &cell_col_guide_[static_cast<size_t>(k) * W], W, u2, fc);
  const CellRow r = cell_row(k, H);
  const int c1 = next_column(c, W);  // pick() returns c in [0, W)
  const double a = lum_[size_t(r.top) * W + c], b = lum_[size_t(r.top) * W + c1];
  const double cc = lum_[size_t(r.bottom) * W + c], d = lum_[size_t(r.bottom) * W + c1];
  // The bilinear patch: marginal in y ∝ lerp(y, a + b, c + d), then x | y ∝ lerp(x, left, right).
  const double y = sample_linear(fr, a + b, cc + d);
  const double x = sample_linear(fc, (1 - y) * a + y * cc, (1 - y) * b + y * d);
  const double v = r.v0 + y * (r.v1 - r.v0);
  double u = c + 0.5 + x;
  if (u >= W) u -= W;
  unit = {u / W, v / H};
  // equirect::uv_to_direction in single precision (the result is a float vector either way):
  // the inference shading draws millions of these.
  const float azimuth = float((unit.u - 0.5) * kTwoPi), elevation = float((0.5 - unit.v) * kPi);
  const float ce = std::cos(elevation);
  return glm::vec3(ce * std::sin(azimuth), std::sin(elevation), -ce * std::cos(azimuth));
}

float EnvironmentMap::pdf_bilinear(const glm::vec3& d) const {
  if (cell_prob_.empty()) return pdf(d);
  if (!(glm::dot(d, d) > 0.0f) || !all_finite3(d)) return 0.0f;
  return pdf_bilinear_unit(equirect::direction_to_uv(d.x, d.y, d.z, 1, 1));
}

float EnvironmentMap::pdf_bilinear_unit(const equirect::UV& unit) const {
  return pdf_bilinear_unit(unit, std::cos((0.5 - unit.v) * kPi));
}

float EnvironmentMap::pdf_bilinear_unit(const equirect::UV& unit, double cos_elevation) const {
  const int H = height_, W = width_;
  if (cell_prob_.empty()) {
    const equirect::Dir d = equirect::uv_to_direction(unit.u * W, unit.v * H, W, H);
    return pdf(glm::vec3(float(d.x), float(d.y), float(d.z)));
  }
  const equirect::UV uv{unit.u * W, unit.v * H};
  const int k = std::clamp(static_cast<int>(std::floor(uv.v + 0.5)), 0, H);
  const CellRow r = cell_row(k, H);
  double fu = uv.u - 0.5;
  const double fl = std::floor(fu);
  const int c = wrap_column(static_cast<int>(fl), W), c1 = next_column(c, W);
  const double x = std::clamp(fu - fl, 0.0, 1.0);
  const double y = std::clamp((uv.v - r.v0) / (r.v1 - r.v0), 0.0, 1.0);
  const double a = lum_[size_t(r.top) * W + c], b = lum_[size_t(r.top) * W + c1];
  const double cc = lum_[size_t(r.bottom) * W + c], dd = lum_[size_t(r.bottom) * W + c1];
  const double mean = 0.25 * (a + b + cc + dd);
  if (!(mean > 0.0)) return 0.0f;
  const double value = (1 - y) * ((1 - x) * a + x * b) + y * ((1 - x) * cc + x * dd);
  const double j = cos_elevation * (kTwoPi / W) * (kPi / H);  // jacobian(uv.v, W, H)
  if (!(j > 1e-12)) return 0.0f;
  // (u, v) density P_cell · value / ∫cell value, with ∫cell value = mean · (v1 − v0).
  const double p = cell_prob_[static_cast<size_t>(k) * W + c] * value / (mean * (r.v1 - r.v0)) / j;
  return std::isfinite(p) ? float(p) : 0.0f;
}

void EnvironmentMap::build_sampling() {
  const int H = height_, W = width_;
  texel_pdf_.assign(static_cast<size_t>(H) * W, 0.0);
  col_cdf_.assign(static_cast<size_t>(H) * (W + 1), 0.0);
  row_cdf_.assign(static_cast<size_t>(H) + 1, 0.0);
  std::vector<double> row_mass(H, 0.0);
  for (int i = 0; i < H; ++i) {
    const double omega = equirect::pixel_solid_angle(i, W, H);
    double* cdf = &col_cdf_[static_cast<size_t>(i) * (W + 1)];
    for (int j = 0; j < W; ++j) {
      // Mass = the exact average of the bilinear lookup over the texel: the tent weights
      // 9/16 (centre), 3/32 (edge neighbours) and 1/64 (corners), with the lookup's pole clamp
      // and seam wrap. pdf > 0 wherever the lookup is > 0, and L/pdf stays within 64× of its
      // texel average even beside a one-texel sun.
      double avg = 0.0;
      for (int di = -1; di <= 1; ++di)
        for (int dj = -1; dj <= 1; ++dj) {
          const glm::vec3 t = texel(std::clamp(i + di, 0, H - 1), (j + dj + W) % W);
          const double w = (di == 0 ? 0.75 : 0.125) * (dj == 0 ? 0.75 : 0.125);
          avg += w * luminance(t.r, t.g, t.b);
        }
      const double m = avg * omega;
      texel_pdf_[static_cast<size_t>(i) * W + j] = m;
      cdf[j + 1] = cdf[j] + m;
    }
    row_mass[i] = cdf[W];
    row_cdf_[i + 1] = row_cdf_[i] + row_mass[i];
  }
  const double total = row_cdf_[H];
  if (!(total > 0.0)) {  // black map: sample() falls back to the uniform sphere
    texel_pdf_.clear();
    cell_prob_.clear();
    return;
  }
  build_bilinear_sampling();
  for (double& m : texel_pdf_) m /= total;
  for (double& c : row_cdf_) c /= total;
  for (int i = 0; i < H; ++i) {
    double* cdf = &col_cdf_[static_cast<size_t>(i) * (W + 1)];
    const double mass = cdf[W];
    for (int j = 0; j <= W; ++j) cdf[j] = mass > 0 ? cdf[j] / mass : static_cast<double>(j) / W;
  }
}

EnvironmentMap::Sample EnvironmentMap::sample(float u1, float u2) const {
  Sample s;
  if (texel_pdf_.empty()) {  // uniform sphere
    const double y = 1.0 - 2.0 * u1, r = std::sqrt(std::max(0.0, 1.0 - y * y)), phi = kTwoPi * u2;
    s.direction = glm::vec3(float(r * std::cos(phi)), float(y), float(r * std::sin(phi)));
    s.radiance = lookup(s.direction);
    s.pdf = float(1.0 / (2.0 * kTwoPi));
    return s;
  }
  const int H = height_, W = width_;
  // Row by the marginal, then column by the row's conditional; the leftover fraction of each
  // uniform places the direction inside the texel, uniformly in solid angle.
  // The cell k with cdf[k] <= u < cdf[k + 1] (the last such k: upper_bound − 1, clamped to a
  // cell), searched forward from the guide table's entry for u.
  auto pick = [](const double* cdf, int n, double u, double& frac) {
    int k = static_cast<int>(std::upper_bound(cdf, cdf + n + 1, u) - cdf) - 1;
    k = std::clamp(k, 0, n - 1);
    while (k > 0 && cdf[k + 1] - cdf[k] <= 0.0) --k;  // never land on a zero-mass bin
    while (k < n - 1 && cdf[k + 1] - cdf[k] <= 0.0) ++k;
    const double w = cdf[k + 1] - cdf[k];
    frac = w > 0 ? std::clamp((u - cdf[k]) / w, 0.0, 1.0) : 0.5;
    return k;
  };
  double fr, fc;
  const int i = pick(row_cdf_.data(), H, u1, fr);
  const int j = pick(&col_cdf_[static_cast<size_t>(i) * (W + 1)], W, u2, fc);
  const double s0 = row_top_sin(i, H), s1 = row_top_sin(i + 1, H);
  const double sin_el = s0 + (s1 - s0) * fr;
  const double u = j + fc;
  const double az = (u / W - 0.5) * kTwoPi;
  const double c = std::sqrt(std::max(0.0, 1.0 - sin_el * sin_el));
  s.direction = glm::vec3(float(c * std::sin(az)), float(sin_el), float(-c * std::cos(az)));
  s.radiance = lookup(s.direction);
  s.pdf = float(texel_pdf_[static_cast<size_t>(i) * W + j] / equirect::pixel_solid_angle(i, W, H));
  return s;
}

float EnvironmentMap::pdf(const glm::vec3& d) const {
  if (texel_pdf_.empty()) return float(1.0 / (2.0 * kTwoPi));
  if (!(glm::dot(d, d) > 0.0f)) return 0.0f;
  const auto uv = equirect::direction_to_uv(d.x, d.y, d.z, width_, height_);
  const int j = std::clamp(static_cast<int>(std::floor(uv.u)), 0, width_ - 1);
  const int i = std::clamp(static_cast<int>(std::floor(uv.v)), 0, height_ - 1);
  return float(texel_pdf_[static_cast<size_t>(i) * width_ + j] / equirect::pixel_solid_angle(i, width_, height_));
}

glm::dvec3 EnvironmentMap::integral() const {
  glm::dvec3 total(0.0);
  for (int i = 0; i < height_; ++i) {
    const double omega = equirect::pixel_solid_angle(i, width_, height_);
    for (int j = 0; j < width_; ++j) total += glm::dvec3(texel(i, j)) * omega;
  }
  return total;
}

EnvironmentMap EnvironmentMap::rotated(double azimuth_rad) const {
  // A feature at azimuth φ moves to φ + angle: new column u reads old column u - shift.
  const double shift = azimuth_rad / kTwoPi * width_;
  Tensor out = Tensor::empty({3, height_, width_}, DType::F32);
  float* po = out.data<float>();
  const float* pi = radiance_.data<float>();
  const int64_t plane = static_cast<int64_t>(height_) * width_;
  for (int c = 0; c < 3; ++c)
    for (int i = 0; i < height_; ++i)
      for (int j = 0; j < width_; ++j) {
        const double src = j - shift;
        const double f = std::floor(src);
        const double w = src - f;
        const int64_t j0 = ((static_cast<int64_t>(f) % width_) + width_) % width_, j1 = (j0 + 1) % width_;
        const float* row = pi + c * plane + static_cast<int64_t>(i) * width_;
        po[c * plane + static_cast<int64_t>(i) * width_ + j] = float((1 - w) * row[j0] + w * row[j1]);
      }
  return EnvironmentMap(out);
}

EnvironmentMap EnvironmentMap::resized(int width, int height) const {
  return EnvironmentMap(resize_panorama(radiance_, width, height));
}

Tensor resize_panorama(const Tensor& panorama, int width, int height) {
  SL_CHECK(panorama.dim() == 3, "resize_panorama: expected [C, H, W], got ", panorama.describe());
  SL_CHECK(width >= 2 && height >= 1, "resize_panorama: bad target size ", width, "x", height);
  const Tensor src = panorama.detach().to(DType::F64).contiguous();
  const int C = int(src.size(0)), H = int(src.size(1)), W = int(src.size(2));
  // Separable overlap weights: rows in the measure sin(elevation) (∝ solid angle), columns in
  // azimuth. out = Σ in · overlap / |out texel|, so Σ out·Ω_out == Σ in·Ω_in exactly.
  std::vector<std::vector<std::pair<int, double>>> rw(height), cw(width);
  for (int o = 0; o < height; ++o) {
    const double a0 = row_top_sin(o + 1, height), a1 = row_top_sin(o, height);
    for (int i = 0; i < H; ++i) {
      const double b0 = row_top_sin(i + 1, H), b1 = row_top_sin(i, H);
      const double ov = std::min(a1, b1) - std::max(a0, b0);
      if (ov > 0) rw[o].push_back({i, ov / (a1 - a0)});
    }
  }
  for (int o = 0; o < width; ++o) {
    const double a0 = double(o) / width, a1 = double(o + 1) / width;
    for (int j = 0; j < W; ++j) {
      const double b0 = double(j) / W, b1 = double(j + 1) / W;
      const double ov = std::min(a1, b1) - std::max(a0, b0);
      if (ov > 0) cw[o].push_back({j, ov / (a1 - a0)});
    }
  }
  Tensor out = Tensor::zeros({C, height, width}, DType::F64);
  const double* ps = src.data<double>();
  double* po = out.data<double>();
  parallel_for(int64_t(C) * height, 1, [&](int64_t b, int64_t e) {
    for (int64_t ci = b; ci < e; ++ci) {
      const int c = int(ci / height), o = int(ci % height);
      for (int q = 0; q < width; ++q) {
        double acc = 0;
        for (auto [i, wr] : rw[o])
          for (auto [j, wc] : cw[q]) acc += wr * wc * ps[(int64_t(c) * H + i) * W + j];
        po[(int64_t(c) * height + o) * width + q] = acc;
      }
    }
  });
  return out.to(panorama.dtype());
}

// ---------------------------------------------------------------- differentiable lookup
Tensor env_lookup(const Tensor& env, const Tensor& directions) {
  SL_CHECK(env.dim() == 3 && env.size(0) == 3, "env_lookup: env must be [3, H, W], got ", env.describe());
  SL_CHECK(directions.dim() == 2 && directions.size(1) == 3, "env_lookup: directions must be [N, 3], got ",
           directions.describe());
  SL_CHECK(env.dtype() == directions.dtype(), "env_lookup: dtypes differ: ", env.describe(), " and ",
           directions.describe());
  const Tensor e = env.detach().contiguous(), d = directions.detach().contiguous();
  const int H = int(e.size(1)), W = int(e.size(2));
  const int64_t N = d.size(0), plane = int64_t(H) * W;
  Tensor out = Tensor::empty({N, 3}, env.dtype());
  SL_DISPATCH_FLOAT(env.dtype(), "env_lookup", [&] {
    using T = scalar_t;
    const T* pe = e.data<T>();
    const T* pd = d.data<T>();
    T* po = out.data<T>();
    parallel_for(N, 1024, [&](int64_t b, int64_t en) {
      for (int64_t n = b; n < en; ++n) {
        const T x = pd[3 * n], y = pd[3 * n + 1], z = pd[3 * n + 2];
        if (!(std::isfinite(x) && std::isfinite(y) && std::isfinite(z)) || x * x + y * y + z * z <= 0) {
          po[3 * n] = po[3 * n + 1] = po[3 * n + 2] = 0;
          continue;
        }
        const EnvTaps t = env_bilinear_taps(x, y, z, W, H);
        for (int c = 0; c < 3; ++c) {
          double v = 0;
          for (int k = 0; k < 4; ++k) v += t.weight[k] * pe[c * plane + t.index[k]];
          po[3 * n + c] = T(v);
        }
      }
    });
  });
  if (needs_grad({env})) {
    const Shape env_shape = env.shape();
    record("env_lookup", {env, directions}, {out}, [=](const TensorList& g) {
      const Tensor go = g[0].contiguous();
      Tensor ge = Tensor::zeros(env_shape, go.dtype());
      SL_DISPATCH_FLOAT(go.dtype(), "env_lookup", [&] {
        using T = scalar_t;
        const T* pd = d.data<T>();
        const T* pg = go.data<T>();
        T* pe = ge.data<T>();
        // One channel per task: each texel plane is written by one thread, in ray order.
        parallel_for(3, 1, [&](int64_t c0, int64_t c1) {
          for (int64_t c = c0; c < c1; ++c) {
            T* p = pe + c * plane;
            for (int64_t n = 0; n < N; ++n) {
              const T x = pd[3 * n], y = pd[3 * n + 1], z = pd[3 * n + 2];
              if (!(std::isfinite(x) && std::isfinite(y) && std::isfinite(z)) || x * x + y * y + z * z <= 0) continue;
              const EnvTaps t = env_bilinear_taps(x, y, z, W, H);
              const T gv = pg[3 * n + c];
              for (int k = 0; k < 4; ++k) p[t.index[k]] += T(t.weight[k]) * gv;
            }
          }
        });
      });
      return TensorList{ge, Tensor()};
    });
  }
  return out;
}

}  // namespace sl::render
