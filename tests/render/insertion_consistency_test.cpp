// Insertion against the reference path tracer : a ground plane of constant albedo plus
// CesiumMilkTruck under a real HDRI. The composite built from a path-traced background (without
// the truck) must match the path tracer's render of the full scene on the object and its shadow.
// Lives with the data tests because it reads the shared HDRI through OpenImageIO.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "autodiff/ops.h"
#include "data/image_io.h"
#include "render/environment_map.h"
#include "render/equirect.h"
#include "render/gltf_loader.h"
#include "render/object_insertion.h"
#include "render/path_tracer.h"
#include "render/primitives.h"
#include "util/math.h"

using sl::data::read_image;
using sl::render::Camera;
using sl::render::CameraRay;
using sl::render::EnvironmentMap;
using sl::render::insert_objects;
using sl::render::InsertionOptions;
using sl::render::InsertionResult;
using sl::render::intrinsics_from_fov;
using sl::render::load_gltf;
using sl::render::make_ground_plane;
using sl::render::Material;
using sl::render::Mesh;
using sl::render::PathTracer;
using sl::render::PathTracerOptions;
using sl::render::place_object;
using sl::render::PlacedObject;
using sl::render::resize_panorama;
using sl::render::rotation_from_yaw_pitch_roll;
using sl::render::VsgGrid;

namespace sl::test {
namespace {

const std::string kData = STREETLIGHT_SHARED_DATA;

// The HDRI at 64×128 with its lower hemisphere replaced by the ground plane's own radiance
// ρ·E/π (E = irradiance from the upper hemisphere on an upward plane). In the path tracer the
// plane hides the HDRI's ground; the insertion's radiance query must see the same thing.
Tensor ground_consistent_sky(const std::string& file, double albedo) {
  Tensor env = resize_panorama(read_image(file), 128, 64).contiguous();
  const int H = 64, W = 128;
  float* p = env.data<float>();
  for (int c = 0; c < 3; ++c) {
    double E = 0;
    for (int i = 0; i < H / 2; ++i) {
      const double omega = render::equirect::pixel_solid_angle(i, W, H);
      const double cos_t = std::sin((0.5 - (i + 0.5) / H) * kPi);
      for (int j = 0; j < W; ++j) E += p[(c * H + i) * W + j] * cos_t * omega;
    }
    const float ground = float(albedo * E / kPi);
    for (int i = H / 2; i < H; ++i)
      for (int j = 0; j < W; ++j) p[(c * H + i) * W + j] = ground;
  }
  return env;
}

TEST(InsertionConsistency, CompositeMatchesPathTracedFullSceneOnObjectAndShadow) {
  const std::string hdri = kData + "/hdri/chinese_garden_1k.hdr", truck_file = kData + "/models/CesiumMilkTruck.glb";
  if (!std::filesystem::exists(hdri) || !std::filesystem::exists(truck_file))
    GTEST_SKIP() << "shared data not found at " << kData << " (needs hdri/chinese_garden_1k.hdr and models/CesiumMilkTruck.glb)";
  const double albedo = 0.4;
  const int W = 96, H = 64;
  const Tensor env = ground_consistent_sky(hdri, albedo);
  const Camera cam(intrinsics_from_fov(60 * kDegToRad, W, H), rotation_from_yaw_pitch_roll(0, -12 * kDegToRad, 0), {0, 1.6, 0});
  std::vector<double> d(size_t(W) * H);
  for (int i = 0; i < H; ++i)
    for (int j = 0; j < W; ++j) {
      const CameraRay r = cam.pixel_ray(j, i);
      d[size_t(i) * W + j] = r.direction.y < -1e-6 ? cam.world_to_camera(r.origin + (-1.6 / r.direction.y) * r.direction).z : INFINITY;
    }
  const Tensor depth = Tensor::from_vector(d, {H, W});

  Material ground_mat;
  ground_mat.base_color_factor = glm::vec4(float(albedo), float(albedo), float(albedo), 1);
  ground_mat.metallic = 0;
  ground_mat.roughness = 1;
  const Mesh ground = make_ground_plane(400.0f, 0.0f, ground_mat);
  const PlacedObject truck = place_object(load_gltf(truck_file), {0.5, -9.0, 35.0, 1.0}, cam, depth);
  Mesh full = ground;
  full.append(truck.mesh);

  const EnvironmentMap env_map(env);
  PathTracerOptions pt;
  pt.spp = 256;
  pt.max_depth = 4;
  pt.seed = 7;
  const Tensor background = PathTracer(ground, env_map).render(cam, pt).radiance;
  const Tensor reference = PathTracer(full, env_map).render(cam, pt).radiance;

  InsertionOptions opt;
  opt.aa_samples = 4;
  opt.light_samples = 128;
  opt.shadow_width = W / 2;
  opt.shadow_height = H / 2;
  opt.shadow_rays = 256;
  opt.importance_sampling = true;
  opt.ambient = 0.0;  // physical occlusion; see the tolerance note below
  const InsertionResult r = insert_objects({background, depth, cam, env, Tensor(), VsgGrid(), {truck}}, opt);

  // Object: pixels fully covered. Shadow: ground pixels the truck darkens by > 10% in the reference.
  const auto comp = r.composite.to_vector(), ref = reference.to_vector(), bg = background.to_vector();
  const auto mask = r.object_mask.to_vector();
  double obj_c = 0, obj_r = 0, sh_c = 0, sh_r = 0;
  int n_obj = 0, n_sh = 0;
  for (int p = 0; p < W * H; ++p) {
    double c = 0, rf = 0, b = 0;
    for (int ch = 0; ch < 3; ++ch) {
      c += comp[ch * W * H + p];
      rf += ref[ch * W * H + p];
      b += bg[ch * W * H + p];
    }
    if (mask[p] >= 0.999) {
      obj_c += c;
      obj_r += rf;
      ++n_obj;
    } else if (mask[p] == 0.0 && b > 0 && rf < 0.9 * b) {
      sh_c += c;
      sh_r += rf;
      ++n_sh;
    }
  }
  ASSERT_GT(n_obj, 50);
  ASSERT_GT(n_sh, 20);
  const double obj_err = std::abs(obj_c / obj_r - 1), sh_err = std::abs(sh_c / sh_r - 1);
  RecordProperty("object_relative_error", std::to_string(obj_err));
  RecordProperty("shadow_relative_error", std::to_string(sh_err));
  std::fprintf(stderr, "object pixels %d: mean radiance ratio insertion/path tracer %.4f\n", n_obj, obj_c / obj_r);
  std::fprintf(stderr, "shadow pixels %d: mean radiance ratio insertion/path tracer %.4f\n", n_sh, sh_c / sh_r);
  // Tolerance 10%. The insertion is single-bounce: it ignores light the truck bounces onto the
  // ground and onto itself, which the path tracer (4 bounces) includes; both are Monte Carlo
  // (256 spp / 128 light and 256 shadow samples). Measured: object 1.035, shadow 1.019.
  // With the paper's I_a = 0.1 the object reads 1.046 and the shadow 1.30: the ambient term
  // lets a tenth of the blocked sun (71% of this sky's energy) into the shadow.
  EXPECT_LT(obj_err, 0.10);
  EXPECT_LT(sh_err, 0.10);
}

}  // namespace
}  // namespace sl::test
