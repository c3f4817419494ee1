// Street samples → predictor inputs and loss targets. See street_batch.h.
#include "train/street_batch.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "data/panorama.h"
#include "data/panorama_sample.h"
#include "render/equirect.h"
#include "train/unprojection.h"
#include "util/math.h"
#include "util/random.h"

using sl::data::binarize_mask;
using sl::data::resize_area;
using sl::data::rotate_azimuth;
using sl::data::rotate_direction_azimuth;
using sl::data::StreetSample;
using sl::data::StreetView;
using sl::render::Camera;
using sl::render::CameraRay;
using sl::render::VsgGrid;

namespace sl::train {

glm::dvec3 CanonicalFrame::direction(const glm::dvec3& d) const { return rotate_direction_azimuth(d, -yaw_rad); }

glm::dvec3 CanonicalFrame::point(const glm::dvec3& p) const {
  return direction({p.x - camera_world.x, p.y, p.z - camera_world.z});
}

Camera CanonicalFrame::camera(const Camera& c) const {
  glm::dmat3 r;
  for (int k = 0; k < 3; ++k) r[k] = direction(c.rotation()[k]);  // columns: the camera axes
  return Camera(c.intrinsics(), r, point(c.position()));
}

double CanonicalFrame::object_yaw_deg(double world_yaw_deg) const {
  return world_yaw_deg + degrees(yaw_rad);
}

Tensor CanonicalFrame::panorama(const Tensor& pano) const {
  return yaw_rad == 0.0 ? pano : rotate_azimuth(pano, -yaw_rad);
}

CanonicalFrame canonical_frame(const Camera& input_camera) {
  const glm::dvec3 forward = input_camera.rotation()[2];
  CanonicalFrame f;
  f.yaw_rad = (std::abs(forward.x) + std::abs(forward.z) > 1e-12) ? std::atan2(forward.x, -forward.z) : 0.0;
  f.camera_world = input_camera.position();
  return f;
}

Tensor resize_bilinear(const Tensor& image, int64_t height, int64_t width) {
  SL_CHECK(image.dim() == 3 && height > 0 && width > 0, "resize_bilinear: expected [C, H, W] and a positive size, got ",
           image.describe(), " to ", height, "×", width);
  const Tensor src = image.to(DType::F32).contiguous();
  const int64_t c = src.size(0), h = src.size(1), w = src.size(2);
  if (h == height && w == width) return src;
  Tensor out = Tensor::empty({c, height, width});
  const float* s = src.data<float>();
  float* o = out.data<float>();
  for (int64_t y = 0; y < height; ++y) {
    const double sy = std::clamp((y + 0.5) * h / height - 0.5, 0.0, static_cast<double>(h - 1));
    const int64_t y0 = static_cast<int64_t>(sy), y1 = std::min(y0 + 1, h - 1);
    const double fy = sy - y0;
    for (int64_t x = 0; x < width; ++x) {
      const double sx = std::clamp((x + 0.5) * w / width - 0.5, 0.0, static_cast<double>(w - 1));
      const int64_t x0 = static_cast<int64_t>(sx), x1 = std::min(x0 + 1, w - 1);
      const double fx = sx - x0;
      for (int64_t ch = 0; ch < c; ++ch) {
        const float* p = s + ch * h * w;
        const double v = (1 - fy) * ((1 - fx) * p[y0 * w + x0] + fx * p[y0 * w + x1]) +
                         fy * ((1 - fx) * p[y1 * w + x0] + fx * p[y1 * w + x1]);
        o[(ch * height + y) * width + x] = static_cast<float>(v);
      }
    }
  }
  return out;
}

namespace {

struct RayList {
  std::vector<double> o, d, rgb, dist, sky;
  void push(const glm::dvec3& origin, const glm::dvec3& dir, const float* c, int64_t plane, double distance,
            double is_sky) {
    o.insert(o.end(), {origin.x, origin.y, origin.z});
    d.insert(d.end(), {dir.x, dir.y, dir.z});
    rgb.insert(rgb.end(), {c[0], c[plane], c[2 * plane]});
    dist.push_back(distance);
    sky.push_back(is_sky);
  }
};

}  // namespace

StreetItem make_street_item(const StreetSample& sample, size_t input_view, const VsgGrid& grid_template,
                            const StreetBatchOptions& opt, uint64_t seed, uint64_t stream) {
  SL_CHECK(input_view < sample.views.size(), "street sample '", sample.id, "': input view ", input_view, " of ",
           sample.views.size());
  const StreetView& view = sample.views[input_view];
  StreetItem it;
  it.frame = canonical_frame(view.camera);
  it.camera = it.frame.camera(view.camera);
  it.grid = grid_template;
  it.grid.center = it.camera.position();
  // The network's input, with the sample's tone curve (data/street_dataset.h input_tone_gamma).
  Tensor input = view.ldr;
  if (sample.input_tone_gamma != 1.0) {
    input = view.ldr.to(DType::F32).clone().contiguous();
    float* p = input.data<float>();
    const float g = static_cast<float>(sample.input_tone_gamma);
    for (int64_t i = 0; i < input.numel(); ++i) p[i] = std::pow(std::max(p[i], 0.0f), g);
  }
  it.image = resize_bilinear(input, opt.image_height, opt.image_width);
  if (opt.need_volume) it.rgba = unproject_rgba(input, view.depth, it.camera, it.grid);
  const Tensor pano_ldr = it.frame.panorama(sample.pano_ldr.contiguous());
  const Tensor pano_mask = it.frame.panorama(sample.pano_sky_mask.contiguous());
  it.pano_ldr_dome = resize_area(pano_ldr, static_cast<int>(opt.dome_height), static_cast<int>(opt.dome_width));
  it.pano_mask_dome =
      binarize_mask(resize_area(pano_mask, static_cast<int>(opt.dome_height), static_cast<int>(opt.dome_width)));
  it.sun_direction = it.frame.direction(sample.sun_direction);
  if (sample.sun_known && sample.hdr_sky && sample.sky_hdr.defined()) {
    it.sun_energy = data::sun_energy_rgb(sample.sky_hdr, sample.sun_direction) * sample.exposure;
    it.sun_energy_known = true;
  }

  // Rays (Sec 3.4): panorama rays from the panorama's centre, then rays of every view.
  const double nan = std::numeric_limits<double>::quiet_NaN();
  Rng rng(seed, stream);
  RayList rays;
  {
    const int64_t hp = pano_ldr.size(1), wp = pano_ldr.size(2), plane = hp * wp;
    const glm::dvec3 origin = it.frame.point(sample.pano_position);
    const float* c = pano_ldr.data<float>();
    const float* m = pano_mask.data<float>();
    for (int64_t r = 0; r < opt.pano_rays; ++r) {
      const int64_t row = rng.randint(hp), col = rng.randint(wp);
      const auto d =
          render::equirect::uv_to_direction(col + 0.5, row + 0.5, static_cast<int>(wp), static_cast<int>(hp));
      rays.push(origin, {d.x, d.y, d.z}, c + row * wp + col, plane, nan, m[row * wp + col] >= 0.5f ? 1.0 : 0.0);
    }
  }
  std::vector<Tensor> ldr(sample.views.size()), mask(sample.views.size()), depth(sample.views.size());
  std::vector<Camera> cams(sample.views.size());
  for (size_t v = 0; v < sample.views.size(); ++v) {
    ldr[v] = sample.views[v].ldr.contiguous();
    mask[v] = sample.views[v].sky_mask.contiguous();
    depth[v] = sample.views[v].depth.contiguous();
    cams[v] = it.frame.camera(sample.views[v].camera);
  }
  for (int64_t r = 0; r < opt.view_rays && !sample.views.empty(); ++r) {
    const size_t v = static_cast<size_t>(rng.randint(static_cast<int64_t>(sample.views.size())));
    const int64_t h = ldr[v].size(1), w = ldr[v].size(2), plane = h * w;
    const int64_t row = rng.randint(h), col = rng.randint(w);
    const CameraRay ray = cams[v].pixel_ray(static_cast<int>(col), static_cast<int>(row));
    const double z = depth[v].data<float>()[row * w + col];
    const bool is_sky = mask[v].data<float>()[row * w + col] >= 0.5f;
    const double dist = (std::isfinite(z) && z > 0 && !is_sky)
                            ? z * glm::length(cams[v].camera_direction(col + 0.5, row + 0.5))
                            : nan;
    rays.push(ray.origin, ray.direction, ldr[v].data<float>() + row * w + col, plane, dist, is_sky ? 1.0 : 0.0);
  }
  const int64_t n = static_cast<int64_t>(rays.dist.size());
  it.origins = Tensor::from_vector(rays.o, {n, 3});
  it.directions = Tensor::from_vector(rays.d, {n, 3});
  it.target_ldr = Tensor::from_vector(rays.rgb, {n, 3});
  it.target_distance = Tensor::from_vector(rays.dist, {n});
  it.sky = Tensor::from_vector(rays.sky, {n});
  return it;
}

}  // namespace sl::train
