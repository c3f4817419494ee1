// Real panoramas as street samples. See panorama_sample.h.
#include "data/panorama_sample.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "data/panorama.h"
#include "render/equirect.h"
#include "util/error.h"
#include "util/math.h"
#include "util/random.h"

using sl::render::exposure_for_ldr_median;

namespace sl::data {

Tensor sanitized_panorama(const Tensor& pano, const std::string& name) {
  SL_CHECK(pano.defined() && pano.dim() == 3 && pano.size(0) == 3, "panorama '", name,
           "': expected an RGB image, got ", pano.defined() ? pano.describe() : std::string("nothing"));
  SL_CHECK(pano.size(2) == 2 * pano.size(1), "panorama '", name, "' is ", pano.size(2), "x", pano.size(1),
           "; an equirectangular panorama is 2:1 (width = 2 x height)");
  Tensor out = pano.to(DType::F32).contiguous().clone();
  float* p = out.data<float>();
  for (int64_t i = 0; i < out.numel(); ++i)
    if (!(p[i] >= 0.0f) || !std::isfinite(p[i])) p[i] = 0.0f;
  return out;
}

SunHardness sun_hardness(const Tensor& pano, double radius_deg, double min_share) {
  SunHardness h;
  h.sun = extract_sun(pano);
  const int64_t H = pano.size(1), W = pano.size(2), plane = H * W;
  const float* p = pano.data<float>();
  const double cos_r = std::cos(radius_deg * kDegToRad);
  const glm::dvec3 s = h.sun.direction;
  double total = 0.0, near = 0.0;
  for (int64_t r = 0; r < H; ++r) {
    const double theta = (0.5 - (r + 0.5) / static_cast<double>(H)) * kPi;  // elevation of the row centre
    const double omega = std::cos(theta);                                  // ∝ solid angle of a texel
    for (int64_t c = 0; c < W; ++c) {
      const int64_t i = r * W + c;
      const double l = luminance(p[i], p[plane + i], p[2 * plane + i]) * omega;
      total += l;
      const auto d = render::equirect::uv_to_direction(c + 0.5, r + 0.5, static_cast<int>(W), static_cast<int>(H));
      if (d.x * s.x + d.y * s.y + d.z * s.z >= cos_r) near += l;
    }
  }
  h.share = total > 0.0 ? near / total : 0.0;
  h.hard = h.sun.found && h.share >= min_share && h.sun.direction.y > 0.0;
  return h;
}

glm::dvec3 sun_energy_rgb(const Tensor& pano_in, const glm::dvec3& s, double radius_deg) {
  SL_CHECK(pano_in.defined() && pano_in.dim() == 3 && pano_in.size(0) == 3 && pano_in.size(1) > 0,
           "sun_energy_rgb: expected an RGB panorama [3, H, W], got ", pano_in.defined() ? pano_in.describe() : "nothing");
  const Tensor pano = pano_in.to(DType::F32).contiguous();
  const int64_t H = pano.size(1), W = pano.size(2), plane = H * W;
  const float* p = pano.data<float>();
  const double cos_r = std::cos(radius_deg * kDegToRad), texel = (2.0 * kPi / W) * (kPi / H);
  glm::dvec3 e(0.0);
  for (int64_t r = 0; r < H; ++r) {
    const double omega = texel * std::cos((0.5 - (r + 0.5) / static_cast<double>(H)) * kPi);
    for (int64_t c = 0; c < W; ++c) {
      const auto d = render::equirect::uv_to_direction(c + 0.5, r + 0.5, static_cast<int>(W), static_cast<int>(H));
      if (d.x * s.x + d.y * s.y + d.z * s.z < cos_r) continue;
      const int64_t i = r * W + c;
      for (int ch = 0; ch < 3; ++ch) {
        const double v = p[ch * plane + i];
        if (std::isfinite(v) && v > 0.0) e[ch] += v * omega;
      }
    }
  }
  return e;
}

PanoramaSampleDraw draw_panorama_sample(uint64_t seed, uint64_t stream, int64_t width, const PanoramaSampleOptions& o) {
  SL_CHECK(width > 0, "draw_panorama_sample: width must be positive, got ", width);
  Rng rng(seed, stream);
  PanoramaSampleDraw d;
  const int64_t shift = rng.randint(width);
  d.shift_columns = o.rotate ? shift : 0;
  d.flip = rng.uniform() < 0.5 && o.flip;
  for (double& g : d.gain) g = std::exp2(rng.uniform(-1.0, 1.0) * o.white_balance_stops);
  d.exposure_jitter = std::exp2(rng.uniform(-1.0, 1.0) * o.exposure_stops);
  d.crop_stream = rng.next_u64();
  if (o.tone_stops > 0.0) d.tone_gamma = std::exp2(rng.uniform(-1.0, 1.0) * o.tone_stops);
  return d;
}

StreetSample panorama_street_sample(const Tensor& pano_in, const std::string& id, uint64_t seed, uint64_t stream,
                                    const PanoramaSampleOptions& o) {
  SL_CHECK(o.pano_width == 2 * o.pano_height && o.pano_height > 0, "panorama_street_sample: pano size must be 2:1, got ",
           o.pano_width, "x", o.pano_height);
  SL_CHECK(o.ldr_median > 0.0 && o.ldr_median < 1.0 && o.exposure_stops >= 0.0 && o.white_balance_stops >= 0.0,
           "panorama_street_sample: need 0 < ldr_median < 1 and non-negative jitter ranges");
  Tensor pano = sanitized_panorama(pano_in, id);
  const int64_t W = pano.size(2);
  const PanoramaSampleDraw draw = draw_panorama_sample(seed, stream, W, o);
  const double* gain = draw.gain;
  const double exposure_jitter = draw.exposure_jitter;
  const uint64_t crop_stream = draw.crop_stream;

  if (draw.shift_columns != 0)
    pano = rotate_azimuth(pano, 2.0 * kPi * static_cast<double>(draw.shift_columns) / static_cast<double>(W));
  if (draw.flip) pano = flip_panorama(pano);
  {
    const double grey = luminance(gain[0], gain[1], gain[2]);
    float* p = pano.data<float>();
    const int64_t plane = pano.size(1) * W;
    for (int c = 0; c < 3; ++c)
      for (int64_t i = 0; i < plane; ++i) p[c * plane + i] = static_cast<float>(p[c * plane + i] * gain[c] / grey);
  }
  pano = pano.contiguous();
  const SunHardness sun = sun_hardness(pano, o.hard_sun_radius_deg, o.hard_sun_share);
  const Tensor mask_full = estimate_sky_mask(pano);

  const glm::dvec3 centre(0.0, o.camera_height_m, 0.0);
  const RandomCrop crop = random_perspective_crop(pano, seed, crop_stream, o.crop, centre, sun.hard ? &sun.sun.direction : nullptr);
  const Tensor view_mask =
      binarize_mask(crop_perspective(mask_full, crop_params(crop, o.crop.width, o.crop.height)).image.contiguous());

  const Tensor& hdr = crop.crop.image;
  const double exposure = exposure_for_ldr_median(hdr, o.ldr_median) * exposure_jitter;

  StreetSample s;
  s.id = id;
  s.exposure = exposure;
  s.pano_hdr = resize_area(pano, o.pano_height, o.pano_width).contiguous();
  s.pano_ldr = to_ldr(s.pano_hdr, exposure);
  s.pano_sky_mask = binarize_mask(resize_area(mask_full, o.pano_height, o.pano_width).contiguous());
  s.sky_hdr = s.pano_hdr;
  s.pano_position = centre;
  s.sun_direction = sun.sun.direction;
  s.sun_known = sun.hard;
  StreetView v;
  v.hdr = hdr;
  v.ldr = to_ldr(hdr, exposure);
  s.input_tone_gamma = draw.tone_gamma;
  v.depth = Tensor::zeros({o.crop.height, o.crop.width}, DType::F32);
  v.sky_mask = view_mask;
  v.camera = crop.crop.camera;
  s.views.push_back(std::move(v));
  return s;
}

}  // namespace sl::data
