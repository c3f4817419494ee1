// A user's photo, intrinsics and depth for insertion. See photo_input.h.
#include "train/photo_input.h"

#include <cmath>
#include <fstream>

#include <nlohmann/json.hpp>

#include "autodiff/ops.h"
#include "data/image_io.h"
#include "data/kitti.h"
#include "train/photo_insertion.h"
#include "util/file_kind.h"
#include "util/math.h"

using sl::data::densify_depth;
using sl::data::ImageReadOptions;
using sl::data::KittiLidar;
using sl::data::load_kitti_lidar;
using sl::data::MissingDepth;
using sl::data::read_depth;
using sl::data::read_image;
using sl::data::read_kitti_calibration;
using sl::data::Transfer;
using sl::render::Camera;
using sl::render::Intrinsics;
using sl::render::kitti_projection_from_file;
using sl::render::Placement;
using sl::render::rotation_from_yaw_pitch_roll;

namespace sl::train {

Intrinsics read_intrinsics(const std::string& path, int width, int height) {
  Intrinsics k;
  if (has_extension(path, {".json"})) {
    std::ifstream f(path);
    SL_CHECK(f.good(), "intrinsics file '", path, "' cannot be opened");
    nlohmann::json j;
    try {
      j = nlohmann::json::parse(f);
      k.fx = j.at("fx").get<double>();
      k.fy = j.at("fy").get<double>();
      k.cx = j.at("cx").get<double>();
      k.cy = j.at("cy").get<double>();
    } catch (const nlohmann::json::exception& e) {
      SL_CHECK(false, "intrinsics file '", path, "': expected a JSON object {fx, fy, cx, cy} (", e.what(), ")");
    }
    if (j.contains("width") || j.contains("height")) {
      for (const char* key : {"width", "height"})
        SL_CHECK(!j.contains(key) || (j[key].is_number_integer() && j[key].get<int64_t>() >= 0 &&
                                      j[key].get<int64_t>() <= 1 << 20),
                 "intrinsics file '", path, "': ", key, " must be a pixel count, got ", j[key].type_name());
      const int w = j.value("width", width), h = j.value("height", height);
      SL_CHECK(w == width && h == height, "intrinsics file '", path, "' is for a ", w, "x", h, " image, but the image is ",
               width, "x", height);
    }
    k.width = width;
    k.height = height;
    validate(k, path.c_str());
  } else {
    k = kitti_projection_from_file(path, width, height).intrinsics;
  }
  check_principal_point(k, "intrinsics file '" + path + "'");
  return k;
}

void check_principal_point(const Intrinsics& k, const std::string& where) {
  SL_CHECK(k.cx > 0 && k.cx < k.width && k.cy > 0 && k.cy < k.height, where, ": principal point (", k.cx, ", ", k.cy,
           ") lies outside the ", k.width, "x", k.height, " image; the intrinsics belong to another image");
}

Camera photo_camera(const Intrinsics& k, const PhotoSources& s) {
  SL_CHECK(s.camera_height_m > 0 && std::isfinite(s.camera_height_m), "--camera-height ", s.camera_height_m,
           " must be positive");
  const glm::dvec3 pos = s.position.value_or(glm::dvec3(0.0, s.camera_height_m, 0.0));
  return Camera(k, rotation_from_yaw_pitch_roll(s.yaw_deg * kPi / 180.0, s.pitch_deg * kPi / 180.0, 0.0), pos);
}

Intrinsics photo_intrinsics(const PhotoSources& s, int w, int h, std::string* source) {
  std::string from;
  Intrinsics k;
  if (!s.intrinsics.empty()) {
    k = read_intrinsics(s.intrinsics, w, h), from = "file";
  } else if (!s.calib.empty()) {
    k = read_kitti_calibration(s.calib, w, h).p2.intrinsics, from = "calib";
  } else if (s.fov_deg != 0.0) {
    SL_CHECK(std::isfinite(s.fov_deg) && s.fov_deg > 0.0 && s.fov_deg < 180.0,
             "--fov DEG must lie between 0 and 180 degrees, got ", s.fov_deg);
    k = render::intrinsics_from_fov(s.fov_deg * kPi / 180.0, w, h), from = "fov";
  } else {
    const double f35 = data::read_image_info(s.image).focal_35mm;
    SL_CHECK(f35 > 0.0, "image '", s.image, "' has no intrinsics: give --intrinsics FILE (KITTI P2 or JSON {fx, fy, "
             "cx, cy}) or --fov DEG (its horizontal field of view); its EXIF has no 35 mm-equivalent focal length");
    constexpr double kFullFrameDiagonalMm = 43.266615305567875;  // √(36² + 24²)
    const double f = f35 * std::sqrt(double(w) * w + double(h) * h) / kFullFrameDiagonalMm;
    k.fx = k.fy = f;
    k.cx = 0.5 * w, k.cy = 0.5 * h;
    k.width = w, k.height = h;
    render::validate(k, "EXIF focal length");
    from = "exif";
  }
  if (source) *source = from;
  return k;
}

Photo load_photo(const PhotoSources& s) {
  SL_CHECK(!s.image.empty(), "--image is required");
  Photo p;
  ImageReadOptions ro;
  ro.transfer = Transfer::Linear;
  ro.channels = 3;
  ro.upright = true;
  p.ldr = read_image(s.image, ro);
  const int h = static_cast<int>(p.ldr.size(1)), w = static_cast<int>(p.ldr.size(2));
  const Intrinsics k = photo_intrinsics(s, w, h, &p.intrinsics_source);
  p.camera = photo_camera(k, s);
  if (!s.depth.empty()) {
    const Tensor d = read_depth(s.depth);
    SL_CHECK(d.size(1) == h && d.size(2) == w, "depth file '", s.depth, "' is ", d.size(2), "x", d.size(1),
             " but the image '", s.image, "' is ", w, "x", h);
    p.depth = reshape(d, {h, w}).contiguous();
    p.depth_source = "depth-file";
  } else if (!s.lidar.empty()) {
    SL_CHECK(!s.calib.empty(), "--lidar needs --calib FILE (the lidar-to-camera calibration)");
    const KittiLidar f = load_kitti_lidar(s.calib, s.lidar, w, h);  // the photo as read, not read again
    SL_CHECK(f.sparse_depth.defined(), "lidar file '", s.lidar, "' gave no depth");
    p.depth = densify_depth(f.sparse_depth, k, f.camera_points).contiguous();
    p.depth_source = "lidar";
  } else {
    p.depth = ground_plane_depth(p.camera);
    p.depth_source = "ground-plane";
  }
  return p;
}

Photo load_street_view(const std::string& dir, int view, Placement* placement, bool* has_placement) {
  const std::string meta_path = dir + "/meta.json";
  std::ifstream f(meta_path);
  SL_CHECK(f.good(), "street sample '", dir, "' has no meta.json");
  Photo p;
  try {
    const nlohmann::json m = nlohmann::json::parse(f);
    const auto& views = m.at("views");
    SL_CHECK(view >= 0 && view < static_cast<int>(views.size()), "street sample '", dir, "' has no view ", view);
    const auto& v = views.at(view);
    const auto& k = v.at("intrinsics");
    Intrinsics in;
    in.fx = k.at("fx").get<double>(), in.fy = k.at("fy").get<double>();
    in.cx = k.at("cx").get<double>(), in.cy = k.at("cy").get<double>();
    in.width = k.at("width").get<int>(), in.height = k.at("height").get<int>();
    const auto& r = v.at("rotation_cam_to_world");
    glm::dmat3 rot;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) rot[j][i] = r.at(i * 3 + j).get<double>();  // row-major → glm columns
    const auto& pos = v.at("position");
    p.camera = Camera(in, rot, {pos.at(0).get<double>(), pos.at(1).get<double>(), pos.at(2).get<double>()});
    ImageReadOptions ro;
    ro.transfer = Transfer::Linear;
    ro.channels = 3;
    ro.width = in.width;
    ro.height = in.height;
    p.ldr = read_image(dir + "/" + v.at("files").at("ldr").get<std::string>(), ro);
    const Tensor d = read_depth(dir + "/" + v.at("files").at("depth").get<std::string>(), MissingDepth::Zero, in.width,
                                in.height);
    p.depth = reshape(d, {in.height, in.width}).contiguous();
    p.depth_source = "dataset";
    p.intrinsics_source = "dataset";
    if (has_placement) *has_placement = false;
    if (placement && m.contains("object") && !m.at("object").is_null()) {
      const auto& pl = m.at("object").at("placement");
      *placement = {pl.at("x_m").get<double>(), pl.at("z_m").get<double>(), pl.at("yaw_deg").get<double>(),
                    pl.at("scale").get<double>()};
      if (has_placement) *has_placement = true;
    }
  } catch (const nlohmann::json::exception& e) {
    SL_CHECK(false, "street sample '", meta_path, "': ", e.what());
  }
  return p;
}

std::string street_sample_object(const std::string& dir) {
  const std::string meta_path = dir + "/meta.json";
  std::ifstream f(meta_path);
  SL_CHECK(f.good(), "street sample '", dir, "' has no meta.json");
  try {
    const nlohmann::json m = nlohmann::json::parse(f);
    SL_CHECK(m.contains("object") && !m.at("object").is_null(), "street sample '", dir,
             "' has no inserted object (generated without insertion); give --object");
    return dir + "/" + m.at("object").at("file").get<std::string>();
  } catch (const nlohmann::json::exception& e) {
    fail("street sample '", meta_path, "': ", e.what());
  }
}

}  // namespace sl::train
