// The generator's JSON schema (defaults) and its conversion into StreetGeneratorConfig.
#include <cmath>
#include <filesystem>

#include "data/hdri_split.h"
#include "data/object_placement.h"
#include "data/street_generator.h"
#include "render/gltf_loader.h"
#include "util/error.h"

using sl::render::load_gltf;
using sl::render::Mesh;

namespace sl::data {

using json = nlohmann::json;

json street_generator_defaults() {
  // Floats are written as doubles so integer overrides are accepted where a float is expected.
  return json{
      {"seed", 0},
      {"samples", 40},
      {"splits", {{"train", 0.8}, {"val", 0.1}}},
      {"render", {{"spp", 16}, {"max_depth", 3}, {"environment_width", 256}, {"target_noise", 0.0}}},
      {"camera_height_m", 1.6},
      {"panorama", {{"width", 128}, {"height", 64}}},
      {"views",
       {{"count", 2},
        {"width", 128},
        {"height", 64},
        {"fov_deg", 70.0},
        {"yaw_range_deg", 40.0},
        {"pitch_range_deg", 3.0},
        {"forward_range_m", 4.0},
        {"lateral_range_m", 1.0}}},
      {"sky",
       {{"width", 128},
        {"height", 32},
        {"hdri_folder", ""},
        {"hdri_fraction", 1.0},
        {"hdri_split", ""},
        {"hdri_split_name", "train"},
        {"elevation_min_deg", 5.0},
        {"elevation_max_deg", 85.0},
        {"turbidity_min", 2.0},
        {"turbidity_max", 8.0},
        {"cloud_probability", 0.3},
        {"cloud_cover_min", 0.1},
        {"cloud_cover_max", 0.6},
        {"ground_albedo", 0.2}}},
      {"exposure", {{"ldr_median", 0.4}}},
      {"scene",
       {{"road_half_width_m", {4.0, 7.0}},
        {"sidewalk_width_m", {2.0, 4.5}},
        {"curb_height_m", 0.15},
        {"street_length_front_m", 120.0},
        {"street_length_back_m", 40.0},
        {"building_height_m", {5.0, 30.0}},
        {"building_frontage_m", {6.0, 25.0}},
        {"building_depth_m", {8.0, 20.0}},
        {"building_setback_max_m", 3.0},
        {"building_gap_probability", 0.25},
        {"building_gap_max_m", 10.0},
        {"poles", true},
        {"pole_spacing_m", 25.0},
        {"trees", true},
        {"tree_probability", 0.5},
        {"parked_cars_max", 4},
        {"car_models", json::array()},
        {"car_model_length_m", 4.5}}},
      {"insertion",
       {{"enabled", true},
        {"object", ""},
        {"length_m", 4.5},
        {"distance_min_m", 6.0},
        {"distance_max_m", 25.0},
        {"min_visible_pixels", 30},
        {"attempts", 60},
        {"coverage_samples", 4},
        {"spp", 0},
        {"light_probe", false}}},
  };
}

namespace {

double num(const json& t, const char* a, const char* b = nullptr) {
  const json& v = b ? t.at(a).at(b) : t.at(a);
  const std::string key = b ? std::string(a) + "." + b : a;
  SL_CHECK(v.is_number(), "config: '", key, "' must be a number, got ", v.dump());
  const double d = v.get<double>();
  SL_CHECK(std::isfinite(d), "config: '", key, "' must be finite, got ", d);
  return d;
}

int64_t integer(const json& t, const char* a, const char* b, int64_t lo, int64_t hi) {
  const json& v = t.at(a).at(b);
  SL_CHECK(v.is_number_integer(), "config: '", a, ".", b, "' must be an integer, got ", v.dump());
  const int64_t i = v.get<int64_t>();
  SL_CHECK(i >= lo && i <= hi, "config: '", a, ".", b, "' must be in [", lo, ", ", hi, "], got ", i);
  return i;
}

void range(const json& t, const char* key, double& lo, double& hi) {
  const json& v = t.at("scene").at(key);
  SL_CHECK(v.is_array() && v.size() == 2 && v[0].is_number() && v[1].is_number(), "config: 'scene.", key,
           "' must be [min, max], got ", v.dump());
  lo = v[0].get<double>();
  hi = v[1].get<double>();
  SL_CHECK(lo <= hi, "config: 'scene.", key, "' must have min <= max, got ", v.dump());
}

void in_range(double v, double lo, double hi, const char* key) {
  SL_CHECK(v >= lo && v <= hi, "config: '", key, "' must be in [", lo, ", ", hi, "], got ", v);
}

std::shared_ptr<const Mesh> load_object(const std::string& path, const char* key) {
  SL_CHECK(std::filesystem::is_regular_file(path), "config: '", key, "': no such file '", path, "'");
  return std::make_shared<const Mesh>(to_object_frame(load_gltf(path)));
}

}  // namespace

StreetGeneratorConfig street_generator_config(const json& t) {
  StreetGeneratorConfig c;
  c.tree = t;
  SL_CHECK(t.at("seed").is_number_integer() && t.at("seed").get<int64_t>() >= 0,
           "config: 'seed' must be a non-negative integer, got ", t.at("seed").dump());
  c.seed = t.at("seed").get<uint64_t>();
  SL_CHECK(t.at("samples").is_number_integer(), "config: 'samples' must be an integer");
  c.samples = t.at("samples").get<int64_t>();
  SL_CHECK(c.samples >= 1 && c.samples <= 10'000'000, "config: 'samples' must be in [1, 10000000], got ", c.samples);
  c.train_fraction = num(t, "splits", "train");
  c.val_fraction = num(t, "splits", "val");
  SL_CHECK(c.train_fraction >= 0 && c.val_fraction >= 0 && c.train_fraction + c.val_fraction <= 1.0 + 1e-12,
           "config: 'splits.train' and 'splits.val' must be >= 0 with a sum <= 1 (test gets the rest), got ",
           c.train_fraction, " and ", c.val_fraction);

  c.spp = static_cast<int>(integer(t, "render", "spp", 1, 1 << 16));
  c.max_depth = static_cast<int>(integer(t, "render", "max_depth", 1, 64));
  c.environment_width = static_cast<int>(integer(t, "render", "environment_width", 16, 8192));
  // Optional inside "render" (trees written before the key existed mean exactly `spp` samples).
  c.target_noise = t.at("render").contains("target_noise") ? num(t, "render", "target_noise") : 0.0;
  in_range(c.target_noise, 0.0, 0.5, "render.target_noise");
  SL_CHECK(c.target_noise == 0.0 || c.spp >= 2, "config: 'render.target_noise' needs 'render.spp' >= 2 (the cap), got ",
           c.spp);
  c.camera_height_m = num(t, "camera_height_m");
  in_range(c.camera_height_m, 0.3, 20.0, "camera_height_m");
  c.pano_width = static_cast<int>(integer(t, "panorama", "width", 4, 16384));
  c.pano_height = static_cast<int>(integer(t, "panorama", "height", 2, 8192));

  c.view_count = static_cast<int>(integer(t, "views", "count", 1, 64));
  c.view_width = static_cast<int>(integer(t, "views", "width", 4, 8192));
  c.view_height = static_cast<int>(integer(t, "views", "height", 4, 8192));
  c.view_fov_deg = num(t, "views", "fov_deg");
  in_range(c.view_fov_deg, 10.0, 150.0, "views.fov_deg");
  c.view_yaw_range_deg = num(t, "views", "yaw_range_deg");
  in_range(c.view_yaw_range_deg, 0.0, 180.0, "views.yaw_range_deg");
  c.view_pitch_range_deg = num(t, "views", "pitch_range_deg");
  in_range(c.view_pitch_range_deg, 0.0, 45.0, "views.pitch_range_deg");
  c.view_forward_range_m = num(t, "views", "forward_range_m");
  in_range(c.view_forward_range_m, 0.0, 50.0, "views.forward_range_m");
  c.view_lateral_range_m = num(t, "views", "lateral_range_m");
  in_range(c.view_lateral_range_m, 0.0, 3.0, "views.lateral_range_m");

  c.sky_width = static_cast<int>(integer(t, "sky", "width", 4, 8192));
  c.sky_height = static_cast<int>(integer(t, "sky", "height", 2, 4096));
  c.hdri_folder = t.at("sky").at("hdri_folder").get<std::string>();
  c.hdri_fraction = num(t, "sky", "hdri_fraction");
  c.hdri_split = t.at("sky").at("hdri_split").get<std::string>();
  c.hdri_split_name = t.at("sky").at("hdri_split_name").get<std::string>();
  if (!c.hdri_split.empty()) {
    SL_CHECK(!c.hdri_folder.empty(), "config: 'sky.hdri_split' needs 'sky.hdri_folder'");
    (void)read_hdri_split(c.hdri_split).split_paths(c.hdri_folder, c.hdri_split_name);  // fail early, naming the file
  }
  in_range(c.hdri_fraction, 0.0, 1.0, "sky.hdri_fraction");
  c.elevation_min_deg = num(t, "sky", "elevation_min_deg");
  c.elevation_max_deg = num(t, "sky", "elevation_max_deg");
  in_range(c.elevation_min_deg, 0.0, 90.0, "sky.elevation_min_deg");
  in_range(c.elevation_max_deg, c.elevation_min_deg, 90.0, "sky.elevation_max_deg");
  c.turbidity_min = num(t, "sky", "turbidity_min");
  c.turbidity_max = num(t, "sky", "turbidity_max");
  in_range(c.turbidity_min, 1.7, 10.0, "sky.turbidity_min");
  in_range(c.turbidity_max, c.turbidity_min, 10.0, "sky.turbidity_max");
  c.cloud_probability = num(t, "sky", "cloud_probability");
  in_range(c.cloud_probability, 0.0, 1.0, "sky.cloud_probability");
  c.cloud_cover_min = num(t, "sky", "cloud_cover_min");
  c.cloud_cover_max = num(t, "sky", "cloud_cover_max");
  in_range(c.cloud_cover_min, 0.0, 1.0, "sky.cloud_cover_min");
  in_range(c.cloud_cover_max, c.cloud_cover_min, 1.0, "sky.cloud_cover_max");
  c.ground_albedo = num(t, "sky", "ground_albedo");
  in_range(c.ground_albedo, 0.0, 1.0, "sky.ground_albedo");
  c.ldr_median = num(t, "exposure", "ldr_median");
  in_range(c.ldr_median, 0.01, 0.99, "exposure.ldr_median");
  if (!c.hdri_folder.empty())
    SL_CHECK(std::filesystem::is_directory(c.hdri_folder), "config: 'sky.hdri_folder': no such folder '",
             c.hdri_folder, "'");

  StreetSceneConfig& s = c.scene;
  range(t, "road_half_width_m", s.road_half_width_min_m, s.road_half_width_max_m);
  range(t, "sidewalk_width_m", s.sidewalk_width_min_m, s.sidewalk_width_max_m);
  range(t, "building_height_m", s.building_height_min_m, s.building_height_max_m);
  range(t, "building_frontage_m", s.building_frontage_min_m, s.building_frontage_max_m);
  range(t, "building_depth_m", s.building_depth_min_m, s.building_depth_max_m);
  const json& sc = t.at("scene");
  s.curb_height_m = num(sc, "curb_height_m");
  s.street_length_front_m = num(sc, "street_length_front_m");
  s.street_length_back_m = num(sc, "street_length_back_m");
  s.building_setback_max_m = num(sc, "building_setback_max_m");
  s.building_gap_probability = num(sc, "building_gap_probability");
  s.building_gap_max_m = num(sc, "building_gap_max_m");
  s.poles = sc.at("poles").get<bool>();
  s.pole_spacing_m = num(sc, "pole_spacing_m");
  s.trees = sc.at("trees").get<bool>();
  s.tree_probability = num(sc, "tree_probability");
  s.parked_cars_max = static_cast<int>(integer(t, "scene", "parked_cars_max", 0, 64));
  s.car_model_length_m = num(sc, "car_model_length_m");
  const json& models = sc.at("car_models");
  for (size_t i = 0; i < models.size(); ++i) {
    SL_CHECK(models[i].is_string(), "config: 'scene.car_models[", i, "]' must be a file name, got ", models[i].dump());
    s.car_models.push_back(load_object(models[i].get<std::string>(), "scene.car_models"));
  }
  try {
    validate(s);
  } catch (const Error& e) {
    fail("config: 'scene': ", e.what());
  }

  const json& in = t.at("insertion");
  c.insertion = in.at("enabled").get<bool>();
  c.object_file = in.at("object").get<std::string>();
  if (!c.object_file.empty()) c.object_mesh = load_object(c.object_file, "insertion.object");
  c.object_length_m = num(in, "length_m");
  in_range(c.object_length_m, 0.1, 20.0, "insertion.length_m");
  c.object_distance_min_m = num(in, "distance_min_m");
  c.object_distance_max_m = num(in, "distance_max_m");
  in_range(c.object_distance_min_m, 1.0, 200.0, "insertion.distance_min_m");
  in_range(c.object_distance_max_m, c.object_distance_min_m, 200.0, "insertion.distance_max_m");
  c.object_min_visible_pixels = static_cast<int>(integer(t, "insertion", "min_visible_pixels", 1, 1 << 24));
  c.object_attempts = static_cast<int>(integer(t, "insertion", "attempts", 1, 10000));
  c.coverage_samples = static_cast<int>(integer(t, "insertion", "coverage_samples", 1, 16));
  c.insertion_spp = static_cast<int>(integer(t, "insertion", "spp", 0, 1 << 16));
  c.light_probe = in.at("light_probe").get<bool>();
  return c;
}

}  // namespace sl::data
