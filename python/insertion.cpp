// streetlight.insert: streetlight-insert's single-photo path (tools/insert.cpp) from Python. The
// same library calls in the same order — the object (tools/common/insert_options.h), its
// placement in the camera's ground frame (render/object_placement.h), the lighting (with
// --sun-from-shadows, train/inference.h estimate_with_shadow_sun), the insertion
// (train/photo_insertion.h) and the KITTI label (train/object_labels.h) — so its arrays equal the
// tool's files bit for bit for the same settings and seed.
#include <cmath>
#include <filesystem>

#include <pybind11/stl.h>

#include "autodiff/ops.h"
#include "data/image_io.h"
#include "python/bindings.h"
#include "python/lighting.h"
#include "python/numpy_arrays.h"
#include "render/object_placement.h"
#include "tools/common/insert_options.h"
#include "train/losses.h"
#include "train/object_labels.h"
#include "train/photo_input.h"
#include "train/photo_insertion.h"
#include "util/file.h"

namespace sl::python {

namespace {

struct PyInsertion {
  train::PhotoInsertion result;
  PyLighting lighting;
  std::string kitti_label;
  render::Placement placement;
  double at_x = 0.0, at_z = 0.0;  // the placement in the camera's ground frame (streetlight-insert --at)
  std::string object;
};

PyInsertion insert(const py::array& image, const py::handle& intrinsics, const PyLighting& lighting,
                   const std::string& obj, const std::optional<std::pair<double, double>>& at,
                   const std::optional<std::pair<int, int>>& at_pixel, double yaw, double scale,
                   const std::optional<py::array>& depth, std::optional<double> camera_height, std::optional<double> pitch,
                   bool sun_from_shadows, bool fast, uint64_t seed, const std::string& label_class) {
  train::check_kitti_class(label_class, "label_class");
  SL_CHECK(at.has_value() != at_pixel.has_value(), at ? "give at=(X, Z) or at_pixel=(U, V), not both"
                                                      : "at=(X, Z) metres or at_pixel=(U, V) is required");
  double ax = at ? at->first : 0.0, az = at ? at->second : 0.0;
  SL_CHECK(std::isfinite(ax) && std::isfinite(az), "at: expected two finite numbers (X right, Z forward), got (", ax, ", ",
           az, ")");
  SL_CHECK(std::isfinite(yaw), "yaw: expected degrees, got ", yaw);
  SL_CHECK(scale > 0 && std::isfinite(scale), "scale ", scale, " must be positive");
  SL_CHECK(!sun_from_shadows || (!lighting.edit.azimuth_deg && !lighting.edit.elevation_deg),
           "sun_from_shadows sets the sun's direction itself; the lighting's sun direction was edited");
  train::InferenceView view;
  view.ldr = ldr_from_image(image);
  const int h = static_cast<int>(view.ldr.size(1)), w = static_cast<int>(view.ldr.size(2));
  train::PhotoSources s;
  s.camera_height_m = camera_height.value_or(s.camera_height_m);
  s.pitch_deg = pitch.value_or(s.pitch_deg);
  view.camera = train::photo_camera(intrinsics_from(intrinsics, w, h), s);
  view.depth = depth ? depth_from_array(*depth, h, w) : train::ground_plane_depth(view.camera);
  const std::string depth_source = depth ? "depth" : "ground-plane";

  PyInsertion out;
  out.object = obj;
  const render::Mesh object = file_call({obj}, [&] {
    Compute c;
    return cli::load_object(obj);
  });
  if (at_pixel) {
    try {
      const render::PixelPlacement p =
          render::placement_at_pixel(view.camera, view.depth, at_pixel->first, at_pixel->second, yaw, scale);
      out.placement = p.placement;
      ax = p.right_m, az = p.forward_m;
    } catch (const Error& e) {
      fail("at_pixel=(", at_pixel->first, ", ", at_pixel->second, ") (depth: ", depth_source, "): ", e.what());
    }
  } else {
    out.placement = render::placement_in_camera_ground_frame(view.camera, ax, az, yaw, scale);
  }
  out.at_x = ax, out.at_z = az;
  out.lighting = lighting;
  {
    Compute c;
    if (sun_from_shadows) {
      train::ShadowSunLighting shadow = train::estimate_with_shadow_sun(*lighting.estimator, view, lighting.edit);
      out.lighting.view = view;
      out.lighting.lighting = shadow.lighting;
      out.lighting.shadow_fit = shadow.fit;
      out.lighting.shadow_intensity_scale = shadow.intensity_scale;
    }
    train::PhotoInsertionOptions options = fast ? train::fast_insertion_options() : train::PhotoInsertionOptions{};
    options.seed = seed;
    options.volume_query = lighting.estimator->volume_query();
    try {
      out.result = train::insert_into_photo(out.lighting.lighting, view.ldr, view.depth, view.camera, object,
                                            out.placement, options);
    } catch (const Error& e) {
      fail("at=(", ax, ", ", az, ") (depth: ", depth_source, "): ", e.what());
    }
  }
  check_signals();
  SL_CHECK(out.result.visible, "the object at at=(", ax, ", ", az, ") covers no pixel of the image");
  out.kitti_label = train::kitti_label_line(label_class, 0.0, 0, out.result.box2d, out.result.box3d);
  return out;
}

// streetlight-insert's pictures of one insertion, under the same names.
void save(const PyInsertion& r, const std::string& dir) {
  namespace fs = std::filesystem;
  // The folder is replaced as a whole: never one that holds anything but a previous insertion.
  SL_CHECK(!fs::exists(dir) || (fs::is_directory(dir) && (fs::is_empty(dir) || fs::exists(fs::path(dir) / "composite.png"))),
           "save: '", dir, "' exists and is not a previous insertion's folder; choose another folder");
  file_call({}, [&] {
    Compute c;
    data::ImageWriteOptions lin;
    lin.transfer = data::Transfer::Linear;
    AtomicDirectory out(dir);
    data::write_image(out.file("composite.png"), r.result.composite_ldr, lin);
    data::write_image(out.file("object_mask.png"), r.result.object_mask, lin);
    data::write_image(out.file("shadow_map.png"), clamp(r.result.shadow_map, 0.0, 1.0), lin);
    const Tensor sky = r.lighting.lighting.env_world().contiguous();
    data::write_image(out.file("sky.exr"), sky);
    data::write_image(out.file("sky.png"), train::ldr_from_hdr(sky), lin);
    write_file_atomic(out.file("label.txt"), r.kitti_label + "\n");
    out.commit();
  });
}

}  // namespace

void bind_insertion(py::module_& m) {
  py::class_<PyInsertion>(m, "Insertion", "One object inserted into one photo (train/photo_insertion.h).")
      .def_property_readonly("composite", [](const PyInsertion& r) { return image_from_tensor(r.result.composite_ldr); },
                             "H x W x 3 float32 LDR in [0, 1] (composite.png)")
      .def_property_readonly("composite_linear",
                             [](const PyInsertion& r) { return image_from_tensor(r.result.composite_linear); },
                             "H x W x 3 float32 exposure-normalised radiance (composite.exr)")
      .def_property_readonly("mask", [](const PyInsertion& r) { return image_from_tensor(r.result.object_mask); },
                             "H x W float32 object coverage in [0, 1] (object_mask.png)")
      .def_property_readonly("shadow", [](const PyInsertion& r) { return image_from_tensor(r.result.shadow_map); },
                             "H x W float32 shadow ratio S of Eq. 3-4 (1 = unshadowed; shadow_map.png clamps it)")
      .def_readonly("kitti_label", &PyInsertion::kitti_label, "the KITTI label line of label.txt")
      .def_readonly("lighting", &PyInsertion::lighting, "the lighting the object was rendered under")
      .def_readonly("object", &PyInsertion::object)
      .def_property_readonly("box2d", [](const PyInsertion& r) { return r.result.box2d; }, "(left, top, right, bottom) px")
      .def_property_readonly("box3d", [](const PyInsertion& r) { return r.result.box3d; },
                             "(h, w, l, x, y, z, rotation_y), KITTI camera frame")
      .def_property_readonly("hidden_fraction", [](const PyInsertion& r) { return r.result.hidden_fraction; })
      .def_property_readonly("truncated", [](const PyInsertion& r) { return r.result.truncated; })
      .def_property_readonly("placement", [](const PyInsertion& r) {
            py::dict d;
            d["at"] = py::make_tuple(r.at_x, r.at_z);
            d["world_x_m"] = r.placement.x_m;
            d["world_z_m"] = r.placement.z_m;
            d["ground_y_m"] = r.result.ground_y_m;
            d["yaw_deg"] = r.placement.yaw_deg;
            d["scale"] = r.placement.scale;
            return d;
          })
      .def_property_readonly("render_ms", [](const PyInsertion& r) { return r.result.render_ms; })
      .def("save", &save, py::arg("folder"),
           "Writes composite.png, object_mask.png, shadow_map.png, sky.exr, sky.png and label.txt as\n"
           "streetlight-insert does (atomically: the folder appears complete or not at all).");
  m.def("insert", &insert, py::arg("image"), py::arg("intrinsics"), py::arg("lighting"), py::arg("obj"), py::kw_only(),
        py::arg("at") = py::none(), py::arg("at_pixel") = py::none(), py::arg("yaw") = 90.0, py::arg("scale") = 1.0, py::arg("depth") = py::none(),
        py::arg("camera_height") = py::none(), py::arg("pitch") = py::none(), py::arg("sun_from_shadows") = false,
        py::arg("fast") = false, py::arg("seed") = 0, py::arg("label_class") = "Car",
        "Inserts an object into the photo under `lighting` (Sec 3.3, Eq. 2-4), as streetlight-insert.\n"
        "  obj: a glTF/GLB path or 'procedural:car'\n"
        "  at: (X, Z) metres on the ground, right of and ahead of the camera; or\n"
        "  at_pixel: (U, V) the pixel column and row whose ground (in depth) the object stands on\n"
        "  yaw: heading in degrees about +Y; 90 (streetlight-insert's default) points the length away\n"
        "  depth, camera_height, pitch: as Estimator.estimate (None depth: the ground plane)\n"
        "  sun_from_shadows: take the sun from the photo's own cast shadows (needs real depth)\n"
        "  fast: streetlight-insert --fast; seed: the sampling seed\n"
        "  label_class: the KITTI class of kitti_label (streetlight-insert --class): Car, Van, Truck,\n"
        "    Pedestrian, Person_sitting, Cyclist, Tram or Misc\n"
        "Returns an Insertion. Releases the GIL. Raises ValueError for a bad argument or placement,\n"
        "OSError (FileNotFoundError) for an object file it cannot read.");
}

}  // namespace sl::python
