#include "data/street_scene.h"

#include <algorithm>
#include <cmath>

#include "data/object_placement.h"
#include "data/procedural_car.h"
#include "render/primitives.h"
#include "util/error.h"
#include "util/random.h"

using sl::render::make_box;
using sl::render::make_ground_plane;
using sl::render::make_icosphere;
using sl::render::Material;
using sl::render::Mesh;
using sl::render::placed_mesh;
using sl::render::Placement;

namespace sl::data {
namespace {

Material material(const char* name, glm::vec3 rgb, float roughness, float metallic = 0.0f) {
  Material m;
  m.name = name;
  m.base_color_factor = glm::vec4(rgb, 1.0f);
  m.roughness = roughness;
  m.metallic = metallic;
  return m;
}

void check_range(double lo, double hi, const char* name) {
  SL_CHECK(std::isfinite(lo) && std::isfinite(hi) && lo >= 0.0 && lo <= hi, "StreetSceneConfig: ", name,
           " range must be finite, >= 0 and min <= max, got [", lo, ", ", hi, "]");
}

// Facade albedos (linear) from a palette of plaster, brick, stone and concrete, each jittered:
// real facades span roughly 0.1-0.6 in albedo, and varied colours keep a model from learning
// one wall colour as "the" lighting.
glm::vec3 facade_colour(Rng& rng) {
  static const glm::vec3 palette[] = {{0.55f, 0.50f, 0.42f}, {0.42f, 0.20f, 0.14f}, {0.60f, 0.58f, 0.55f},
                                      {0.30f, 0.30f, 0.32f}, {0.62f, 0.52f, 0.33f}, {0.35f, 0.40f, 0.45f},
                                      {0.70f, 0.68f, 0.62f}, {0.25f, 0.18f, 0.15f}};
  const glm::vec3 base = palette[rng.randint(8)];
  const float brightness = static_cast<float>(rng.uniform(0.7, 1.15));
  glm::vec3 c = base * brightness;
  for (int k = 0; k < 3; ++k) c[k] = std::clamp(c[k] * static_cast<float>(rng.uniform(0.92, 1.08)), 0.02f, 0.9f);
  return c;
}

glm::vec3 car_colour(Rng& rng) {
  static const glm::vec3 palette[] = {{0.6f, 0.6f, 0.62f}, {0.03f, 0.03f, 0.035f}, {0.5f, 0.04f, 0.03f},
                                      {0.05f, 0.12f, 0.35f}, {0.75f, 0.75f, 0.72f}, {0.2f, 0.22f, 0.24f},
                                      {0.08f, 0.25f, 0.1f}, {0.7f, 0.5f, 0.1f}};
  return palette[rng.randint(8)];
}

// One side of the street (side = −1 left, +1 right): curb, sidewalk slab and buildings.
void add_side(StreetScene& s, const StreetSceneConfig& c, double side, Rng& rng) {
  const double r = s.road_half_width_m, curb_w = 0.25, h = c.curb_height_m;
  const Material curb = material("curb", {0.45f, 0.44f, 0.42f}, 0.8f);
  const Material pavement = material("sidewalk", glm::vec3(static_cast<float>(rng.uniform(0.25, 0.4))), 0.85f);
  auto x_range = [&](double a, double b) { return side > 0 ? std::make_pair(a, b) : std::make_pair(-b, -a); };
  auto box = [&](double a, double b, double y0, double y1, double z0, double z1, const Material& m) {
    const auto [x0, x1] = x_range(a, b);
    s.mesh.append(make_box({static_cast<float>(x0), static_cast<float>(y0), static_cast<float>(z0)},
                           {static_cast<float>(x1), static_cast<float>(y1), static_cast<float>(z1)}, m));
  };
  box(r, r + curb_w, 0.0, h, s.z_front, s.z_back, curb);
  // The slab reaches past the buildings so lots between them are paved, not road.
  const double lot_end = r + curb_w + s.sidewalk_width_m + c.building_setback_max_m + c.building_depth_max_m + 5.0;
  box(r + curb_w, lot_end, 0.0, h - 0.01, s.z_front, s.z_back, pavement);

  const double front0 = r + curb_w + s.sidewalk_width_m;
  for (double z = s.z_front; z < s.z_back;) {
    if (rng.uniform() < c.building_gap_probability) {
      z += rng.uniform(2.0, std::max(2.0, c.building_gap_max_m));
      continue;
    }
    const double frontage = rng.uniform(c.building_frontage_min_m, c.building_frontage_max_m);
    const double z1 = std::min(z + frontage, s.z_back);
    if (z1 - z < 2.0) break;  // the street's end clips the last building to a sliver
    const double setback = rng.uniform(0.0, c.building_setback_max_m);
    const double depth = rng.uniform(c.building_depth_min_m, c.building_depth_max_m);
    const double height = rng.uniform(c.building_height_min_m, c.building_height_max_m);
    const Material wall = material("facade", facade_colour(rng), static_cast<float>(rng.uniform(0.6, 0.95)));
    box(front0 + setback, front0 + setback + depth, 0.0, height, z, z1, wall);
    // A ground-floor band (shop fronts) and a roof parapet vary the silhouette and shading.
    if (rng.uniform() < 0.5 && height > 6.0) {
      const Material band = material("shopfront", facade_colour(rng) * 0.6f, 0.3f);
      box(front0 + setback - 0.15, front0 + setback, 0.0, 3.2, z + 0.3, z1 - 0.3, band);
    }
    if (rng.uniform() < 0.4) box(front0 + setback + 0.5, front0 + setback + depth - 0.5, height, height + 1.5,
                                 z + 0.5, z1 - 0.5, wall);
    const auto [fx0, fx1] = x_range(front0 + setback - 0.15, front0 + setback + depth);
    s.obstacles.push_back({fx0, z, fx1, z1, "building"});
    z = z1;
  }

  // Poles on the sidewalk near the curb; trees halfway between them.
  if (c.pole_spacing_m > 0.0) {
    const double px = side * (r + curb_w + 0.5);
    const Material metal = material("pole", {0.3f, 0.3f, 0.3f}, 0.5f, 0.8f);
    const Material bark = material("bark", {0.12f, 0.08f, 0.05f}, 0.9f);
    const Material leaves = material("leaves", {0.06f, 0.16f, 0.04f}, 0.8f);
    const double offset = rng.uniform(0.0, c.pole_spacing_m);
    for (double z = s.z_front + offset; z < s.z_back; z += c.pole_spacing_m) {
      if (c.poles) {
        const double height = rng.uniform(5.0, 8.0);
        s.mesh.append(make_box({static_cast<float>(px - 0.08), 0.0f, static_cast<float>(z - 0.08)},
                               {static_cast<float>(px + 0.08), static_cast<float>(height), static_cast<float>(z + 0.08)},
                               metal));
        const double arm_end = px - side * 1.5;
        s.mesh.append(make_box({static_cast<float>(std::min(px, arm_end)), static_cast<float>(height - 0.1),
                                static_cast<float>(z - 0.06)},
                               {static_cast<float>(std::max(px, arm_end)), static_cast<float>(height),
                                static_cast<float>(z + 0.06)},
                               metal));
        s.obstacles.push_back({px - 0.08, z - 0.08, px + 0.08, z + 0.08, "pole"});
      }
      const double tz = z + 0.5 * c.pole_spacing_m;
      if (c.trees && tz < s.z_back && rng.uniform() < c.tree_probability) {
        const double trunk = rng.uniform(2.0, 3.5), crown = rng.uniform(1.2, 2.5);
        s.mesh.append(make_box({static_cast<float>(px - 0.12), 0.0f, static_cast<float>(tz - 0.12)},
                               {static_cast<float>(px + 0.12), static_cast<float>(trunk), static_cast<float>(tz + 0.12)},
                               bark));
        s.mesh.append(make_icosphere({static_cast<float>(px), static_cast<float>(trunk + 0.8 * crown),
                                      static_cast<float>(tz)},
                                     static_cast<float>(crown), 1, leaves));
        s.obstacles.push_back({px - crown, tz - crown, px + crown, tz + crown, "tree"});
      }
    }
  }
}

void add_parked_cars(StreetScene& s, const StreetSceneConfig& c, Rng& rng) {
  if (c.parked_cars_max <= 0) return;
  const int n = static_cast<int>(rng.randint(c.parked_cars_max + 1));
  for (int i = 0; i < n; ++i) {
    Mesh model;
    double scale = 1.0;
    if (!c.car_models.empty()) {
      model = *c.car_models[static_cast<size_t>(rng.randint(static_cast<int64_t>(c.car_models.size())))];
      scale = scale_to_length(model, c.car_model_length_m * rng.uniform(0.95, 1.05));
    } else {
      ProceduralCarParams p;
      p.length_m = rng.uniform(4.0, 4.9);
      p.width_m = rng.uniform(1.7, 1.9);
      p.height_m = rng.uniform(1.35, 1.65);
      p.paint_rgb = car_colour(rng);
      p.wheel_segments = 8;
      model = make_procedural_car(p);
    }
    // Parked along a curb (the camera's own lane stays clear), heading up or down the street.
    const double side = rng.uniform() < 0.5 ? -1.0 : 1.0;
    Placement pl;
    pl.x_m = side * (s.road_half_width_m - 1.2);
    pl.z_m = rng.uniform(s.z_front + 10.0, s.z_back - 5.0);
    pl.yaw_deg = (rng.uniform() < 0.5 ? 90.0 : -90.0) + rng.uniform(-3.0, 3.0);
    pl.scale = scale;
    const FootprintXZ fp = placed_footprint(model, pl);
    // The street camera's surroundings stay free so views are not blocked at close range.
    bool free = !(fp.x0 < 1.5 && fp.x1 > -1.5 && fp.z0 < 4.0 && fp.z1 > -8.0);
    for (const FootprintXZ& o : s.obstacles) free = free && !o.overlaps(fp, 0.5);
    if (!free) continue;
    s.mesh.append(placed_mesh(model, pl));
    FootprintXZ car = fp;
    car.kind = "car";
    s.obstacles.push_back(car);
  }
}

}  // namespace

void validate(const StreetSceneConfig& c) {
  check_range(c.road_half_width_min_m, c.road_half_width_max_m, "road_half_width_m");
  SL_CHECK(c.road_half_width_min_m >= 2.0, "StreetSceneConfig: road_half_width_min_m must be >= 2, got ",
           c.road_half_width_min_m);
  check_range(c.sidewalk_width_min_m, c.sidewalk_width_max_m, "sidewalk_width_m");
  check_range(c.building_height_min_m, c.building_height_max_m, "building_height_m");
  check_range(c.building_frontage_min_m, c.building_frontage_max_m, "building_frontage_m");
  check_range(c.building_depth_min_m, c.building_depth_max_m, "building_depth_m");
  SL_CHECK(c.building_frontage_min_m >= 2.0, "StreetSceneConfig: building_frontage_min_m must be >= 2, got ",
           c.building_frontage_min_m);
  SL_CHECK(c.building_depth_min_m >= 2.0 && c.building_height_min_m >= 1.0,
           "StreetSceneConfig: building_depth_min_m must be >= 2 and building_height_min_m >= 1, got ",
           c.building_depth_min_m, " and ", c.building_height_min_m);
  SL_CHECK(c.street_length_front_m >= 20.0 && c.street_length_back_m >= 10.0 &&
               std::isfinite(c.street_length_front_m + c.street_length_back_m),
           "StreetSceneConfig: street_length_front_m >= 20 and street_length_back_m >= 10 required, got ",
           c.street_length_front_m, " and ", c.street_length_back_m);
  SL_CHECK(c.curb_height_m > 0.0 && c.curb_height_m < 0.5, "StreetSceneConfig: curb_height_m must be in (0, 0.5), got ",
           c.curb_height_m);
  SL_CHECK(c.building_setback_max_m >= 0.0 && c.building_gap_max_m >= 0.0,
           "StreetSceneConfig: building_setback_max_m and building_gap_max_m must be >= 0");
  SL_CHECK(c.building_gap_probability >= 0.0 && c.building_gap_probability <= 0.9,
           "StreetSceneConfig: building_gap_probability must be in [0, 0.9], got ", c.building_gap_probability);
  SL_CHECK(c.tree_probability >= 0.0 && c.tree_probability <= 1.0,
           "StreetSceneConfig: tree_probability must be in [0, 1], got ", c.tree_probability);
  SL_CHECK(c.pole_spacing_m == 0.0 || c.pole_spacing_m >= 5.0,
           "StreetSceneConfig: pole_spacing_m must be 0 (none) or >= 5, got ", c.pole_spacing_m);
  SL_CHECK(c.parked_cars_max >= 0 && c.parked_cars_max <= 64, "StreetSceneConfig: parked_cars_max must be in [0, 64], got ",
           c.parked_cars_max);
  SL_CHECK(c.car_model_length_m > 0.5, "StreetSceneConfig: car_model_length_m must be > 0.5, got ", c.car_model_length_m);
  for (size_t i = 0; i < c.car_models.size(); ++i)
    SL_CHECK(c.car_models[i] && c.car_models[i]->triangle_count() > 0, "StreetSceneConfig: car_models[", i,
             "] is empty");
}

StreetScene build_street_scene(const StreetSceneConfig& c, uint64_t seed) {
  validate(c);
  Rng rng(seed, 0x57EE7);
  StreetScene s;
  s.road_half_width_m = rng.uniform(c.road_half_width_min_m, c.road_half_width_max_m);
  s.sidewalk_width_m = rng.uniform(c.sidewalk_width_min_m, c.sidewalk_width_max_m);
  s.z_front = -c.street_length_front_m;
  s.z_back = c.street_length_back_m;

  // The road plane reaches far past the street so rays just below the horizon still hit ground.
  const float asphalt_albedo = static_cast<float>(rng.uniform(0.06, 0.14));
  s.mesh = make_ground_plane(4000.0f, 0.0f, material("asphalt", glm::vec3(asphalt_albedo), 0.9f));
  // Dashed centre line, raised a few millimetres so it never z-fights with the road.
  const Material paint = material("road_marking", {0.7f, 0.7f, 0.68f}, 0.6f);
  for (double z = s.z_front; z < s.z_back; z += 9.0)
    s.mesh.append(make_box({-0.07f, 0.0f, static_cast<float>(z)}, {0.07f, 0.004f, static_cast<float>(z + 3.0)}, paint));

  Rng left(seed, 0x1EF7), right(seed, 0x216E7), cars(seed, 0xCA125);
  add_side(s, c, -1.0, left);
  add_side(s, c, +1.0, right);
  add_parked_cars(s, c, cars);
  s.mesh.validate("build_street_scene");
  return s;
}

}  // namespace sl::data
