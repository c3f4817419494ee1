// A tiny in-memory street sample for the stage tests: a flat ground under a sky, two views.
#pragma once
#include <cmath>

#include "autodiff/tensor.h"
#include "data/street_dataset.h"
#include "render/camera.h"

namespace sl::train::test {

// Camera-z depth of the ground plane y = 0 seen from height h; 0 (sky) above the horizon.
inline Tensor ground_depth(const Camera& cam, double height) {
  const auto& k = cam.intrinsics();
  Tensor d = Tensor::zeros({k.height, k.width});
  float* p = d.data<float>();
  for (int r = 0; r < k.height; ++r)
    for (int c = 0; c < k.width; ++c) {
      const CameraRay ray = cam.pixel_ray(c, r);
      if (ray.direction.y < -1e-3) {
        const double t = height / -ray.direction.y;
        p[r * k.width + c] = static_cast<float>(cam.world_to_camera(ray.origin + t * ray.direction).z);
      }
    }
  return d;
}

inline StreetSample tiny_street_sample(uint64_t seed, int width = 32, int height = 16) {
  StreetSample s;
  s.id = "tiny" + std::to_string(seed);
  s.pano_ldr = Tensor::uniform({3, 16, 32}, 0.1, 0.9, seed);
  s.pano_hdr = s.pano_ldr.clone();
  s.pano_sky_mask = Tensor::zeros({1, 16, 32});
  for (int i = 0; i < 8 * 32; ++i) s.pano_sky_mask.data<float>()[i] = 1.0f;
  s.pano_position = {0.0, 1.6, 0.0};
  s.sun_direction = glm::normalize(glm::dvec3(0.3, 0.8, -0.5));
  s.sky_hdr = Tensor::uniform({3, 8, 32}, 0.5, 2.0, seed + 1);
  for (int v = 0; v < 2; ++v) {
    StreetView view;
    view.camera = Camera(intrinsics_from_fov(1.2, width, height), rotation_from_yaw_pitch_roll(0.4 * v, 0, 0),
                         {0.3 * v, 1.6, 0.0});
    view.ldr = Tensor::uniform({3, height, width}, 0.0, 1.0, seed * 7 + static_cast<uint64_t>(v));
    view.depth = ground_depth(view.camera, 1.6);
    view.sky_mask = Tensor::zeros({1, height, width});
    const float* d = view.depth.data<float>();
    for (int i = 0; i < width * height; ++i) view.sky_mask.data<float>()[i] = d[i] > 0 ? 0.0f : 1.0f;
    s.views.push_back(view);
  }
  return s;
}

}  // namespace sl::train::test
