// Placing a mesh in a street scene's world frame: the one Placement type, the one yaw
// convention, and place_object(), which sets an object on the ground a depth map shows.
//
// A Placement maps object coordinates p to world coordinates
//   p_world = (x_m, ground_y, z_m) + R_y(yaw) · (scale · (p − origin)),
//   R_y(yaw): +X → (cos yaw, 0, −sin yaw)   (counter-clockwise seen from above),
// so yaw = +90° points an object's length (+X) down the street (world −Z, away from a camera
// that looks down −Z). The object frame (data/object_placement.h, data/procedural_car.h) has
// +Y up, the bottom on y = 0, the footprint centred on the origin and the length along +X;
// for such a mesh origin = 0.
// Requires: a non-empty mesh, finite x, z and yaw, a finite scale > 0.
// Throws: sl::Error naming the function and the offending value; place_object() also names a
// position behind the camera or outside the depth map's view.
#pragma once
#include <memory>

#include <glm/glm.hpp>

#include "autodiff/tensor.h"
#include "render/bvh.h"
#include "render/camera.h"
#include "render/mesh.h"

namespace sl::render {

struct Placement {
  double x_m = 0.0, z_m = 0.0;  // world ground position (metres)
  double yaw_deg = 0.0;         // about +Y, see above
  double scale = 1.0;           // uniform
};

// R_y(yaw) of the header: +X → (cos yaw, 0, −sin yaw).
glm::dvec3 rotate_yaw(const glm::dvec3& v, double yaw_rad);

// The placement at (right_m, forward_m) in the camera's ground frame: from the camera's position,
// right_m along its right axis and forward_m along its viewing direction, both projected onto the
// ground plane (the frame of streetlight-insert --at X,Z). Yaw and scale are copied.
Placement placement_in_camera_ground_frame(const Camera& camera, double right_m, double forward_m, double yaw_deg,
                                           double scale = 1.0);

// The placement under a pixel: the point the photo shows at pixel (col, row) of `depth` ([H, W]
// camera-frame z in metres, the camera's size; 0, NaN or inf: nothing seen there), its world x and z,
// with yaw and scale copied; and that point's (right_m, forward_m) in the camera's ground frame above
// (so placement_in_camera_ground_frame(camera, right_m, forward_m, ...) is the same placement).
// Throws naming the pixel when it lies outside the image or sees nothing (sky, a depth hole).
struct PixelPlacement {
  Placement placement;
  double right_m = 0.0, forward_m = 0.0;
};
PixelPlacement placement_at_pixel(const Camera& camera, const Tensor& depth, int col, int row, double yaw_deg,
                                  double scale = 1.0);

// Throws unless the mesh has triangles and the placement is finite with scale > 0; `fn` names
// the caller in the message.
void check_placement(const Mesh& mesh, const Placement& placement, const char* fn);

// The mesh moved to the world by `placement` (above), its `origin` landing at (x_m, ground_y_m, z_m).
Mesh placed_mesh(const Mesh& mesh, const Placement& placement, const glm::dvec3& origin = glm::dvec3(0.0),
                 double ground_y_m = 0.0);

// A mesh in world coordinates with its BVH.
struct PlacedObject {
  Mesh mesh;
  std::shared_ptr<Bvh> bvh;
  glm::dvec3 position{0.0};  // footprint centre on the ground
  double yaw_rad = 0.0, scale = 1.0;
  Bounds3 world_bounds() const;
};

// Places `mesh` (any frame with +Y up; the centre of its bounds' bottom face is its origin) by
// yaw and scale at (x_m, z_m), its base on the ground height the depth map shows there (median
// height of the depth points over the footprint; y = 0 when none), and builds its BVH. `depth`
// is [H, W] camera-z depth matching the camera's image.
PlacedObject place_object(const Mesh& mesh, const Placement& placement, const Camera& camera, const Tensor& depth);

}  // namespace sl::render
