// Unprojection of an image into an RGBα volume on the VSG grid (Sec 3.2, "Lighting volume
// prediction branch"): every pixel with a valid depth is lifted to its 3D point, which lands in
// one voxel of the log-projected grid; a voxel's RGB is the mean colour of its points and its
// α is 1 when any point landed in it (occupancy), 0 otherwise.
//
// Requires: image [3, H, W] (any values), depth [H, W] camera-frame z in metres (0, negative,
// NaN and inf are holes), a camera whose intrinsics match H×W, the grid the VSG lives on.
// Guarantees: output F32 [4, X, Y, Z] in the grid's layout (vsg_volume.h), finite; points
// outside the grid are dropped. Not differentiable (its inputs are data). Deterministic.
#pragma once
#include "autodiff/tensor.h"
#include "render/camera.h"
#include "render/vsg_volume.h"

namespace sl::train {

Tensor unproject_rgba(const Tensor& image, const Tensor& depth, const render::Camera& camera,
                      const render::VsgGrid& grid);

}  // namespace sl::train
