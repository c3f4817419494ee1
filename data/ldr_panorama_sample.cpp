// Real LDR panoramas as street samples. See ldr_panorama_sample.h.
#include "data/ldr_panorama_sample.h"

#include <algorithm>
#include <cmath>

#include "data/augment.h"
#include "data/panorama.h"
#include "util/error.h"
#include "util/math.h"

namespace sl::data {

namespace {

constexpr float kClippedCode = 254.0f / 255.0f;

void check_panorama(const Tensor& t, const std::string& id) {
  SL_CHECK(t.defined() && t.dim() == 3 && t.size(0) == 3 && t.size(2) == 2 * t.size(1), "LDR panorama '", id,
           "': expected [3, H, 2H], got ", t.defined() ? t.describe() : std::string("nothing"));
}

// The linear radiance codes^2.2 with white balance and exposure applied; clipped texels stay 1.
// `base` (optional): codes^2.2 computed before (LdrPanorama::linear), the same bits as computing it.
Tensor linear_radiance(const Tensor& ldr, const Tensor& base, const double gain[3], double k) {
  const double grey = luminance(gain[0], gain[1], gain[2]);
  const Tensor codes = ldr.to(DType::F32).contiguous();
  const float* q = codes.data<float>();
  const float* b = base.defined() ? base.data<float>() : nullptr;
  Tensor out = Tensor::empty(codes.shape(), DType::F32);
  float* p = out.data<float>();
  const int64_t plane = out.size(1) * out.size(2);
  float scale[3];
  for (int c = 0; c < 3; ++c) scale[c] = static_cast<float>(gain[c] / grey * k);
  for (int64_t i = 0; i < plane; ++i) {
    const bool clipped = q[i] >= kClippedCode || q[plane + i] >= kClippedCode || q[2 * plane + i] >= kClippedCode;
    for (int c = 0; c < 3; ++c) {
      const int64_t j = c * plane + i;
      p[j] = clipped ? 1.0f : (b ? b[j] : std::pow(std::max(q[j], 0.0f), 2.2f)) * scale[c];
    }
  }
  return out;
}

}  // namespace

Tensor ldr_linear(const Tensor& ldr) {
  check_panorama(ldr, "linear radiance input");
  const double one[3] = {1.0, 1.0, 1.0};
  return linear_radiance(ldr, Tensor(), one, 1.0);
}

Tensor ldr_sky_mask(const Tensor& ldr) {
  check_panorama(ldr, "sky mask input");
  return estimate_sky_mask(ldr_linear(ldr));
}

StreetSample ldr_panorama_street_sample(const LdrPanorama& pano, const std::string& id, uint64_t seed, uint64_t stream,
                                        const PanoramaSampleOptions& o, bool keep_images) {
  check_panorama(pano.ldr, id);
  SL_CHECK(o.pano_width == 2 * o.pano_height && o.pano_height > 0,
           "ldr_panorama_street_sample: pano size must be 2:1, got ", o.pano_width, "x", o.pano_height);
  const int64_t W = pano.ldr.size(2);
  const PanoramaSampleDraw draw = draw_panorama_sample(seed, stream, W, o);
  const double delta = 2.0 * kPi * static_cast<double>(draw.shift_columns) / static_cast<double>(W);
  SL_CHECK(!pano.linear.defined() || pano.linear.shape() == pano.ldr.shape(), "LDR panorama '", id,
           "': its linear radiance is ", pano.linear.describe(), ", its codes ", pano.ldr.describe());
  const Tensor linear = linear_radiance(pano.ldr, pano.linear.defined() ? pano.linear.contiguous() : Tensor(), draw.gain,
                                        draw.exposure_jitter);
  const auto turn = [&](const Tensor& t) {  // the rotation, then the flip
    Tensor r = draw.shift_columns ? rotate_azimuth(t, delta) : t;
    return (draw.flip ? flip_panorama(r) : r).contiguous();
  };
  const Tensor full = turn(linear);
  const glm::dvec3 centre(0.0, o.camera_height_m, 0.0);
  const glm::dvec3 turned_sun = rotate_direction_azimuth(pano.sun_direction, delta);
  const glm::dvec3 sun = draw.flip ? flip_panorama_direction(turned_sun) : turned_sun;
  const RandomCrop rc = random_perspective_crop(full, seed, draw.crop_stream, o.crop, centre, pano.sun_known ? &sun : nullptr);

  StreetSample s;
  s.id = id;
  s.exposure = 1.0;
  s.pano_position = centre;
  s.sun_direction = sun;
  s.sun_known = pano.sun_known;
  s.sun_weight = pano.sun_weight;
  s.input_tone_gamma = draw.tone_gamma;
  s.hdr_sky = false;  // codes^2.2 are clipped where the sun is: no measure of its energy
  StreetView v;
  v.camera = rc.crop.camera;
  if (keep_images) {
    // The small panorama is resized before it is turned (as the benchmark has always done): the
    // rotation of a whole working column is a fraction of a small one, read linearly.
    s.pano_hdr = turn(resize_area(linear, o.pano_height, o.pano_width));
    s.pano_ldr = to_ldr(s.pano_hdr, 1.0);
    s.sky_hdr = s.pano_hdr;
    v.ldr = to_ldr(rc.crop.image.contiguous(), 1.0);
    v.depth = Tensor::zeros({o.crop.height, o.crop.width}, DType::F32);
    if (pano.sky_mask.defined()) {
      const Tensor mask = turn(pano.sky_mask);
      s.pano_sky_mask = binarize_mask(resize_area(mask, o.pano_height, o.pano_width).contiguous());
      v.sky_mask = binarize_mask(crop_perspective(mask, crop_params(rc, o.crop.width, o.crop.height)).image.contiguous());
    }
  }
  s.views.push_back(std::move(v));
  return s;
}

}  // namespace sl::data
