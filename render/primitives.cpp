// Procedural meshes: subdivided icosahedron, ground square, box.
#include "render/primitives.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

#include "util/error.h"
#include "util/math.h"

namespace sl::render {
namespace {

void check_size(float value, const char* what, const char* fn) {
  SL_CHECK(std::isfinite(value) && value >= 0.0f, fn, ": ", what, " must be finite and >= 0, got ", value);
}

Mesh with_material(Mesh m, const Material& material) {
  m.materials = {material};
  m.material_ids.assign(m.triangles.size(), 0u);
  m.validate("primitive");
  return m;
}

}  // namespace

Mesh make_icosphere(const glm::vec3& centre, float radius, int subdivisions, const Material& material) {
  check_size(radius, "radius", "make_icosphere");
  SL_CHECK(subdivisions >= 0 && subdivisions <= 7, "make_icosphere: subdivisions must be in [0, 7], got ",
           subdivisions);
  SL_CHECK(std::isfinite(centre.x) && std::isfinite(centre.y) && std::isfinite(centre.z),
           "make_icosphere: centre must be finite");
  // Icosahedron: the three golden rectangles (±1, ±φ, 0) and their cyclic permutations.
  const float g = (1.0f + std::sqrt(5.0f)) / 2.0f;
  std::vector<glm::vec3> unit = {{-1, g, 0}, {1, g, 0},   {-1, -g, 0}, {1, -g, 0}, {0, -1, g},  {0, 1, g},
                                 {0, -1, -g}, {0, 1, -g}, {g, 0, -1},  {g, 0, 1},  {-g, 0, -1}, {-g, 0, 1}};
  for (auto& v : unit) v = glm::normalize(v);
  std::vector<glm::uvec3> tris = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                  {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                  {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                  {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (int s = 0; s < subdivisions; ++s) {
    std::map<std::pair<uint32_t, uint32_t>, uint32_t> midpoint;  // shared edges get one vertex
    auto mid = [&](uint32_t a, uint32_t b) {
      const auto key = std::minmax(a, b);
      auto it = midpoint.find(key);
      if (it != midpoint.end()) return it->second;
      unit.push_back(glm::normalize(unit[a] + unit[b]));
      const uint32_t id = static_cast<uint32_t>(unit.size() - 1);
      midpoint.emplace(key, id);
      return id;
    };
    std::vector<glm::uvec3> next;
    next.reserve(tris.size() * 4);
    for (const glm::uvec3& t : tris) {
      const uint32_t ab = mid(t.x, t.y), bc = mid(t.y, t.z), ca = mid(t.z, t.x);
      next.push_back({t.x, ab, ca});
      next.push_back({t.y, bc, ab});
      next.push_back({t.z, ca, bc});
      next.push_back({ab, bc, ca});
    }
    tris = std::move(next);
  }
  Mesh m;
  for (const glm::vec3& u : unit) {
    m.positions.push_back(centre + radius * u);
    m.normals.push_back(u);
    // Equirectangular UVs (glTF v down); the seam is left unsplit, which only matters for textures.
    m.uvs.push_back({0.5f + std::atan2(u.x, -u.z) / (2.0f * kPiF), 0.5f - std::asin(u.y) / kPiF});
  }
  m.triangles = std::move(tris);
  return with_material(std::move(m), material);
}

Mesh make_ground_plane(float size_m, float height, const Material& material, float centre_x, float centre_z) {
  check_size(size_m, "size_m", "make_ground_plane");
  SL_CHECK(std::isfinite(height) && std::isfinite(centre_x) && std::isfinite(centre_z),
           "make_ground_plane: height and centre must be finite");
  const float h = 0.5f * size_m;
  Mesh m;
  m.positions = {{centre_x - h, height, centre_z - h},
                 {centre_x + h, height, centre_z - h},
                 {centre_x + h, height, centre_z + h},
                 {centre_x - h, height, centre_z + h}};
  m.normals.assign(4, glm::vec3(0, 1, 0));
  m.uvs = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  m.triangles = {{0, 2, 1}, {0, 3, 2}};  // counter-clockwise seen from +Y
  return with_material(std::move(m), material);
}

Mesh make_box(const glm::vec3& lo, const glm::vec3& hi, const Material& material) {
  for (int k = 0; k < 3; ++k)
    SL_CHECK(std::isfinite(lo[k]) && std::isfinite(hi[k]) && lo[k] <= hi[k], "make_box: need finite lo <= hi, got axis ",
             k, " lo ", lo[k], " hi ", hi[k]);
  Mesh m;
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side) {
      glm::vec3 n(0.0f);
      n[axis] = side ? 1.0f : -1.0f;
      const int a = (axis + 1) % 3, b = (axis + 2) % 3;  // (a, b, axis) is right-handed
      const uint32_t base = static_cast<uint32_t>(m.positions.size());
      for (int corner = 0; corner < 4; ++corner) {
        glm::vec3 p;
        p[axis] = side ? hi[axis] : lo[axis];
        const bool ua = corner == 1 || corner == 2, ub = corner >= 2;
        p[a] = ua ? hi[a] : lo[a];
        p[b] = ub ? hi[b] : lo[b];
        m.positions.push_back(p);
        m.normals.push_back(n);
        m.uvs.push_back({ua ? 1.0f : 0.0f, ub ? 1.0f : 0.0f});
      }
      // Corners go counter-clockwise around +axis; reverse them for the -axis face.
      if (side)
        m.triangles.insert(m.triangles.end(), {{base, base + 1, base + 2}, {base, base + 2, base + 3}});
      else
        m.triangles.insert(m.triangles.end(), {{base, base + 2, base + 1}, {base, base + 3, base + 2}});
    }
  return with_material(std::move(m), material);
}

}  // namespace sl::render
