// numpy arrays in and out of the library's tensors (python/bindings.h). Call with the GIL held.
//
// Contract:
// - ldr_from_image(): an H x W x 3 array, uint8 (an sRGB photo's stored values: v / 255, the
//   values the tools read from a PNG, so the paper's LDR) or float32 (linear radiance at exposure
//   1: clip(x^(1/2.2), 0, 1), util/math.h ldr_encode), to the LDR [3, H, W] the library takes.
// - depth_from_array(): an H x W float32 or float64 array of camera-z metres (holes 0/NaN/inf) to
//   [H, W] float32, matching the image's size.
// - intrinsics_from(): (fx, fy, cx, cy) or a 3 x 3 matrix, for an image of width x height;
//   checked as the tools check an intrinsics file (render/camera.h validate, principal point
//   inside the image).
// - image_from_tensor(): [C, H, W] to an H x W x C float32 array (H x W when C = 1), a copy.
// - uint8_from_ldr(): [3, H, W] in [0, 1] to the H x W x 3 uint8 it was read from.
// Throws: sl::Error (ValueError) naming the argument, its shape and dtype.
#pragma once
#include <string>

#include "autodiff/tensor.h"
#include "python/bindings.h"
#include "render/camera.h"

namespace sl::python {

Tensor ldr_from_image(const py::array& image);
Tensor depth_from_array(const py::array& depth, int64_t height, int64_t width);
render::Intrinsics intrinsics_from(const py::handle& intrinsics, int width, int height);
py::array_t<float> image_from_tensor(const Tensor& chw);
py::array_t<uint8_t> uint8_from_ldr(const Tensor& ldr);
// "(480, 640, 3) uint8" for messages.
std::string describe_array(const py::array& a);

}  // namespace sl::python
