#include "data/procedural_car.h"

#include <cmath>

#include "render/primitives.h"
#include "util/error.h"
#include "util/math.h"

using sl::render::make_box;
using sl::render::Material;
using sl::render::Mesh;

namespace sl::data {
namespace {

Material paint_material(const glm::vec3& rgb) {
  Material m;
  m.name = "car_paint";
  m.base_color_factor = glm::vec4(rgb, 1.0f);
  m.metallic = 0.0f;
  m.roughness = 0.35f;
  // A clear coat gives the sharp sky reflection of automotive paint over a softer base.
  m.clearcoat = 1.0f;
  m.clearcoat_roughness = 0.05f;
  return m;
}

Material simple_material(const char* name, glm::vec3 rgb, float metallic, float roughness) {
  Material m;
  m.name = name;
  m.base_color_factor = glm::vec4(rgb, 1.0f);
  m.metallic = metallic;
  m.roughness = roughness;
  return m;
}

}  // namespace

Mesh make_cylinder_z(const glm::vec3& c, float radius, float length, int segments, const Material& material) {
  SL_CHECK(segments >= 3, "make_cylinder_z: segments must be >= 3, got ", segments);
  SL_CHECK(std::isfinite(radius) && radius > 0.0f && std::isfinite(length) && length > 0.0f,
           "make_cylinder_z: radius and length must be finite and > 0, got ", radius, " and ", length);
  Mesh m;
  // Side: two rings with radial normals.
  for (int s = 0; s <= segments; ++s) {
    const float a = (2.0f * kPiF) * static_cast<float>(s % segments) / segments;
    const glm::vec3 n(std::cos(a), std::sin(a), 0.0f);
    for (int end = 0; end < 2; ++end) {
      m.positions.push_back(c + radius * n + glm::vec3(0.0f, 0.0f, end * length));
      m.normals.push_back(n);
      m.uvs.push_back({static_cast<float>(s) / segments, static_cast<float>(end)});
    }
  }
  for (int s = 0; s < segments; ++s) {
    const uint32_t a = 2 * s, b = a + 1, d = a + 2, e = a + 3;  // a,b at angle s; d,e at s+1
    m.triangles.push_back({a, d, b});
    m.triangles.push_back({b, d, e});
  }
  // Caps: a fan around a centre vertex, facing −Z at z0 and +Z at z1.
  for (int end = 0; end < 2; ++end) {
    const glm::vec3 n(0.0f, 0.0f, end ? 1.0f : -1.0f);
    const uint32_t centre = static_cast<uint32_t>(m.positions.size());
    m.positions.push_back(c + glm::vec3(0.0f, 0.0f, end * length));
    m.normals.push_back(n);
    m.uvs.push_back({0.5f, 0.5f});
    for (int s = 0; s < segments; ++s) {
      const float a = (2.0f * kPiF) * static_cast<float>(s) / segments;
      m.positions.push_back(c + glm::vec3(radius * std::cos(a), radius * std::sin(a), end * length));
      m.normals.push_back(n);
      m.uvs.push_back({0.5f + 0.5f * std::cos(a), 0.5f + 0.5f * std::sin(a)});
    }
    for (int s = 0; s < segments; ++s) {
      const uint32_t p = centre + 1 + s, q = centre + 1 + (s + 1) % segments;
      if (end) m.triangles.push_back({centre, p, q});
      else m.triangles.push_back({centre, q, p});
    }
  }
  m.materials = {material};
  m.material_ids.assign(m.triangles.size(), 0u);
  m.validate("make_cylinder_z");
  return m;
}

Mesh make_procedural_car(const ProceduralCarParams& p) {
  SL_CHECK(std::isfinite(p.length_m) && p.length_m > 0.5 && std::isfinite(p.width_m) && p.width_m > 0.3 &&
               std::isfinite(p.height_m) && p.height_m > 0.4,
           "make_procedural_car: length_m, width_m, height_m must be finite and reasonable (> 0.5, 0.3, 0.4 m), got ",
           p.length_m, ", ", p.width_m, ", ", p.height_m);
  for (int c = 0; c < 3; ++c)
    SL_CHECK(p.paint_rgb[c] >= 0.0f && p.paint_rgb[c] <= 1.0f, "make_procedural_car: paint_rgb[", c,
             "] must lie in [0, 1], got ", p.paint_rgb[c]);
  SL_CHECK(p.wheel_segments >= 6, "make_procedural_car: wheel_segments must be >= 6, got ", p.wheel_segments);

  const float L = static_cast<float>(p.length_m), W = static_cast<float>(p.width_m),
              H = static_cast<float>(p.height_m);
  const float wheel_r = 0.21f * H, wheel_w = 0.13f * W;
  const float body_lo = 0.6f * wheel_r, body_hi = 0.55f * H;
  const Material paint = paint_material(p.paint_rgb);
  const Material glass = simple_material("glass", {0.02f, 0.025f, 0.03f}, 0.0f, 0.05f);
  const Material rubber = simple_material("rubber", {0.03f, 0.03f, 0.03f}, 0.0f, 0.9f);
  const Material trim = simple_material("trim", {0.25f, 0.25f, 0.26f}, 0.8f, 0.4f);

  Mesh car = make_box({-0.5f * L, body_lo, -0.5f * W}, {0.5f * L, body_hi, 0.5f * W}, paint);
  // Cabin: set back from the nose; glass band below a painted roof.
  const float cab_x0 = -0.32f * L, cab_x1 = 0.18f * L, cab_w = 0.46f * W, roof_t = 0.06f * H;
  car.append(make_box({cab_x0, body_hi, -cab_w}, {cab_x1, H - roof_t, cab_w}, glass));
  car.append(make_box({cab_x0 - 0.02f, H - roof_t, -cab_w - 0.02f}, {cab_x1 + 0.02f, H, cab_w + 0.02f}, paint));
  // Bumpers.
  car.append(make_box({0.5f * L - 0.02f, body_lo, -0.48f * W}, {0.5f * L + 0.06f, body_lo + 0.18f, 0.48f * W}, trim));
  car.append(make_box({-0.5f * L - 0.06f, body_lo, -0.48f * W}, {-0.5f * L + 0.02f, body_lo + 0.18f, 0.48f * W}, trim));
  // Wheels slightly inside the body's sides, axles at ±0.32 L.
  for (float ax : {-0.32f * L, 0.32f * L})
    for (float side : {-1.0f, 1.0f}) {
      const float z0 = side > 0 ? 0.5f * W - wheel_w + 0.01f : -0.5f * W - 0.01f;
      car.append(make_cylinder_z({ax, wheel_r, z0}, wheel_r, wheel_w, p.wheel_segments, rubber));
    }
  car.validate("make_procedural_car");
  return car;
}

}  // namespace sl::data
