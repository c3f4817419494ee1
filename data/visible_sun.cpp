// A visible sun disk in an LDR photo. See visible_sun.h.
#include "data/visible_sun.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "util/error.h"
#include "util/math.h"

namespace sl::data {

namespace {

struct Image {
  int h = 0, w = 0;
  std::vector<float> lum;      // Rec. 709 of the LDR values, NaN/Inf → 0
  std::vector<uint8_t> clip;   // every channel ≥ saturation
};

Image read_image(const Tensor& ldr, double saturation) {
  SL_CHECK(ldr.defined() && ldr.dim() == 3 && ldr.size(0) == 3, "find_visible_sun: expected an LDR image [3, H, W], got ",
           ldr.defined() ? ldr.describe() : std::string("undefined"));
  Image im;
  im.h = static_cast<int>(ldr.size(1));
  im.w = static_cast<int>(ldr.size(2));
  const int64_t plane = static_cast<int64_t>(im.h) * im.w;
  im.lum.assign(static_cast<size_t>(plane), 0.0f);
  im.clip.assign(static_cast<size_t>(plane), 0);
  if (plane == 0) return im;
  const Tensor c = ldr.detach().to(DType::F32).contiguous();
  const float* p = c.data<float>();
  for (int64_t i = 0; i < plane; ++i) {
    float rgb[3];
    for (int ch = 0; ch < 3; ++ch) {
      const float v = p[ch * plane + i];
      rgb[ch] = std::isfinite(v) ? v : 0.0f;
    }
    im.lum[static_cast<size_t>(i)] = static_cast<float>(luminance(rgb[0], rgb[1], rgb[2]));
    im.clip[static_cast<size_t>(i)] = std::min({rgb[0], rgb[1], rgb[2]}) >= saturation;
  }
  return im;
}

// 8-connected components of the clipped pixels, in scan order of their first pixel.
std::vector<std::vector<int64_t>> clipped_components(const Image& im) {
  std::vector<std::vector<int64_t>> comps;
  std::vector<uint8_t> seen(im.clip.size(), 0);
  std::vector<int64_t> stack;
  for (int64_t start = 0; start < static_cast<int64_t>(im.clip.size()); ++start) {
    if (!im.clip[static_cast<size_t>(start)] || seen[static_cast<size_t>(start)]) continue;
    std::vector<int64_t> comp;
    stack.assign(1, start);
    seen[static_cast<size_t>(start)] = 1;
    while (!stack.empty()) {
      const int64_t i = stack.back();
      stack.pop_back();
      comp.push_back(i);
      const int r = static_cast<int>(i / im.w), c = static_cast<int>(i % im.w);
      for (int dr = -1; dr <= 1; ++dr)
        for (int dc = -1; dc <= 1; ++dc) {
          const int rr = r + dr, cc = c + dc;
          if (rr < 0 || rr >= im.h || cc < 0 || cc >= im.w) continue;
          const int64_t j = static_cast<int64_t>(rr) * im.w + cc;
          if (im.clip[static_cast<size_t>(j)] && !seen[static_cast<size_t>(j)]) {
            seen[static_cast<size_t>(j)] = 1;
            stack.push_back(j);
          }
        }
    }
    comps.push_back(std::move(comp));
  }
  return comps;
}

// Mean luminance of rings k = 0 and k = 2 of width w beyond r_max around (cu, cv); NaN when a
// ring holds no pixel of the image.
void ring_means(const Image& im, double cu, double cv, double r_max, double w, double& ring1, double& ring3) {
  const double reach = r_max + 3.0 * w;
  const int r0 = std::max(0, static_cast<int>(std::floor(cv - reach))), r1 = std::min(im.h - 1, static_cast<int>(std::ceil(cv + reach)));
  const int c0 = std::max(0, static_cast<int>(std::floor(cu - reach))), c1 = std::min(im.w - 1, static_cast<int>(std::ceil(cu + reach)));
  double sum[3] = {0, 0, 0};
  int64_t n[3] = {0, 0, 0};
  for (int r = r0; r <= r1; ++r)
    for (int c = c0; c <= c1; ++c) {
      const double d = std::hypot(c + 0.5 - cu, r + 0.5 - cv);
      if (d < r_max) continue;
      const int k = static_cast<int>((d - r_max) / w);
      if (k > 2) continue;
      sum[k] += im.lum[static_cast<size_t>(r) * im.w + c];
      ++n[k];
    }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  ring1 = n[0] ? sum[0] / n[0] : nan;
  ring3 = n[2] ? sum[2] / n[2] : nan;
}

VisibleSun measure(const Image& im, const std::vector<int64_t>& comp, const render::Camera* camera,
                   const VisibleSunParams& p) {
  VisibleSun s;
  s.area_px = static_cast<int>(comp.size());
  double su = 0.0, sv = 0.0;
  int64_t border = 0;
  for (const int64_t i : comp) {
    const int r = static_cast<int>(i / im.w), c = static_cast<int>(i % im.w);
    su += c + 0.5, sv += r + 0.5;
    border += r == 0 || c == 0 || r == im.h - 1 || c == im.w - 1;
  }
  const double cu = su / comp.size(), cv = sv / comp.size();
  double r_max = 0.0;
  for (const int64_t i : comp)
    r_max = std::max(r_max, std::hypot(static_cast<double>(i % im.w) + 0.5 - cu, static_cast<double>(i / im.w) + 0.5 - cv));
  r_max += 0.5;
  s.pixel = {cu, cv};
  s.compactness = std::min(1.0, comp.size() / (kPi * r_max * r_max));
  s.border_fraction = static_cast<double>(border) / comp.size();
  if (camera) {
    s.direction = camera->ray(cu, cv).direction;
    s.elevation_deg = degrees(std::asin(std::clamp(s.direction.y, -1.0, 1.0)));
  } else {
    s.elevation_deg = std::numeric_limits<double>::quiet_NaN();
  }
  const double pixels = static_cast<double>(im.h) * im.w;
  const bool sized = s.area_px >= p.min_area_fraction * pixels && s.area_px <= p.max_area_fraction * pixels;
  // Rings are measured for diagnostics a little beyond the size limits, never for huge blobs.
  if (s.area_px >= 3 && s.area_px <= 4.0 * p.max_area_fraction * pixels) {
    double ring1 = 0.0, ring3 = 0.0;
    ring_means(im, cu, cv, r_max, std::max(2.0, r_max), ring1, ring3);
    if (std::isfinite(ring1)) s.halo = ring1;
    if (std::isfinite(ring1) && std::isfinite(ring3)) s.falloff = ring1 - ring3;
  }
  const bool in_sky = camera ? s.elevation_deg >= p.min_elevation_deg : cv <= p.max_row_fraction * im.h;
  s.found = sized && s.compactness >= p.min_compactness && s.border_fraction <= p.max_border_fraction &&
            s.halo >= p.min_halo && s.falloff >= p.min_falloff && in_sky;
  s.score = s.found ? s.falloff * s.compactness : 0.0;
  if (!std::isfinite(s.elevation_deg)) s.elevation_deg = 0.0;
  return s;
}

void check_params(const VisibleSunParams& p) {
  SL_CHECK(p.saturation > 0.0 && p.saturation <= 1.0, "find_visible_sun: saturation must be in (0, 1], got ", p.saturation);
  SL_CHECK(p.min_area_fraction >= 0.0 && p.max_area_fraction > 0.0 && p.max_area_fraction <= 1.0 &&
               p.min_area_fraction <= p.max_area_fraction,
           "find_visible_sun: need 0 ≤ min_area_fraction ≤ max_area_fraction ≤ 1, max > 0; got ", p.min_area_fraction,
           " and ", p.max_area_fraction);
  SL_CHECK(p.min_compactness >= 0.0 && p.min_compactness <= 1.0,
           "find_visible_sun: min_compactness must be in [0, 1], got ", p.min_compactness);
  SL_CHECK(p.max_border_fraction >= 0.0 && p.max_border_fraction <= 1.0,
           "find_visible_sun: max_border_fraction must be in [0, 1], got ", p.max_border_fraction);
  SL_CHECK(std::isfinite(p.min_halo) && std::isfinite(p.min_falloff) && std::isfinite(p.min_elevation_deg) &&
               std::isfinite(p.max_row_fraction),
           "find_visible_sun: min_halo, min_falloff, min_elevation_deg and max_row_fraction must be finite");
}

VisibleSun best_of(const std::vector<VisibleSun>& candidates) {
  VisibleSun best;
  best.candidate_count = static_cast<int>(candidates.size());
  bool any = false;
  for (const VisibleSun& c : candidates) {
    // The best passing candidate; without one, the most glowing rejected one for diagnostics.
    const bool better = !any || (c.found && !best.found) || (c.found == best.found && (c.found ? c.score > best.score : c.falloff > best.falloff));
    if (!better) continue;
    best = c;
    best.candidate_count = static_cast<int>(candidates.size());
    any = true;
  }
  if (!best.found) best.pixel = {0.0, 0.0}, best.direction = {0.0, 1.0, 0.0}, best.score = 0.0;
  return best;
}

}  // namespace

std::vector<VisibleSun> visible_sun_candidates(const Tensor& ldr, const render::Camera* camera, const VisibleSunParams& p) {
  check_params(p);
  const Image im = read_image(ldr, p.saturation);
  if (camera) {
    const render::Intrinsics& k = camera->intrinsics();
    SL_CHECK(k.width == im.w && k.height == im.h, "find_visible_sun: image ", ldr.describe(), " does not match the camera's ",
             k.width, "x", k.height);
  }
  std::vector<VisibleSun> out;
  for (const auto& comp : clipped_components(im)) out.push_back(measure(im, comp, camera, p));
  return out;
}

VisibleSun find_visible_sun(const Tensor& ldr, const VisibleSunParams& params) {
  return best_of(visible_sun_candidates(ldr, nullptr, params));
}

VisibleSun find_visible_sun(const Tensor& ldr, const render::Camera& camera, const VisibleSunParams& params) {
  return best_of(visible_sun_candidates(ldr, &camera, params));
}

}  // namespace sl::data
