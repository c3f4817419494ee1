// Procedural street scenes for the synthetic dataset : a straight street along the
// view with asphalt, curbs, sidewalks, buildings on both sides, and optional poles, trees and
// parked cars.
//
// Frame: world (render/camera.h): metres, +Y up, the road surface on y = 0. The street runs
// along Z; the street camera stands at the origin (on the road's centre line) looking down −Z.
// The scene spans z ∈ [−street_length_front_m, street_length_back_m]; beyond it the road plane
// continues to the horizon, so every downward ray hits the ground.
// Randomness: a pure function of (config, seed) (util/random.h), so one seed gives the
// same scene on every machine and thread count.
// Guarantees: the Mesh passes validate(); triangle counts stay in the hundreds to a few
// thousand, so the path tracer stays fast; every solid object on the ground (buildings,
// poles, trees, parked cars) is listed in `obstacles` with its axis-aligned footprint, so an
// inserted object can avoid them (data/object_placement.h).
// Throws: sl::Error naming the field for a range with min > max, a negative size, or a car
// model mesh that is empty.
#pragma once
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "render/mesh.h"

namespace sl::data {

struct StreetSceneConfig {
  double road_half_width_min_m = 4.0, road_half_width_max_m = 7.0;
  double sidewalk_width_min_m = 2.0, sidewalk_width_max_m = 4.5;
  double curb_height_m = 0.15;
  double street_length_front_m = 120.0, street_length_back_m = 40.0;
  double building_height_min_m = 5.0, building_height_max_m = 30.0;
  double building_frontage_min_m = 6.0, building_frontage_max_m = 25.0;
  double building_depth_min_m = 8.0, building_depth_max_m = 20.0;
  double building_setback_max_m = 3.0;
  double building_gap_probability = 0.25, building_gap_max_m = 10.0;
  bool poles = true;
  double pole_spacing_m = 25.0;
  bool trees = true;
  double tree_probability = 0.5;  // per pole slot, on the opposite spacing
  int parked_cars_max = 4;
  // Object-frame meshes (data/procedural_car.h frame) used for parked cars; empty = procedural.
  std::vector<std::shared_ptr<const render::Mesh>> car_models;
  double car_model_length_m = 4.5;  // car models are scaled to this length (±5 %)
};

void validate(const StreetSceneConfig& config);

// Axis-aligned footprint on the ground plane, x ∈ [x0, x1], z ∈ [z0, z1].
struct FootprintXZ {
  double x0 = 0, z0 = 0, x1 = 0, z1 = 0;
  std::string kind;  // "building", "pole", "tree", "car"
  bool overlaps(const FootprintXZ& o, double margin_m = 0.0) const {
    return x0 - margin_m < o.x1 && o.x0 - margin_m < x1 && z0 - margin_m < o.z1 && o.z0 - margin_m < z1;
  }
};

struct StreetScene {
  render::Mesh mesh;
  double road_half_width_m = 0.0;
  double sidewalk_width_m = 0.0;
  double z_front = 0.0, z_back = 0.0;  // the street's extent along Z (z_front < 0 < z_back)
  std::vector<FootprintXZ> obstacles;
};

StreetScene build_street_scene(const StreetSceneConfig& config, uint64_t seed);

}  // namespace sl::data
