// The synthetic street-scene dataset generator (format in docs/DATASET.md).
//
// One sample = one procedural street (data/street_scene.h) lit by the Preetham sky
// (data/sky_model.h) or by a real HDRI rotated by a random azimuth, rendered with the reference
// path tracer (render/path_tracer.h):
//   - an HDR + LDR panorama at the street camera, its sky mask (pixel-centre rays that escape
//     the scene) and the true sun direction;
//   - perspective views: intrinsics, pose, HDR, LDR, metric depth (camera z), sky mask;
//   - the true HDR sky alone (area-resized from the map the scene was lit with);
//   - insertion ground truth: an object (procedural car or a glTF) on the road in view 0,
//     rendered inside the scene with the SAME per-pixel random streams as view 0 without it,
//     with its placement, KITTI-style 2D and 3D boxes and coverage mask.
// LDR is the paper's clip((exposure·L)^(1/2.2), 0, 1) (Sec 3.4) with one exposure per sample,
// chosen so view 0's median luminance maps to `ldr_median`.
// Noise: with render.target_noise > 0 every image is rendered to that LDR noise level (adaptive
// samples per image, capped by render.spp); meta.json records the samples and the estimated
// noise of each image.
//
// Determinism: every random choice and every path-tracer seed is a pure function of
// (config, dataset seed, sample index), so the same seed writes the same files with any
// number of threads. Samples are independent: any subset can be (re)generated alone.
// Atomicity: a sample is written into a temporary sibling folder (util/file.h AtomicDirectory)
// and renamed to `<id>/` only when complete;
// index.json is written to a temporary file and renamed.
// Throws: sl::Error naming the config key and value (bad config), or the file (I/O); the
// OpenMP loops never throw.
#pragma once
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "data/street_scene.h"
#include "render/mesh.h"

namespace sl::data {

struct StreetGeneratorConfig {
  nlohmann::json tree;  // the validated JSON it came from (stored in index.json)
  uint64_t seed = 0;
  int64_t samples = 40;
  double train_fraction = 0.8, val_fraction = 0.1;  // test gets the rest
  // Path tracing.
  int spp = 16, max_depth = 3;
  // > 0: render every image progressively (render/progressive_render.h, two seeds) until its
  // estimated LDR noise — the standard deviation of a 0-1 LDR pixel value at the sample's
  // exposure rule — is at most this, with `spp` as the cap. 0: exactly `spp` samples.
  double target_noise = 0.0;
  int environment_width = 256;  // the lighting map (height = width / 2)
  // Street camera and panorama.
  double camera_height_m = 1.6;
  int pano_width = 128, pano_height = 64;
  // Perspective views.
  int view_count = 2, view_width = 128, view_height = 64;
  double view_fov_deg = 70.0, view_yaw_range_deg = 40.0, view_pitch_range_deg = 3.0;
  double view_forward_range_m = 4.0, view_lateral_range_m = 1.0;
  // Sky.
  int sky_width = 128, sky_height = 32;
  std::string hdri_folder;  // non-empty: light with real HDRIs instead of the sky model
  std::string hdri_split;   // optional split file (data/hdri_split.h): only its `hdri_split_name` list is used
  std::string hdri_split_name = "train";
  double hdri_fraction = 1.0;  // with hdri_folder: share of samples lit by an HDRI (the rest: sky model)
  double elevation_min_deg = 5.0, elevation_max_deg = 85.0;
  double turbidity_min = 2.0, turbidity_max = 8.0;
  double cloud_probability = 0.3, cloud_cover_min = 0.1, cloud_cover_max = 0.6;
  double ground_albedo = 0.2;
  double ldr_median = 0.4;
  // Scene.
  StreetSceneConfig scene;
  // Insertion.
  bool insertion = true;
  std::string object_file;  // .glb/.gltf; empty = the procedural car
  std::shared_ptr<const render::Mesh> object_mesh;  // loaded object, object frame (null = procedural)
  double object_length_m = 4.5;
  double object_distance_min_m = 6.0, object_distance_max_m = 25.0;
  int object_min_visible_pixels = 30;
  int object_attempts = 60;
  int coverage_samples = 4;  // per axis: coverage mask uses n×n rays per pixel
  // > 0: the insertion pair (view 0 with and without the object, same per-pixel streams) is
  // rendered at this many samples per pixel instead of view 0's, so that metrics against it are
  // not limited by the truth's own noise (16 spp caps insertion PSNR near 27 dB). 0: view 0's.
  int insertion_spp = 0;
  // Also render the light at the object: an HDR panorama (pano size, render.spp) from the centre
  // of the object's bounding box, in the scene WITHOUT the object — the ground-truth lighting an
  // "oracle" insertion needs (the panorama at the camera misses what the object itself sees).
  bool light_probe = false;
};

// Every valid key with its default (the config schema, for tools/common/config.h).
nlohmann::json street_generator_defaults();
// Reads a tree already checked against the defaults; checks ranges (errors name the key) and
// loads the glTF files it names (errors name the file).
StreetGeneratorConfig street_generator_config(const nlohmann::json& tree);

std::string sample_id(int64_t index);  // "000042"

struct GeneratedSample {
  std::string id;
  bool has_insertion = false;
  double exposure = 1.0;
  double seconds = 0.0;
};

// Renders sample `index` into `<samples_dir>/<id>/` (replacing an existing folder).
GeneratedSample generate_street_sample(const StreetGeneratorConfig& config, int64_t index,
                                       const std::string& samples_dir);

// train/val/test assignment of `ids`, a seeded shuffle cut by the config's fractions.
struct DatasetSplits {
  std::vector<std::string> train, val, test;
};
DatasetSplits split_ids(const std::vector<std::string>& ids, uint64_t seed, double train_fraction,
                        double val_fraction);

// Writes `<out_dir>/index.json` atomically.
void write_dataset_index(const std::string& out_dir, const StreetGeneratorConfig& config,
                         const DatasetSplits& splits);

// Writes text to `path` through a temporary file and a rename.
void write_text_atomic(const std::string& path, const std::string& text);

}  // namespace sl::data
