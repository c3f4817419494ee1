// Street fixtures shared by the tests: a tiny generated street dataset (one per test process;
// rendering it takes well under a second at these sizes) and a tiny in-memory street sample (a
// flat ground under a sky, two views) for the stage tests.
#pragma once
#include <cmath>
#include <filesystem>
#include <string>

#include "autodiff/tensor.h"
#include "data/street_dataset.h"
#include "data/street_generator.h"
#include "render/camera.h"
#include "support/test_files.h"

namespace sl::test {

// The generator's defaults shrunk to thumbnail size and a few samples per pixel.
inline nlohmann::json tiny_generator_tree(int samples = 3) {
  nlohmann::json t = data::street_generator_defaults();
  t["samples"] = samples;
  t["seed"] = 7;
  t["render"] = {{"spp", 2}, {"max_depth", 2}, {"environment_width", 64}};
  t["panorama"] = {{"width", 32}, {"height", 16}};
  t["views"]["width"] = 48;
  t["views"]["height"] = 24;
  t["sky"]["width"] = 32;
  t["sky"]["height"] = 8;
  t["insertion"]["min_visible_pixels"] = 4;
  t["insertion"]["coverage_samples"] = 2;
  t["splits"] = {{"train", 0.34}, {"val", 0.33}};
  return t;
}

// Generates the tiny dataset once into `<scratch>/<name>` and returns the folder.
inline std::string tiny_dataset(const std::string& name = "tiny_dataset", int samples = 3) {
  const std::string out = scratch(name);
  if (std::filesystem::exists(std::filesystem::path(out) / "index.json")) return out;
  const data::StreetGeneratorConfig c = data::street_generator_config(tiny_generator_tree(samples));
  std::vector<std::string> ids;
  std::filesystem::create_directories(std::filesystem::path(out) / "samples");
  for (int64_t i = 0; i < c.samples; ++i) ids.push_back(data::generate_street_sample(c, i, out + "/samples").id);
  data::write_dataset_index(out, c, data::split_ids(ids, c.seed, c.train_fraction, c.val_fraction));
  return out;
}

// Camera-z depth of the ground plane y = 0 seen from height h; 0 (sky) above the horizon.
inline Tensor ground_depth(const render::Camera& cam, double height) {
  const auto& k = cam.intrinsics();
  Tensor d = Tensor::zeros({k.height, k.width});
  float* p = d.data<float>();
  for (int r = 0; r < k.height; ++r)
    for (int c = 0; c < k.width; ++c) {
      const render::CameraRay ray = cam.pixel_ray(c, r);
      if (ray.direction.y < -1e-3) {
        const double t = height / -ray.direction.y;
        p[r * k.width + c] = static_cast<float>(cam.world_to_camera(ray.origin + t * ray.direction).z);
      }
    }
  return d;
}

inline data::StreetSample tiny_street_sample(uint64_t seed, int width = 32, int height = 16) {
  data::StreetSample s;
  s.id = "tiny" + std::to_string(seed);
  s.pano_ldr = Tensor::uniform({3, 16, 32}, 0.1, 0.9, seed);
  s.pano_hdr = s.pano_ldr.clone();
  s.pano_sky_mask = Tensor::zeros({1, 16, 32});
  for (int i = 0; i < 8 * 32; ++i) s.pano_sky_mask.data<float>()[i] = 1.0f;
  s.pano_position = {0.0, 1.6, 0.0};
  s.sun_direction = glm::normalize(glm::dvec3(0.3, 0.8, -0.5));
  s.sky_hdr = Tensor::uniform({3, 8, 32}, 0.5, 2.0, seed + 1);
  for (int v = 0; v < 2; ++v) {
    data::StreetView view;
    view.camera = render::Camera(render::intrinsics_from_fov(1.2, width, height),
                                 render::rotation_from_yaw_pitch_roll(0.4 * v, 0, 0), {0.3 * v, 1.6, 0.0});
    view.ldr = Tensor::uniform({3, height, width}, 0.0, 1.0, seed * 7 + static_cast<uint64_t>(v));
    view.depth = ground_depth(view.camera, 1.6);
    view.sky_mask = Tensor::zeros({1, height, width});
    const float* d = view.depth.data<float>();
    for (int i = 0; i < width * height; ++i) view.sky_mask.data<float>()[i] = d[i] > 0 ? 0.0f : 1.0f;
    s.views.push_back(view);
  }
  return s;
}

}  // namespace sl::test
