// Object placement in a photo's world frame and the labels an augmented dataset needs
// (paper Sec 4.4): the object frame, KITTI 3D and 2D boxes, and KITTI label lines.
//
// Conventions are those of data/object_placement.h: an object-frame mesh has +Y up, its bottom
// on y = 0, its footprint centred on the origin and its length along +X; a pose maps it to the
// world as (x, 0, z) + R_y(yaw)·(scale·p) with R_y taking +X to (cos yaw, 0, −sin yaw), which is
// also what render/object_insertion.h's place_object() applies.
// Guarantees: kitti_label_line() prints the 15 fields of the KITTI object benchmark
// (type truncated occluded alpha x1 y1 x2 y2 h w l x y z ry) with alpha = ry − atan2(x, z)
// wrapped to (−π, π]. mask_box2d() returns false when no pixel of the mask exceeds threshold.
// Throws: sl::Error for an empty mesh or a non-positive scale, naming the function.
#pragma once
#include <array>
#include <string>

#include "autodiff/tensor.h"
#include "render/camera.h"
#include "render/mesh.h"

namespace sl::train {

struct ObjectPose {
  double x_m = 0.0, z_m = 0.0;  // world ground position
  double yaw_deg = 90.0;
  double scale = 1.0;
};

Mesh to_object_frame_mesh(const Mesh& mesh);
// The scale that makes the object `length_m` long (its longer horizontal side).
double scale_for_length(const Mesh& object_frame_mesh, double length_m);
// h w l x y z ry in `camera`'s OpenCV frame (KITTI object convention).
std::array<double, 7> object_box3d(const Mesh& object_frame_mesh, const ObjectPose& pose, const Camera& camera);
// x1 y1 x2 y2 (pixel edges, x2/y2 exclusive) of the pixels of mask [1, H, W] above threshold.
bool mask_box2d(const Tensor& mask, double threshold, std::array<double, 4>& box);
std::string kitti_label_line(const std::string& type, double truncated, int occluded,
                             const std::array<double, 4>& box2d, const std::array<double, 7>& box3d);

}  // namespace sl::train
