// Reading a user's photo for insertion: the image, its intrinsics and a depth map from one of
// three sources, with every mismatch reported as one sl::Error naming the file.
//
// Contract:
// - read_intrinsics(path, width, height): a KITTI 3×4 projection text file (`P2:` line or 12
//   bare numbers) or a JSON object {fx, fy, cx, cy[, width, height]} (.json). Throws when the
//   file's width/height differ from the image or the principal point lies outside the image
//   (intrinsics that belong to another image).
// - photo_intrinsics(sources, width, height, &source): the photo's intrinsics, from the first of
//   `intrinsics` (read_intrinsics), `calib` (its P2), `fov_deg` (a centred camera with that
//   horizontal field of view, square pixels; must lie in (0, 180)), and the image's EXIF
//   35 mm-equivalent focal length f35 (fx = fy = f35 · √(W² + H²) / 43.27 mm, the 35 mm frame's
//   diagonal; centred). `source` says which: "file", "calib", "fov" or "exif". Throws naming the
//   image when none is there.
// - load_photo(): image as stored 8-bit values in [0, 1] (treated as the paper's LDR), turned
//   upright by its EXIF Orientation tag (data/image_io.h: a phone's portrait photo), camera at
//   (0, camera_height, 0) with yaw = 0 and the given pitch (world +Y up, looking down −Z)
//   unless a pose is given; depth from, in order of preference, `depth_path` (metric EXR or
//   KITTI 16-bit PNG; must have the image's size), `lidar_path` + `calib_path` (data/kitti.h:
//   projected velodyne points densified by nearest fill and a fitted ground plane), or the
//   ground plane y = 0 seen from the camera. depth_source says which ("depth-file", "lidar",
//   "ground-plane").
#pragma once
#include <optional>
#include <string>

#include "autodiff/tensor.h"
#include "render/camera.h"
#include "render/object_placement.h"

namespace sl::train {

render::Intrinsics read_intrinsics(const std::string& path, int width, int height);
// Throws naming `where` unless the principal point lies inside the k.width x k.height image
// (intrinsics that belong to another image).
void check_principal_point(const render::Intrinsics& k, const std::string& where);

struct PhotoSources {
  std::string image, intrinsics, depth, lidar, calib;
  double fov_deg = 0.0;  // horizontal field of view when there is no intrinsics file (0: not given)
  double camera_height_m = 1.65, pitch_deg = 0.0;
  // Optional world pose: position and yaw/pitch in degrees (multi-view rigs).
  std::optional<glm::dvec3> position;
  double yaw_deg = 0.0;
};

struct Photo {
  Tensor ldr;    // [3, H, W]
  Tensor depth;  // [H, W]
  render::Camera camera;
  std::string depth_source;
  std::string intrinsics_source;  // photo_intrinsics' source; "dataset" for a street sample
};

render::Intrinsics photo_intrinsics(const PhotoSources& sources, int width, int height, std::string* source);
Photo load_photo(const PhotoSources& sources);
// load_photo()'s camera for intrinsics k: at sources.position, else (0, camera_height_m, 0), with
// sources' yaw and pitch. Throws unless camera_height_m is finite and positive.
render::Camera photo_camera(const render::Intrinsics& k, const PhotoSources& sources);

// View `view` of a generated street sample folder (docs/DATASET.md: DIR/samples/<id>): its LDR,
// depth and full camera pose from meta.json (depth_source "dataset"). When the sample has an
// inserted object, *placement receives its world placement (x, z, yaw, scale) and true is returned.
Photo load_street_view(const std::string& sample_dir, int view, render::Placement* placement, bool* has_placement);
// The object the generator inserted into a street sample (meta.json object.file, in the object
// frame), so an insertion into the sample compares like with like against its path-traced truth.
// Throws naming the sample when it has no inserted object.
std::string street_sample_object(const std::string& sample_dir);

}  // namespace sl::train
