#include "data/object_placement.h"

#include <cmath>

#include "util/error.h"
#include "util/math.h"

using sl::render::Bounds3;
using sl::render::Camera;
using sl::render::check_placement;
using sl::render::Mesh;
using sl::render::Placement;
using sl::render::rotate_yaw;

namespace sl::data {
namespace {

void check_object(const Mesh& m, const char* fn) {
  SL_CHECK(m.triangle_count() > 0 && !m.bounds().empty(), fn, ": the object mesh is empty");
}

}  // namespace

Mesh to_object_frame(const Mesh& mesh) {
  check_object(mesh, "to_object_frame");
  Mesh out = mesh;
  const glm::vec3 e = mesh.bounds().extent();
  if (e.z > e.x) {
    // Length along X (KITTI's heading axis): a quarter turn about +Y, (x, z) → (z, −x).
    for (glm::vec3& p : out.positions) p = glm::vec3(p.z, p.y, -p.x);
    for (glm::vec3& n : out.normals) n = glm::vec3(n.z, n.y, -n.x);
  }
  const Bounds3 b = out.bounds();
  const glm::vec3 shift(0.5f * (b.lo.x + b.hi.x), b.lo.y, 0.5f * (b.lo.z + b.hi.z));
  for (glm::vec3& p : out.positions) p -= shift;
  return out;
}

double scale_to_length(const Mesh& m, double length_m) {
  check_object(m, "scale_to_length");
  SL_CHECK(std::isfinite(length_m) && length_m > 0.0, "scale_to_length: length_m must be > 0, got ", length_m);
  const glm::vec3 e = m.bounds().extent();
  const double longest = std::max(e.x, e.z);
  SL_CHECK(longest > 0.0, "scale_to_length: the object has no horizontal extent");
  return length_m / longest;
}

FootprintXZ placed_footprint(const Mesh& object, const Placement& p) {
  check_placement(object, p, "placed_footprint");
  const Bounds3 b = object.bounds();
  const double yaw = p.yaw_deg * kDegToRad;
  FootprintXZ f{1e30, 1e30, -1e30, -1e30, "object"};
  for (float x : {b.lo.x, b.hi.x})
    for (float z : {b.lo.z, b.hi.z}) {
      const glm::dvec3 w = rotate_yaw(p.scale * glm::dvec3(x, 0.0, z), yaw);
      f.x0 = std::min(f.x0, w.x + p.x_m);
      f.x1 = std::max(f.x1, w.x + p.x_m);
      f.z0 = std::min(f.z0, w.z + p.z_m);
      f.z1 = std::max(f.z1, w.z + p.z_m);
    }
  return f;
}

std::array<double, 7> kitti_box3d(const Mesh& object, const Placement& p, const Camera& camera) {
  check_placement(object, p, "kitti_box3d");
  const Bounds3 b = object.bounds();
  const glm::dvec3 e = p.scale * glm::dvec3(b.extent());
  const double yaw = p.yaw_deg * kDegToRad;
  // Bottom-face centre of the (scaled, rotated) object-frame box.
  const glm::dvec3 centre_obj(0.5 * (b.lo.x + b.hi.x), b.lo.y, 0.5 * (b.lo.z + b.hi.z));
  const glm::dvec3 bottom = rotate_yaw(p.scale * centre_obj, yaw) + glm::dvec3(p.x_m, 0.0, p.z_m);
  const glm::dvec3 loc = camera.world_to_camera(bottom);
  const glm::dvec3 heading_cam = glm::transpose(camera.rotation()) * rotate_yaw({1.0, 0.0, 0.0}, yaw);
  const double ry = std::atan2(-heading_cam.z, heading_cam.x);
  return {e.y, e.z, e.x, loc.x, loc.y, loc.z, ry};
}

}  // namespace sl::data
