// Placements and place_object() (see object_placement.h).
#include "render/object_placement.h"

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include "util/error.h"
#include "util/math.h"

namespace sl::render {

Bounds3 PlacedObject::world_bounds() const { return mesh.bounds(); }

glm::dvec3 rotate_yaw(const glm::dvec3& v, double yaw_rad) {
  const double c = std::cos(yaw_rad), s = std::sin(yaw_rad);
  return {c * v.x + s * v.z, v.y, -s * v.x + c * v.z};
}

namespace {

// The camera's right and forward axes projected onto the ground and normalised: the axes of its
// ground frame.
std::pair<glm::dvec3, glm::dvec3> ground_axes(const Camera& camera) {
  const glm::dvec3 right = camera.rotation()[0], fwd = camera.rotation()[2];
  return {glm::normalize(glm::dvec3(right.x, 0, right.z)), glm::normalize(glm::dvec3(fwd.x, 0, fwd.z))};
}

}  // namespace

Placement placement_in_camera_ground_frame(const Camera& camera, double right_m, double forward_m, double yaw_deg,
                                           double scale) {
  const auto [r_h, f_h] = ground_axes(camera);
  const glm::dvec3 ground = camera.position() + right_m * r_h + forward_m * f_h;
  return Placement{ground.x, ground.z, yaw_deg, scale};
}

PixelPlacement placement_at_pixel(const Camera& camera, const Tensor& depth, int col, int row, double yaw_deg,
                                  double scale) {
  const Intrinsics& k = camera.intrinsics();
  SL_CHECK(depth.defined() && depth.dim() == 2 && depth.size(0) == k.height && depth.size(1) == k.width,
           "placement_at_pixel: expected a depth map [", k.height, ", ", k.width, "], got ",
           depth.defined() ? depth.describe() : std::string("undefined"));
  SL_CHECK(col >= 0 && col < k.width && row >= 0 && row < k.height, "pixel (", col, ", ", row,
           ") lies outside the ", k.width, "x", k.height, " image");
  const double z = depth.contiguous().to(DType::F64).data<double>()[static_cast<size_t>(row) * k.width + col];
  SL_CHECK(std::isfinite(z) && z > 0.0, "pixel (", col, ", ", row, ") sees no surface (depth ", z,
           ": sky or a hole in the depth); pick a pixel on the ground");
  const glm::dvec3 p = camera.unproject(col + 0.5, row + 0.5, z);
  const auto [r_h, f_h] = ground_axes(camera);
  const glm::dvec3 d = p - camera.position();
  // r_h and f_h are orthonormal on the ground for any yaw and pitch without roll; solve the 2x2
  // system in general so that a rolled camera also round-trips.
  const double a = r_h.x, b = f_h.x, c = r_h.z, e = f_h.z, det = a * e - b * c;
  SL_CHECK(std::abs(det) > 1e-12, "placement_at_pixel: the camera looks straight up or down");
  PixelPlacement out;
  out.placement = Placement{p.x, p.z, yaw_deg, scale};
  out.right_m = (d.x * e - b * d.z) / det;
  out.forward_m = (a * d.z - c * d.x) / det;
  return out;
}

void check_placement(const Mesh& mesh, const Placement& p, const char* fn) {
  SL_CHECK(mesh.triangle_count() > 0 && !mesh.bounds().empty(), fn, ": the object mesh is empty");
  SL_CHECK(std::isfinite(p.x_m) && std::isfinite(p.z_m) && std::isfinite(p.yaw_deg), fn, ": placement (x ", p.x_m,
           ", z ", p.z_m, ", yaw ", p.yaw_deg, ") must be finite");
  SL_CHECK(std::isfinite(p.scale) && p.scale > 0.0, fn, ": placement scale must be finite and > 0, got ", p.scale);
}

Mesh placed_mesh(const Mesh& mesh, const Placement& p, const glm::dvec3& origin, double ground_y_m) {
  check_placement(mesh, p, "placed_mesh");
  const double yaw = p.yaw_deg * kPi / 180.0;
  const glm::dvec3 at(p.x_m, ground_y_m, p.z_m);
  Mesh out = mesh;
  for (glm::vec3& v : out.positions) v = glm::vec3(rotate_yaw((glm::dvec3(v) - origin) * p.scale, yaw) + at);
  for (glm::vec3& n : out.normals) n = glm::vec3(rotate_yaw(glm::dvec3(n), yaw));  // uniform scale keeps normals
  return out;
}

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
  check_placement(mesh, placement, "place_object");
  SL_CHECK(depth.dim() == 2 && depth.size(0) == camera.intrinsics().height && depth.size(1) == camera.intrinsics().width,
           "place_object: depth ", depth.describe(), " does not match the camera's ", camera.intrinsics().width, "x",
           camera.intrinsics().height, " image");
  const Bounds3 b = mesh.bounds();
  const glm::dvec3 base_centre((b.lo.x + b.hi.x) * 0.5, b.lo.y, (b.lo.z + b.hi.z) * 0.5);
  const double half_footprint = 0.5 * placement.scale * std::max(b.hi.x - b.lo.x, b.hi.z - b.lo.z);

  const Projection at = camera.project({placement.x_m, 0.0, placement.z_m});
  SL_CHECK(at.in_front, "place_object: position (x ", placement.x_m, ", z ", placement.z_m,
           ") is behind the camera");
  SL_CHECK(at.in_image, "place_object: position (x ", placement.x_m, ", z ", placement.z_m,
           ") is outside the image (it projects to pixel ", at.pixel.x, ", ", at.pixel.y, ")");

  double ground = ground_height(camera, depth, placement.x_m, placement.z_m, std::max(0.25, half_footprint));
  if (!std::isfinite(ground)) ground = 0.0;  // the world's ground plane (docs/DESIGN.md, "World frame")

  PlacedObject obj;
  obj.position = {placement.x_m, ground, placement.z_m};
  obj.yaw_rad = placement.yaw_deg * kPi / 180.0;
  obj.scale = placement.scale;
  obj.mesh = placed_mesh(mesh, placement, base_centre, ground);
  obj.bvh = std::make_shared<Bvh>(obj.mesh);
  return obj;
}

}  // namespace sl::render
