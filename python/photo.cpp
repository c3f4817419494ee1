// streetlight.load_photo and streetlight.write_image: a photo, its intrinsics and depth read the
// way streetlight-insert reads them (train/photo_input.h), and images written the way it writes
// them (data/image_io.h).
#include <pybind11/stl.h>

#include <cmath>

#include "autodiff/ops.h"
#include "data/image_io.h"
#include "python/bindings.h"
#include "python/numpy_arrays.h"
#include "train/photo_input.h"

namespace sl::python {

namespace {

struct PyPhoto {
  py::array_t<uint8_t> image;
  py::tuple intrinsics;
  py::array_t<float> depth;
  std::string depth_source, intrinsics_source;
  double camera_height = 1.65, pitch = 0.0;
};

PyPhoto load(const std::string& image, const std::optional<std::string>& intrinsics, const std::optional<std::string>& depth,
             const std::optional<std::string>& lidar, const std::optional<std::string>& calib, double camera_height,
             double pitch, const std::optional<double>& fov) {
  train::PhotoSources s;
  s.image = image;
  s.intrinsics = path_or_empty(intrinsics);
  s.depth = path_or_empty(depth);
  s.lidar = path_or_empty(lidar);
  s.calib = path_or_empty(calib);
  s.camera_height_m = camera_height;
  s.pitch_deg = pitch;
  if (fov) {
    SL_CHECK(std::isfinite(*fov) && *fov > 0.0 && *fov < 180.0, "load_photo: fov must lie between 0 and 180 degrees, got ",
             *fov);
    s.fov_deg = *fov;
  }
  const train::Photo p = file_call({s.image, s.intrinsics, s.depth, s.lidar, s.calib}, [&] {
    Compute c;
    return train::load_photo(s);
  });
  const render::Intrinsics& k = p.camera.intrinsics();
  PyPhoto out;
  out.image = uint8_from_ldr(p.ldr);
  out.intrinsics = py::make_tuple(k.fx, k.fy, k.cx, k.cy);
  out.depth = image_from_tensor(reshape(p.depth, {1, p.depth.size(0), p.depth.size(1)}));
  out.depth_source = p.depth_source;
  out.intrinsics_source = p.intrinsics_source;
  out.camera_height = camera_height;
  out.pitch = pitch;
  return out;
}

void write(const std::string& path, const py::array& image) {
  Tensor t;
  if (image.ndim() == 2) {
    const auto v = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(image);
    SL_CHECK(v, "write_image: expected an H x W or H x W x 3 float array, got ", describe_array(image));
    t = Tensor::empty({1, v.shape(0), v.shape(1)});
    std::copy(v.data(), v.data() + v.size(), t.data<float>());
  } else {
    SL_CHECK(image.ndim() == 3 && image.shape(2) == 3 && image.dtype().is(py::dtype::of<float>()),
             "write_image: expected an H x W or H x W x 3 float32 array, got ", describe_array(image));
    const auto v = py::array_t<float, py::array::c_style>::ensure(image);
    const int64_t h = v.shape(0), w = v.shape(1);
    t = Tensor::empty({3, h, w});
    float* o = t.data<float>();
    for (int64_t c = 0; c < 3; ++c)
      for (int64_t i = 0; i < h * w; ++i) o[c * h * w + i] = v.data()[i * 3 + c];
  }
  data::ImageWriteOptions lin;
  lin.transfer = data::Transfer::Linear;
  file_call({}, [&] {
    Compute c;
    data::write_image(path, t, lin);
  });
}

}  // namespace

void bind_photo(py::module_& m) {
  py::class_<PyPhoto>(m, "Photo", "A street photo with its intrinsics and depth, as streetlight-insert reads it.")
      .def_readonly("image", &PyPhoto::image, "H x W x 3 uint8, the file's stored values")
      .def_readonly("intrinsics", &PyPhoto::intrinsics, "(fx, fy, cx, cy) in pixels")
      .def_readonly("depth", &PyPhoto::depth, "H x W float32 camera-z metres (0 where unknown)")
      .def_readonly("depth_source", &PyPhoto::depth_source, "'depth-file', 'lidar' or 'ground-plane'")
      .def_readonly("intrinsics_source", &PyPhoto::intrinsics_source, "'file', 'calib', 'fov' or 'exif'")
      .def_readonly("camera_height", &PyPhoto::camera_height, "metres above the ground")
      .def_readonly("pitch", &PyPhoto::pitch, "degrees, positive up");
  m.def("load_photo", &load, py::arg("image"), py::kw_only(), py::arg("intrinsics") = py::none(),
        py::arg("depth") = py::none(), py::arg("lidar") = py::none(), py::arg("calib") = py::none(),
        py::arg("camera_height") = 1.65, py::arg("pitch") = 0.0, py::arg("fov") = py::none(),
        "Reads a photo as streetlight-insert --image does, turned upright by its EXIF orientation:\n"
        "intrinsics from a KITTI projection file or JSON {fx, fy, cx, cy}, else from calib's P2, else a\n"
        "centred camera with horizontal field of view `fov` degrees, else the photo's EXIF 35 mm-\n"
        "equivalent focal length (OSError naming the image when none is there); depth from a depth file (EXR metres or KITTI\n"
        "16-bit PNG), else KITTI lidar + calib (projected and densified), else the ground plane seen\n"
        "from camera_height. Raises OSError (FileNotFoundError) for a file it cannot read.");
  m.def("write_image", &write, py::arg("path"), py::arg("image"),
        "Writes H x W x 3 or H x W float values as streetlight-insert writes its pictures: PNG/JPEG\n"
        "stores the values in [0, 1] as 8 bits without a transfer curve; EXR stores the floats.");
}

}  // namespace sl::python
