#include "data/augment.h"

#include <algorithm>
#include <cmath>

#include "util/error.h"
#include "util/math.h"
#include "util/random.h"

using sl::render::Camera;
using sl::render::Intrinsics;

namespace sl::data {
namespace {

void check_image(const Tensor& t, const char* fn) {
  SL_CHECK(t.defined() && (t.dim() == 3 || t.dim() == 2) && t.dtype() == DType::F32, fn,
           ": expected an F32 [C, H, W] or [H, W] tensor, got ", t.defined() ? t.describe() : "undefined");
}

}  // namespace

RandomCrop random_perspective_crop(const Tensor& pano, uint64_t seed, uint64_t stream, const CropRanges& r,
                                   const glm::dvec3& position, const glm::dvec3* sun) {
  SL_CHECK(r.fov_min_deg > 0.0 && r.fov_min_deg <= r.fov_max_deg && r.fov_max_deg < 179.0,
           "random_perspective_crop: need 0 < fov_min_deg <= fov_max_deg < 179, got [", r.fov_min_deg, ", ",
           r.fov_max_deg, "]");
  SL_CHECK(r.pitch_range_deg >= 0.0 && r.pitch_range_deg <= 89.0 && r.roll_range_deg >= 0.0 && r.roll_range_deg <= 180.0,
           "random_perspective_crop: pitch_range_deg must be in [0, 89] and roll_range_deg in [0, 180], got ",
           r.pitch_range_deg, " and ", r.roll_range_deg);
  Rng rng(seed, stream);
  RandomCrop out;
  out.fov_deg = rng.uniform(r.fov_min_deg, r.fov_max_deg);
  out.yaw_deg = rng.uniform(-180.0, 180.0);
  out.pitch_deg = rng.uniform(-r.pitch_range_deg, r.pitch_range_deg);
  out.roll_deg = rng.uniform(-r.roll_range_deg, r.roll_range_deg);
  SL_CHECK(r.sun_aim_share >= 0.0 && r.sun_aim_share <= 1.0 && r.sun_aim_max_pitch_deg >= 0.0 &&
               r.sun_aim_max_pitch_deg <= 89.0,
           "random_perspective_crop: sun_aim_share must be in [0, 1] and sun_aim_max_pitch_deg in [0, 89], got ",
           r.sun_aim_share, " and ", r.sun_aim_max_pitch_deg);
  // Drawn always, after the others (see augment.h).
  const double aim = rng.uniform(0.0, 1.0), side = rng.uniform(0.0, 1.0);
  const double du = rng.uniform(-0.7, 0.7), dv = rng.uniform(-0.7, 0.7);
  const double len = sun ? glm::length(*sun) : 0.0;
  if (sun && aim < r.sun_aim_share && std::isfinite(len) && len > 0.0) {
    const glm::dvec3 s = *sun / len;
    const double elevation = std::asin(std::clamp(s.y, -1.0, 1.0)) / kDegToRad;
    const double azimuth = std::atan2(s.x, -s.z) / kDegToRad;
    const double half_h = 0.5 * out.fov_deg;
    const double half_v = std::atan(std::tan(half_h * kDegToRad) * r.height / r.width) / kDegToRad;
    const double pitch = std::clamp(elevation - dv * half_v, -r.sun_aim_max_pitch_deg, r.sun_aim_max_pitch_deg);
    if (std::abs(elevation - pitch) <= 0.7 * half_v) {  // the sun can be brought into view
      const double yaw = azimuth - du * half_h + (side < 0.5 ? 0.0 : 180.0);
      out.yaw_deg = std::remainder(yaw, 360.0);
      if (side < 0.5) out.pitch_deg = pitch;
      out.aimed = side < 0.5 ? 1 : -1;
    }
  }
  out.crop = crop_perspective(pano, crop_params(out, r.width, r.height));
  out.crop.camera = Camera(out.crop.camera.intrinsics(), out.crop.camera.rotation(), position);
  return out;
}

Tensor flip_horizontal(const Tensor& image) {
  check_image(image, "flip_horizontal");
  const Tensor src = image.contiguous();
  Tensor out = Tensor::empty(src.shape());
  const int64_t W = src.size(-1), rows = src.numel() / std::max<int64_t>(W, 1);
  const float* s = src.data<float>();
  float* d = out.data<float>();
  for (int64_t r = 0; r < rows; ++r)
    for (int64_t x = 0; x < W; ++x) d[r * W + x] = s[r * W + (W - 1 - x)];
  return out;
}

glm::dvec3 mirror_direction(const glm::dvec3& d, const glm::dvec3& n) { return d - 2.0 * glm::dot(d, n) * n; }

StreetView flip_view(const StreetView& view, glm::dvec3* world_direction) {
  StreetView out;
  out.ldr = flip_horizontal(view.ldr);
  if (view.hdr.defined()) out.hdr = flip_horizontal(view.hdr);
  if (view.depth.defined()) out.depth = flip_horizontal(view.depth);
  if (view.sky_mask.defined()) out.sky_mask = flip_horizontal(view.sky_mask);
  Intrinsics k = view.camera.intrinsics();
  k.cx = k.width - k.cx;
  out.camera = Camera(k, view.camera.rotation(), view.camera.position());
  if (world_direction) *world_direction = mirror_direction(*world_direction, view.camera.rotation()[0]);
  return out;
}

Tensor flip_panorama(const Tensor& pano) {
  check_panorama(pano, "flip_panorama");
  // Column j covers u ∈ [j, j+1); the mirror u → W − u maps it onto column W − 1 − j.
  return flip_horizontal(pano);
}

StreetSample flip_sample(const StreetSample& s) {
  // The world mirror x → −x is the panorama flip's, for positions as for directions.
  const auto mirror = flip_panorama_direction;
  const auto flip_pano = [](const Tensor& t) { return t.defined() ? flip_panorama(t) : t; };
  StreetSample out;
  out.id = s.id;
  out.sky_hdr = flip_pano(s.sky_hdr);
  out.pano_hdr = flip_pano(s.pano_hdr);
  out.pano_ldr = flip_pano(s.pano_ldr);
  out.pano_sky_mask = flip_pano(s.pano_sky_mask);
  out.pano_position = mirror(s.pano_position);
  out.sun_direction = mirror(s.sun_direction);
  out.sun_known = s.sun_known;
  out.sun_weight = s.sun_weight;
  out.input_tone_gamma = s.input_tone_gamma;
  out.hdr_sky = s.hdr_sky;
  out.exposure = s.exposure;
  out.insert_light_probe_hdr = flip_pano(s.insert_light_probe_hdr);
  out.light_probe_position = mirror(s.light_probe_position);
  for (const StreetView& v : s.views) {
    StreetView f = flip_view(v);  // pixels and principal point; the pose is set below
    glm::dmat3 r = v.camera.rotation();
    r[0] = -mirror(r[0]);  // columns are the camera axes: (−M·x, M·y, M·z)
    r[1] = mirror(r[1]);
    r[2] = mirror(r[2]);
    f.camera = Camera(f.camera.intrinsics(), r, mirror(v.camera.position()));
    out.views.push_back(std::move(f));
  }
  return out;
}

double random_exposure_factor(uint64_t seed, uint64_t stream, double stops) {
  SL_CHECK(std::isfinite(stops) && stops >= 0.0, "random_exposure_factor: stops must be finite and >= 0, got ", stops);
  return std::exp2(Rng(seed, stream).uniform(-stops, stops));
}

Tensor scale_hdr(const Tensor& hdr, double factor) {
  check_image(hdr, "scale_hdr");
  SL_CHECK(std::isfinite(factor) && factor >= 0.0, "scale_hdr: factor must be finite and >= 0, got ", factor);
  Tensor out = hdr.contiguous().clone();
  float* p = out.data<float>();
  for (int64_t i = 0; i < out.numel(); ++i) p[i] = static_cast<float>(p[i] * factor);
  return out;
}

Tensor scale_ldr(const Tensor& ldr, double factor) {
  check_image(ldr, "scale_ldr");
  SL_CHECK(std::isfinite(factor) && factor >= 0.0, "scale_ldr: factor must be finite and >= 0, got ", factor);
  const float g = static_cast<float>(std::pow(factor, 1.0 / kLdrGamma));
  Tensor out = ldr.contiguous().clone();
  float* p = out.data<float>();
  for (int64_t i = 0; i < out.numel(); ++i) p[i] = std::clamp(p[i] * g, 0.0f, 1.0f);
  return out;
}

PerspectiveCropParams crop_params(const RandomCrop& crop, int width, int height) {
  PerspectiveCropParams p;
  p.horizontal_fov_rad = crop.fov_deg * kDegToRad;
  p.yaw_rad = crop.yaw_deg * kDegToRad;
  p.pitch_rad = crop.pitch_deg * kDegToRad;
  p.roll_rad = crop.roll_deg * kDegToRad;
  p.width = width;
  p.height = height;
  return p;
}

}  // namespace sl::data
