// streetlight.Estimator and streetlight.Lighting: train/inference.h's LightingEstimator (the
// released model by default, as the tools' cli::released_model_path()) and its estimate.
#include "python/lighting.h"

#include <cmath>

#include <pybind11/stl.h>

#include "data/image_io.h"
#include "python/bindings.h"
#include "python/numpy_arrays.h"
#include "tools/common/cli.h"
#include "train/losses.h"
#include "train/photo_input.h"
#include "train/photo_insertion.h"

namespace sl::python {

namespace {

using train::azimuth_deg_of;
using train::elevation_deg_of;

struct PyEstimator {
  std::shared_ptr<train::LightingEstimator> est;
};

PyEstimator make_estimator(const std::optional<std::string>& checkpoint, bool flip_average, bool visible_sun,
                           const std::vector<double>& crop_scales) {
  std::string path;
  PyEstimator e;
  file_call({checkpoint.value_or("")}, [&] {
    path = checkpoint ? *checkpoint : cli::released_model_path();
    Compute c;
    e.est = std::make_shared<train::LightingEstimator>(path);
    // The released learned glare detector behind the disk test, as the tools do by default.
    if (const std::string glare = cli::released_sun_glare_path(); visible_sun && !glare.empty())
      e.est->set_sun_glare(train::load_sun_glare(glare));
  });
  e.est->set_flip_average(flip_average);
  e.est->set_visible_sun(visible_sun);
  e.est->set_crop_scales(crop_scales);
  return e;
}

// The photo as the estimator and the insertion take it: load_photo()'s camera and depth rules.
train::InferenceView view_of(const py::array& image, const py::handle& intrinsics, const std::optional<py::array>& depth,
                             std::optional<double> camera_height, std::optional<double> pitch) {
  train::InferenceView v;
  v.ldr = ldr_from_image(image);
  const int h = static_cast<int>(v.ldr.size(1)), w = static_cast<int>(v.ldr.size(2));
  train::PhotoSources s;
  s.camera_height_m = camera_height.value_or(s.camera_height_m);
  s.pitch_deg = pitch.value_or(s.pitch_deg);
  v.camera = train::photo_camera(intrinsics_from(intrinsics, w, h), s);
  v.depth = depth ? depth_from_array(*depth, h, w) : train::ground_plane_depth(v.camera);
  return v;
}

train::SunEdit sun_edit(std::optional<double> azimuth, std::optional<double> elevation, double intensity) {
  train::SunEdit e;
  e.azimuth_deg = azimuth;
  e.elevation_deg = elevation;
  e.intensity_scale = intensity;
  SL_CHECK(std::isfinite(intensity) && intensity > 0, "sun_intensity: expected a positive scale, got ", intensity);
  return e;
}

PyLighting estimate(const PyEstimator& e, const py::array& image, const py::handle& intrinsics,
                    const std::optional<py::array>& depth, std::optional<double> camera_height, std::optional<double> pitch,
                    std::optional<double> sun_azimuth, std::optional<double> sun_elevation, double sun_intensity) {
  PyLighting l;
  l.estimator = e.est;
  l.view = view_of(image, intrinsics, depth, camera_height, pitch);
  l.edit = sun_edit(sun_azimuth, sun_elevation, sun_intensity);
  {
    Compute c;
    l.lighting = e.est->estimate({l.view}, l.edit);
  }
  check_signals();
  return l;
}

PyLighting with_sun(const PyLighting& in, std::optional<double> azimuth, std::optional<double> elevation,
                    std::optional<double> intensity_scale) {
  SL_CHECK(in.lighting.has_sky_code, "with_sun: the checkpoint '", in.estimator->path(),
           "' has no sky vector to edit (its sky branch is '", in.estimator->predictor().options().sky_branch, "')");
  PyLighting out = in;
  if (azimuth) out.edit.azimuth_deg = azimuth;
  if (elevation) out.edit.elevation_deg = elevation;
  if (intensity_scale) out.edit = sun_edit(out.edit.azimuth_deg, out.edit.elevation_deg, *intensity_scale);
  out.shadow_fit.reset();
  out.shadow_intensity_scale = 1.0;
  {
    Compute c;
    out.lighting = in.estimator->estimate({out.view}, out.edit);
  }
  check_signals();
  return out;
}

py::object nan_to_none(double v) { return std::isfinite(v) ? py::cast(v) : py::none(); }

py::tuple vec3(const glm::dvec3& v) { return py::make_tuple(v.x, v.y, v.z); }

py::dict confidence(const PyLighting& l) {
  const train::EstimatedLighting& e = l.lighting;
  py::dict d;
  d["flip_spread_deg"] = nan_to_none(e.sun_flip_spread_deg);
  d["hedge"] = nan_to_none(e.sun_hedge);
  d["crop_spread_deg"] = nan_to_none(e.sun_crop_spread_deg);
  d["probability"] = nan_to_none(e.sun_probability);
  d["visible_sun"] = e.visible_sun_found;
  d["visible_sun_learned"] = e.visible_sun_learned;
  d["glare_azimuth_used"] = e.glare_azimuth_used;
  if (e.visible_sun_found) d["visible_sun_pixel"] = py::make_tuple(e.visible_sun_pixel.x, e.visible_sun_pixel.y);
  return d;
}

Tensor sky_world(const PyLighting& l) { return l.lighting.env_world().contiguous(); }

}  // namespace

void bind_lighting(py::module_& m) {
  py::class_<PyEstimator>(m, "Estimator",
                          "A trained lighting model (train/inference.h): photo -> HDR sky dome + volume (Sec 3.2).")
      .def(py::init(&make_estimator), py::arg("checkpoint") = py::none(), py::kw_only(), py::arg("flip_average") = true,
           py::arg("visible_sun") = true, py::arg("crop_scales") = std::vector<double>{},
           "Loads a stage-2 or stage-3 checkpoint; None loads the released model (the tools' default:\n"
           "$STREETLIGHT_MODEL, else models/streetlight.safetensors, else the copy installed beside this\n"
           "module, else the source tree's). flip_average, visible_sun and\n"
           "crop_scales are streetlight-insert's --no-flip-average, --no-visible-sun and --crop-scales;\n"
           "with visible_sun, the released sun-glare detector (models/sun_glare.safetensors, when\n"
           "present) backs the disk test, as in the tools.\n"
           "Raises OSError (FileNotFoundError) when the checkpoint cannot be read.")
      .def_property_readonly("checkpoint", [](const PyEstimator& e) { return e.est->path(); })
      .def_property_readonly("stage", [](const PyEstimator& e) { return e.est->stage(); })
      .def_property_readonly("step", [](const PyEstimator& e) { return e.est->step(); })
      .def("estimate", &estimate, py::arg("image"), py::arg("intrinsics"), py::kw_only(), py::arg("depth") = py::none(),
           py::arg("camera_height") = py::none(), py::arg("pitch") = py::none(), py::arg("sun_azimuth") = py::none(),
           py::arg("sun_elevation") = py::none(), py::arg("sun_intensity") = 1.0,
           "Estimates the photo's lighting.\n"
           "  image: H x W x 3, uint8 sRGB or float32 linear radiance\n"
           "  intrinsics: (fx, fy, cx, cy) or a 3 x 3 matrix, in pixels\n"
           "  depth: H x W camera-z metres (None: the ground plane seen from camera_height)\n"
           "  camera_height: metres (default 1.65); pitch: degrees, positive up (default 0)\n"
           "  sun_azimuth, sun_elevation (degrees, world), sun_intensity (a factor): edit the sun (Sec 3.2)\n"
           "Releases the GIL. Raises ValueError for a bad argument.");
  py::class_<PyLighting>(m, "Lighting",
                         "An estimated lighting: the sun, the model's confidence, and the HDR sky dome. The world\n"
                         "frame is the photo camera's level frame: +Y up, the camera looking at azimuth 0.")
      .def_property_readonly("sun_direction", [](const PyLighting& l) {
            return vec3(glm::transpose(l.view.camera.rotation()) * l.lighting.sun_direction_world());
          }, "unit direction towards the sun in the camera frame (x right, y down, z forward)")
      .def_property_readonly("sun_direction_world", [](const PyLighting& l) { return vec3(l.lighting.sun_direction_world()); })
      .def_property_readonly("sun_azimuth", [](const PyLighting& l) { return azimuth_deg_of(l.lighting.sun_direction_world()); },
                             "degrees (render/equirect.h)")
      .def_property_readonly("sun_elevation",
                             [](const PyLighting& l) { return elevation_deg_of(l.lighting.sun_direction_world()); },
                             "degrees above the horizon")
      .def_property_readonly("sun_strength", [](const PyLighting& l) { return vec3(l.lighting.sun_intensity_rgb); },
                             "the sun's RGB intensity f_intensity (0 without a sky vector)")
      .def_property_readonly("confidence", &confidence,
                             "the tools' confidences: flip_spread_deg, hedge, crop_spread_deg (smaller is more\n"
                             "confident; None when not measured), probability (models with a sun head: the\n"
                             "probability within 20 degrees of the sun, larger is more confident), visible_sun\n"
                             "(a sun seen in the photo set it), visible_sun_learned (the learned glare\n"
                             "detector saw it, not the disk test) and glare_azimuth_used (the detector's azimuth\n"
                             "head reweighed the sun head's distribution)")
      .def_property_readonly("has_sky_vector", [](const PyLighting& l) { return l.lighting.has_sky_code; })
      .def_property_readonly("sun_from_shadows", [](const PyLighting& l) -> py::object {
            if (!l.shadow_fit) return py::none();
            py::dict d;
            d["found"] = l.shadow_fit->found;
            d["azimuth_deg"] = l.shadow_fit->azimuth_deg;
            d["elevation_deg"] = l.shadow_fit->elevation_deg;
            d["shadow_ratio"] = l.shadow_fit->shadow_ratio;
            d["intensity_scale"] = l.shadow_intensity_scale;
            return d;
          }, "the fit of insert(..., sun_from_shadows=True), None otherwise")
      .def_property_readonly("inference_ms", [](const PyLighting& l) { return l.lighting.inference_ms; })
      .def("sky", [](const PyLighting& l) { return image_from_tensor(sky_world(l)); },
           "The HDR sky dome, H x W x 3 float32 equirectangular (row 0 the zenith), world azimuths.")
      .def("save_exr", [](const PyLighting& l, const std::string& path) {
            const Tensor sky = sky_world(l);
            file_call({}, [&] {
              Compute c;
              data::write_image(path, sky);
            });
          }, py::arg("path"), "Writes the sky dome as streetlight-insert's sky.exr.")
      .def("save_png", [](const PyLighting& l, const std::string& path) {
            const Tensor sky = sky_world(l);
            data::ImageWriteOptions lin;
            lin.transfer = data::Transfer::Linear;
            file_call({}, [&] {
              Compute c;
              data::write_image(path, train::ldr_from_hdr(sky), lin);
            });
          }, py::arg("path"), "Writes the sky dome tone-mapped, as streetlight-insert's sky.png.")
      .def("with_sun", &with_sun, py::kw_only(), py::arg("azimuth") = py::none(), py::arg("elevation") = py::none(),
           py::arg("intensity_scale") = py::none(),
           "The same photo's lighting with the sun edited through the sky vector (Sec 3.2): a new\n"
           "direction (world degrees) and/or intensity factor; unset fields keep this lighting's edit.");
}

}  // namespace sl::python
