// The labels an augmented dataset needs (paper Sec 4.4): 2D boxes from an object's mask and
// KITTI label lines. Placements, the object frame and 3D boxes are data/object_placement.h's.
// Guarantees: kitti_label_line() prints the 15 fields of the KITTI object benchmark
// (type truncated occluded alpha x1 y1 x2 y2 h w l x y z ry) with alpha = ry − atan2(x, z)
// wrapped to (−π, π]. mask_box2d() returns false when no pixel of the mask exceeds threshold.
// check_kitti_class() returns its name when it is one of the object benchmark's classes.
// Throws: sl::Error for a mask that is not [1, H, W], and for a class name KITTI does not have
// (naming `what`, the value and the classes).
#pragma once
#include <array>
#include <string>

#include "autodiff/tensor.h"

namespace sl::train {

// x1 y1 x2 y2 (pixel edges, x2/y2 exclusive) of the pixels of mask [1, H, W] above threshold.
bool mask_box2d(const Tensor& mask, double threshold, std::array<double, 4>& box);
std::string kitti_label_line(const std::string& type, double truncated, int occluded,
                             const std::array<double, 4>& box2d, const std::array<double, 7>& box3d);

// The object benchmark's classes an inserted object can be labelled with (its devkit's type field,
// DontCare aside): Car, Van, Truck, Pedestrian, Person_sitting, Cyclist, Tram, Misc.
const std::string& check_kitti_class(const std::string& name, const std::string& what);

}  // namespace sl::train
