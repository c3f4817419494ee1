// place_object(): puts a mesh on the ground the depth map shows (see object_insertion.h).
#include <algorithm>
#include <cmath>

#include "render/object_insertion.h"

namespace sl {

Bounds3 PlacedObject::world_bounds() const { return mesh.bounds(); }

namespace {

bool valid_depth(double d) { return std::isfinite(d) && d > 0.0; }

// Median world height of the depth map's points within `radius` of (x, z); NaN when none.
double ground_height(const Camera& camera, const Tensor& depth, double x, double z, double radius) {
  const Tensor d = depth.detach().to(DType::F64).contiguous();
  const int64_t H = d.size(0), W = d.size(1);
  const double* pd = d.data<double>();
  std::vector<double> heights;
  for (int64_t i = 0; i < H; ++i)
    for (int64_t j = 0; j < W; ++j) {
      const double z_cam = pd[i * W + j];
      if (!valid_depth(z_cam)) continue;
      const glm::dvec3 p = camera.unproject(j + 0.5, i + 0.5, z_cam);
      if (std::abs(p.x - x) <= radius && std::abs(p.z - z) <= radius) heights.push_back(p.y);
    }
  if (heights.empty()) return std::nan("");
  std::nth_element(heights.begin(), heights.begin() + heights.size() / 2, heights.end());
  return heights[heights.size() / 2];
}

}  // namespace

PlacedObject place_object(const Mesh& mesh, const Placement& placement, const Camera& camera, const Tensor& depth) {
  SL_CHECK(mesh.triangle_count() > 0, "place_object: the mesh has no triangles");
  SL_CHECK(std::isfinite(placement.x) && std::isfinite(placement.z) && std::isfinite(placement.yaw_deg),
           "place_object: placement (", placement.x, ", ", placement.z, ", yaw ", placement.yaw_deg,
           ") must be finite");
  SL_CHECK(placement.scale > 0 && std::isfinite(placement.scale), "place_object: scale ", placement.scale,
           " must be positive");
  SL_CHECK(depth.dim() == 2 && depth.size(0) == camera.intrinsics().height && depth.size(1) == camera.intrinsics().width,
           "place_object: depth ", depth.describe(), " does not match the camera's ", camera.intrinsics().width, "x",
           camera.intrinsics().height, " image");
  const Bounds3 b = mesh.bounds();
  const glm::dvec3 base_centre((b.lo.x + b.hi.x) * 0.5, b.lo.y, (b.lo.z + b.hi.z) * 0.5);
  const double half_footprint = 0.5 * placement.scale * std::max(b.hi.x - b.lo.x, b.hi.z - b.lo.z);

  const Projection at = camera.project({placement.x, 0.0, placement.z});
  SL_CHECK(at.in_front, "place_object: position (x ", placement.x, ", z ", placement.z,
           ") is behind the camera");
  SL_CHECK(at.in_image, "place_object: position (x ", placement.x, ", z ", placement.z,
           ") is outside the image (it projects to pixel ", at.pixel.x, ", ", at.pixel.y, ")");

  double ground = ground_height(camera, depth, placement.x, placement.z, std::max(0.25, half_footprint));
  if (!std::isfinite(ground)) ground = 0.0;  // the world's ground plane (DESIGN)

  PlacedObject obj;
  obj.position = {placement.x, ground, placement.z};
  obj.yaw_rad = placement.yaw_deg * 3.14159265358979323846 / 180.0;
  obj.scale = placement.scale;
  obj.mesh = mesh;
  const double c = std::cos(obj.yaw_rad), s = std::sin(obj.yaw_rad);
  // Yaw about +Y (counter-clockwise seen from above), then scale, then translate.
  auto rotate = [c, s](const glm::dvec3& v) { return glm::dvec3(c * v.x + s * v.z, v.y, -s * v.x + c * v.z); };
  for (glm::vec3& p : obj.mesh.positions)
    p = glm::vec3(rotate((glm::dvec3(p) - base_centre) * placement.scale) + obj.position);
  for (glm::vec3& n : obj.mesh.normals) n = glm::vec3(rotate(glm::dvec3(n)));
  obj.bvh = std::make_shared<Bvh>(obj.mesh);
  return obj;
}

}  // namespace sl
