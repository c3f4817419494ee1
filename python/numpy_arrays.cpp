// numpy arrays in and out of the library's tensors. See numpy_arrays.h.
#include "python/numpy_arrays.h"

#include <array>
#include <cmath>
#include <cstring>

#include "train/photo_input.h"
#include "util/math.h"

namespace sl::python {

std::string describe_array(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) {
    if (i > 0) s += ", ";
    s += std::to_string(a.shape(i));
  }
  if (a.ndim() == 1) s += ",";
  return s + ") " + std::string(py::str(a.dtype()));
}

Tensor ldr_from_image(const py::array& image) {
  SL_CHECK(image.ndim() == 3 && image.shape(2) == 3 && image.shape(0) > 0 && image.shape(1) > 0,
           "image: expected an H x W x 3 array (uint8 sRGB or float32 linear), got ", describe_array(image));
  const int64_t h = image.shape(0), w = image.shape(1);
  Tensor ldr = Tensor::empty({3, h, w});
  float* out = ldr.data<float>();
  if (image.dtype().is(py::dtype::of<uint8_t>())) {
    const auto v = py::array_t<uint8_t, py::array::c_style>::ensure(image);
    const uint8_t* in = v.data();
    // OpenImageIO's 8-bit to float conversion (the tools read PNGs with it): v * (1/255).
    constexpr float kScale = 1.0f / 255.0f;
    for (int64_t c = 0; c < 3; ++c)
      for (int64_t i = 0; i < h * w; ++i) out[c * h * w + i] = static_cast<float>(in[i * 3 + c]) * kScale;
  } else if (image.dtype().is(py::dtype::of<float>())) {
    const auto v = py::array_t<float, py::array::c_style>::ensure(image);
    const float* in = v.data();
    for (int64_t c = 0; c < 3; ++c)
      for (int64_t i = 0; i < h * w; ++i) {
        const float x = in[i * 3 + c];
        SL_CHECK(std::isfinite(x), "image: a float32 image must be finite linear radiance, got ", x, " at pixel ", i / w,
                 ", ", i % w);
        out[c * h * w + i] = static_cast<float>(ldr_encode(std::max(0.0f, x)));
      }
  } else {
    fail("image: expected dtype uint8 (sRGB) or float32 (linear), got ", describe_array(image));
  }
  return ldr;
}

Tensor depth_from_array(const py::array& depth, int64_t height, int64_t width) {
  SL_CHECK(depth.ndim() == 2, "depth: expected an H x W array of metres, got ", describe_array(depth));
  SL_CHECK(depth.shape(0) == height && depth.shape(1) == width, "depth: ", describe_array(depth),
           " does not match the image's ", height, " x ", width);
  Tensor d = Tensor::empty({height, width});
  float* out = d.data<float>();
  if (depth.dtype().is(py::dtype::of<float>())) {
    const auto v = py::array_t<float, py::array::c_style>::ensure(depth);
    std::memcpy(out, v.data(), sizeof(float) * height * width);
  } else if (depth.dtype().is(py::dtype::of<double>())) {
    const auto v = py::array_t<double, py::array::c_style>::ensure(depth);
    for (int64_t i = 0; i < height * width; ++i) out[i] = static_cast<float>(v.data()[i]);
  } else {
    fail("depth: expected dtype float32 or float64, got ", describe_array(depth));
  }
  return d;
}

render::Intrinsics intrinsics_from(const py::handle& intrinsics, int width, int height) {
  render::Intrinsics k;
  const auto v = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(intrinsics);
  SL_CHECK(v && ((v.ndim() == 1 && v.shape(0) == 4) || (v.ndim() == 2 && v.shape(0) == 3 && v.shape(1) == 3)),
           "intrinsics: expected (fx, fy, cx, cy) or a 3 x 3 matrix, got ", std::string(py::repr(intrinsics)));
  const double* p = v.data();
  if (v.ndim() == 1) {
    k = render::Intrinsics{p[0], p[1], p[2], p[3], width, height};
  } else {
    std::array<double, 9> m{};
    std::copy(p, p + 9, m.begin());
    k = render::intrinsics_from_matrix3x3(m, width, height);
  }
  render::validate(k, "intrinsics");
  train::check_principal_point(k, "intrinsics");
  return k;
}

py::array_t<float> image_from_tensor(const Tensor& chw) {
  const Tensor t = chw.to(DType::F32).contiguous();
  SL_CHECK(t.dim() == 3, "image_from_tensor: expected [C, H, W], got ", t.describe());
  const int64_t c = t.size(0), h = t.size(1), w = t.size(2);
  py::array_t<float> out = c == 1 ? py::array_t<float>({h, w}) : py::array_t<float>({h, w, c});
  float* o = out.mutable_data();
  const float* in = t.data<float>();
  for (int64_t ch = 0; ch < c; ++ch)
    for (int64_t i = 0; i < h * w; ++i) o[i * c + ch] = in[ch * h * w + i];
  return out;
}

py::array_t<uint8_t> uint8_from_ldr(const Tensor& ldr) {
  const Tensor t = ldr.contiguous();
  const int64_t h = t.size(1), w = t.size(2);
  py::array_t<uint8_t> out({h, w, int64_t{3}});
  uint8_t* o = out.mutable_data();
  const float* in = t.data<float>();
  for (int64_t c = 0; c < 3; ++c)
    for (int64_t i = 0; i < h * w; ++i)
      o[i * 3 + c] = static_cast<uint8_t>(std::lround(std::clamp(in[c * h * w + i], 0.0f, 1.0f) * 255.0f));
  return out;
}

}  // namespace sl::python
