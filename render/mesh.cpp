#include "render/mesh.h"

#include <cmath>

#include "util/error.h"

namespace sl::render {

glm::vec4 Texture::sample(glm::vec2 uv) const {
  if (width <= 0 || height <= 0 || rgba.size() < static_cast<size_t>(width) * height * 4) return glm::vec4(1.0f);
  if (!std::isfinite(uv.x) || !std::isfinite(uv.y)) uv = glm::vec2(0.0f);
  // Continuous texel coordinates; texel centres at integer + 0.5.
  const float x = (uv.x - std::floor(uv.x)) * width - 0.5f;
  const float y = (uv.y - std::floor(uv.y)) * height - 0.5f;
  const float fx = std::floor(x), fy = std::floor(y);
  const float ax = x - fx, ay = y - fy;
  auto wrap = [](int i, int n) { return ((i % n) + n) % n; };
  const int x0 = wrap(static_cast<int>(fx), width), x1 = wrap(static_cast<int>(fx) + 1, width);
  const int y0 = wrap(static_cast<int>(fy), height), y1 = wrap(static_cast<int>(fy) + 1, height);
  auto texel = [&](int i, int j) {
    const float* p = &rgba[(static_cast<size_t>(j) * width + i) * 4];
    return glm::vec4(p[0], p[1], p[2], p[3]);
  };
  return (1 - ay) * ((1 - ax) * texel(x0, y0) + ax * texel(x1, y0)) +
         ay * ((1 - ax) * texel(x0, y1) + ax * texel(x1, y1));
}

Bounds3 Mesh::bounds() const {
  Bounds3 b;
  for (const auto& t : triangles)
    for (int k = 0; k < 3; ++k) b.extend(positions[t[k]]);
  return b;
}

void Mesh::validate(const std::string& what) const {
  const size_t nv = positions.size();
  SL_CHECK(normals.empty() || normals.size() == nv, what, ": normals has ", normals.size(),
           " entries, expected 0 or ", nv, " (one per position)");
  SL_CHECK(uvs.empty() || uvs.size() == nv, what, ": uvs has ", uvs.size(), " entries, expected 0 or ", nv);
  SL_CHECK(material_ids.size() == triangles.size(), what, ": material_ids has ", material_ids.size(),
           " entries, expected ", triangles.size(), " (one per triangle)");
  for (size_t i = 0; i < nv; ++i) {
    const glm::vec3& p = positions[i];
    SL_CHECK(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z), what, ": position ", i,
             " is not finite (", p.x, ", ", p.y, ", ", p.z, ")");
  }
  for (size_t t = 0; t < triangles.size(); ++t) {
    for (int k = 0; k < 3; ++k)
      SL_CHECK(triangles[t][k] < nv, what, ": triangle ", t, " has vertex index ", triangles[t][k],
               " out of range [0, ", nv, ")");
    SL_CHECK(material_ids[t] < materials.size(), what, ": triangle ", t, " has material id ", material_ids[t],
             " but there are ", materials.size(), " materials");
  }
}

void Mesh::compute_vertex_normals() {
  normals.assign(positions.size(), glm::vec3(0.0f));
  for (const auto& t : triangles) {
    // The unnormalised cross product weights each face by twice its area.
    const glm::vec3 n = glm::cross(positions[t[1]] - positions[t[0]], positions[t[2]] - positions[t[0]]);
    if (!std::isfinite(n.x + n.y + n.z)) continue;
    for (int k = 0; k < 3; ++k) normals[t[k]] += n;
  }
  for (auto& n : normals) {
    const float len = glm::length(n);
    n = len > 0.0f && std::isfinite(len) ? n / len : glm::vec3(0.0f, 1.0f, 0.0f);
  }
}

void Mesh::append(const Mesh& other) {
  const uint32_t v0 = static_cast<uint32_t>(positions.size());
  const uint32_t m0 = static_cast<uint32_t>(materials.size());
  // Keep normals and uvs either absent or complete: fill the side that lacks them.
  if (normals.empty() != other.normals.empty() && !(positions.empty() || other.positions.empty())) {
    if (normals.empty()) compute_vertex_normals();
  }
  const bool want_uvs = !uvs.empty() || !other.uvs.empty();
  positions.insert(positions.end(), other.positions.begin(), other.positions.end());
  if (!normals.empty() || v0 == 0) {
    if (other.normals.empty() && !other.positions.empty()) {
      Mesh copy;
      copy.positions = other.positions;
      copy.triangles = other.triangles;
      copy.compute_vertex_normals();
      normals.insert(normals.end(), copy.normals.begin(), copy.normals.end());
    } else {
      normals.insert(normals.end(), other.normals.begin(), other.normals.end());
    }
  }
  if (want_uvs) {
    uvs.resize(v0, glm::vec2(0.0f));
    if (other.uvs.empty())
      uvs.resize(positions.size(), glm::vec2(0.0f));
    else
      uvs.insert(uvs.end(), other.uvs.begin(), other.uvs.end());
  }
  for (const auto& t : other.triangles) triangles.push_back(t + glm::uvec3(v0));
  for (uint32_t m : other.material_ids) material_ids.push_back(m + m0);
  materials.insert(materials.end(), other.materials.begin(), other.materials.end());
}

}  // namespace sl::render
