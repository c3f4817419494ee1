// Object insertion into a photo with estimated lighting. See photo_insertion.h.
#include "train/photo_insertion.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "autodiff/ops.h"
#include "autodiff/tape.h"
#include "render/object_insertion.h"
#include "train/losses.h"
#include "util/math.h"

using sl::data::kitti_box3d;
using sl::render::Camera;
using sl::render::CameraRay;
using sl::render::insert_objects;
using sl::render::InsertionInputs;
using sl::render::InsertionOptions;
using sl::render::InsertionResult;
using sl::render::Intrinsics;
using sl::render::Mesh;
using sl::render::place_object;
using sl::render::Placement;
using sl::render::Projection;

namespace sl::train {

Tensor ground_plane_depth(const Camera& camera) {
  const Intrinsics& k = camera.intrinsics();
  Tensor depth = Tensor::zeros({k.height, k.width});
  float* d = depth.data<float>();
  const double h = camera.position().y;
  SL_CHECK(h > 0, "ground_plane_depth: the camera must be above the ground (height ", h, " m)");
  const glm::dvec3 forward = camera.rotation()[2];
  for (int r = 0; r < k.height; ++r)
    for (int c = 0; c < k.width; ++c) {
      const CameraRay ray = camera.pixel_ray(c, r);
      if (ray.direction.y >= -1e-6) continue;
      const double t = h / -ray.direction.y;
      const double z = t * glm::dot(ray.direction, forward);
      if (z > 0 && std::isfinite(z)) d[r * k.width + c] = static_cast<float>(z);
    }
  return depth;
}

namespace {

void check_on_ground(const Tensor& depth, const Camera& cam, const Placement& pose, double max_offset) {
  const Projection at = cam.project({pose.x_m, 0.0, pose.z_m});
  SL_CHECK(at.in_front, "object position (x ", pose.x_m, ", z ", pose.z_m, ") is behind the camera");
  SL_CHECK(at.in_image, "object position (x ", pose.x_m, ", z ", pose.z_m, ") is outside the image (pixel ",
           at.pixel.x, ", ", at.pixel.y, ")");
  const Tensor d = depth.detach().to(DType::F32).contiguous();
  const int64_t w = d.size(1);
  const int col = static_cast<int>(at.pixel.x), row = static_cast<int>(at.pixel.y);
  const float z = d.data<float>()[row * w + col];
  SL_CHECK(std::isfinite(z) && z > 0, "object position (x ", pose.x_m, ", z ", pose.z_m,
           ") is not on the ground: the depth map has no surface at pixel (", col, ", ", row, ")");
  // A surface nearer than the position occludes it (fine); one that lies far from y = 0 where
  // the ray meets it, at about the position's distance, means the spot is not ground.
  const glm::dvec3 p = cam.unproject(col + 0.5, row + 0.5, z);
  SL_CHECK(z < at.depth * 0.8 || std::abs(p.y) <= max_offset, "object position (x ", pose.x_m, ", z ", pose.z_m,
           ") is not on the ground: the depth map shows a surface at height ", p.y, " m there");
}

// KITTI truncation: 1 − (area of the projected box's 2D extent inside the image) / (its area);
// a box reaching behind the camera counts as fully truncated.
double box_truncation(const std::array<double, 7>& b, const Intrinsics& k) {
  const double h = b[0], w = b[1], l = b[2], c = std::cos(b[6]), s = std::sin(b[6]);
  double u0 = 1e300, v0 = 1e300, u1 = -1e300, v1 = -1e300;
  for (int i = 0; i < 8; ++i) {
    const double dx = ((i & 1) ? 0.5 : -0.5) * l, dz = ((i & 2) ? 0.5 : -0.5) * w, dy = (i & 4) ? -h : 0.0;
    const double x = b[3] + c * dx + s * dz, y = b[4] + dy, z = b[5] - s * dx + c * dz;
    if (z <= 0.1) return 1.0;
    const double u = k.fx * x / z + k.cx, v = k.fy * y / z + k.cy;
    u0 = std::min(u0, u), u1 = std::max(u1, u), v0 = std::min(v0, v), v1 = std::max(v1, v);
  }
  const double area = (u1 - u0) * (v1 - v0);
  const double in_w = std::max(0.0, std::min(u1, double(k.width)) - std::max(u0, 0.0));
  const double in_h = std::max(0.0, std::min(v1, double(k.height)) - std::max(v0, 0.0));
  return area > 0 ? std::clamp(1.0 - in_w * in_h / area, 0.0, 1.0) : 1.0;
}

}  // namespace

PhotoInsertionOptions fast_insertion_options() {
  PhotoInsertionOptions o;
  o.light_samples = 6;
  o.shadow_rays = 128;
  o.exact_light_rays = 0;
  o.shadow_exact_rays = 0;
  return o;
}

InsertionOptions insertion_options(const PhotoInsertionOptions& o) {
  InsertionOptions io;
  io.aa_samples = o.aa_samples;
  io.light_samples = o.light_samples;
  io.shadow_width = o.shadow_width;
  io.shadow_height = o.shadow_height;
  io.shadow_rays = o.shadow_rays;
  io.ambient = o.ambient;
  io.importance_sampling = true;
  io.seed = o.seed;
  io.query = o.volume_query;
  io.radiance_cache = o.radiance_cache;
  io.cache_spacing_m = o.cache_spacing_m;
  io.cache_shadow_max_xz = o.cache_shadow_max_xz;
  io.cache_max_y = o.cache_max_y;
  io.cache_height = o.cache_height;
  io.cache_width = 2 * o.cache_height;
  io.cache_shadow_height = o.cache_shadow_height;
  io.diffuse_control_variate = o.diffuse_control_variate;
  io.adaptive_light_samples = o.adaptive_light_samples;
  io.denoise_radius = o.denoise_radius;
  io.bilinear_env_sampling = o.bilinear_env_sampling;
  io.stratify_per_pixel = o.stratify_per_pixel;
  io.cache_exact_light_rays = o.exact_light_rays;
  io.cache_exact_filter_radius = o.exact_light_radius;
  io.cache_shadow_exact_rays = o.shadow_exact_rays;
  io.cache_shadow_exact_filter_radius = o.shadow_exact_radius;
  return io;
}

InsertionInputs photo_insertion_inputs(const EstimatedLighting& lighting, const Tensor& ldr, const Tensor& depth,
                                       const Camera& world_camera, const Mesh& object_frame_mesh, const Placement& pose,
                                       const PhotoInsertionOptions& o) {
  NoGradGuard no_grad;
  const Intrinsics& k = world_camera.intrinsics();
  SL_CHECK(ldr.dim() == 3 && ldr.size(0) == 3 && ldr.size(1) == k.height && ldr.size(2) == k.width, "insertion: image ",
           ldr.describe(), " does not match the camera's ", k.width, "x", k.height);
  SL_CHECK(depth.dim() == 2 && depth.size(0) == k.height && depth.size(1) == k.width, "insertion: depth ",
           depth.describe(), " does not match the image's ", k.width, "x", k.height);
  check_on_ground(depth, world_camera, pose, o.max_ground_offset_m);
  InsertionInputs in;
  in.background = pow_scalar(ldr.to(DType::F32).contiguous(), kLdrGamma);
  in.depth = depth.to(DType::F32).contiguous();
  in.camera = lighting.frame.camera(world_camera);
  in.env = lighting.env;
  in.vsg = lighting.vsg;
  in.grid = lighting.grid;
  const glm::dvec3 at = lighting.frame.point({pose.x_m, 0.0, pose.z_m});
  Placement p;
  p.x_m = at.x;
  p.z_m = at.z;
  p.yaw_deg = lighting.frame.object_yaw_deg(pose.yaw_deg);
  p.scale = pose.scale;
  in.objects.push_back(place_object(object_frame_mesh, p, in.camera, in.depth));
  const double ground_y_m = in.objects.back().position.y;
  SL_CHECK(std::abs(ground_y_m) <= o.max_ground_offset_m, "object position (x ", pose.x_m, ", z ", pose.z_m,
           ") is not on the ground: the depth map puts the surface there at y = ", ground_y_m, " m");
  return in;
}

PhotoInsertion insert_into_photo(const EstimatedLighting& lighting, const Tensor& ldr, const Tensor& depth,
                                 const Camera& world_camera, const Mesh& object_frame_mesh, const Placement& pose,
                                 const PhotoInsertionOptions& o) {
  NoGradGuard no_grad;
  const auto t0 = std::chrono::steady_clock::now();
  const InsertionInputs in = photo_insertion_inputs(lighting, ldr, depth, world_camera, object_frame_mesh, pose, o);
  PhotoInsertion out;
  out.ground_y_m = in.objects.back().position.y;
  const InsertionResult r = insert_objects(in, insertion_options(o));
  out.render_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  out.composite_linear = r.composite.detach().contiguous();
  out.composite_ldr = ldr_from_hdr(out.composite_linear).contiguous();
  out.object_mask = r.object_mask.detach().contiguous();
  out.shadow_map = mean(r.shadow_map.detach(), {0}, true).contiguous();
  out.visible = mask_box2d(out.object_mask, 0.5 / 255.0, out.box2d);
  out.box3d = kitti_box3d(object_frame_mesh, pose, world_camera);
  out.box3d[4] -= out.ground_y_m;  // the base sits at ground_y (camera y points down)
  out.object_depth = r.object_depth.detach().to(DType::F32).contiguous();
  const double seen = sum(r.object_mask.detach().to(DType::F64)).item();
  const double whole = sum(r.object_silhouette.detach().to(DType::F64)).item();
  out.hidden_fraction = whole > 0 ? std::clamp(1.0 - seen / whole, 0.0, 1.0) : 0.0;
  out.truncated = box_truncation(out.box3d, world_camera.intrinsics());
  return out;
}

}  // namespace sl::train
