// Placing an object-frame mesh (data/procedural_car.h frame: +Y up, bottom on y = 0, footprint
// centred on the origin, length along +X) on the ground of a street scene, and the KITTI-style
// boxes that describe the placement.
//
// A Placement (render/object_placement.h, the one type and yaw convention) maps object
// coordinates p to world coordinates (x, 0, z) + R_y(yaw) · (scale · p); render::placed_mesh()
// applies it, so yaw = +90° points the object's length down the street (world −Z).
// 3D box (KITTI object benchmark convention, in a camera's OpenCV frame): dimensions h, w, l
// (height, width along object Z, length along object X, scaled), location = the bottom-face
// centre in camera coordinates, rotation_y = the heading's angle about the camera's y axis,
// heading_cam = (cos ry, ·, −sin ry) — exact for a level camera, the projection of the
// heading onto the camera's x-z plane otherwise.
// Throws: sl::Error naming the function and value for an empty mesh, non-finite or
// non-positive scale.
#pragma once
#include <array>
#include <cstdint>

#include <glm/glm.hpp>

#include "data/street_scene.h"
#include "render/camera.h"
#include "render/mesh.h"
#include "render/object_placement.h"

namespace sl::data {

// Moves a mesh into the object frame: footprint centred on the origin, bottom on y = 0, and the
// longer horizontal extent along X (a model longer along Z is turned a quarter turn about +Y;
// which end is the front is unknown for an arbitrary model, so headings are ±180° ambiguous).
render::Mesh to_object_frame(const render::Mesh& mesh);
// Uniform scale that makes the longer horizontal extent `length_m`.
double scale_to_length(const render::Mesh& object_frame_mesh, double length_m);

// The placed object's axis-aligned world footprint.
FootprintXZ placed_footprint(const render::Mesh& object_frame_mesh, const render::Placement& placement);

// h w l x y z ry (see above).
std::array<double, 7> kitti_box3d(const render::Mesh& object_frame_mesh, const render::Placement& placement,
                                  const render::Camera& camera);

}  // namespace sl::data
