// Triangle meshes with metallic-roughness PBR materials (glTF 2.0 core + KHR_materials_clearcoat).
//
// Contract: a Mesh is plain data in the world frame (right-handed, metres, +Y up). Per vertex:
// position, unit normal, UV (glTF convention: v down, origin at the image's top-left). Per
// triangle: three vertex indices and a material id into `materials`. `validate()` checks every
// invariant below and throws sl::Error naming the offending array, index and value; the loaders
// call it before returning, so a Mesh from them is always valid:
//   normals and uvs are empty or have one entry per position;
//   material_ids has one entry per triangle and each is < materials.size();
//   every vertex index is < positions.size(); every position is finite.
// Texture pixels are linear RGBA floats (sRGB-encoded base colours are decoded on load).
#pragma once
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <glm/glm.hpp>

namespace sl::render {

struct Bounds3 {
  glm::vec3 lo{std::numeric_limits<float>::infinity()};
  glm::vec3 hi{-std::numeric_limits<float>::infinity()};

  void extend(const glm::vec3& p) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  void extend(const Bounds3& b) {
    lo = glm::min(lo, b.lo);
    hi = glm::max(hi, b.hi);
  }
  bool empty() const { return !(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z); }
  glm::vec3 centre() const { return 0.5f * (lo + hi); }
  glm::vec3 extent() const { return empty() ? glm::vec3(0.0f) : hi - lo; }
  // Half the surface area; the SAH only needs areas up to a common factor.
  float half_area() const {
    const glm::vec3 e = extent();
    return e.x * e.y + e.y * e.z + e.z * e.x;
  }
};

// Decoded image in linear RGBA float, row 0 at the top (v = 0).
struct Texture {
  int width = 0, height = 0;
  std::vector<float> rgba;  // width * height * 4

  // Bilinear lookup with REPEAT wrapping (the glTF default sampler). Texel centres sit at
  // ((i + 0.5) / width, (j + 0.5) / height). An empty texture samples as opaque white.
  glm::vec4 sample(glm::vec2 uv) const;
};

struct Material {
  std::string name;
  glm::vec4 base_color_factor{1.0f};                   // linear RGBA
  std::shared_ptr<const Texture> base_color_texture;   // null when absent
  float metallic = 1.0f;                               // glTF defaults
  float roughness = 1.0f;
  float clearcoat = 0.0f;  // KHR_materials_clearcoat: 0 means no coat
  float clearcoat_roughness = 0.0f;

  // factor × texture(uv), linear RGBA.
  glm::vec4 base_color(glm::vec2 uv) const {
    return base_color_texture ? base_color_factor * base_color_texture->sample(uv) : base_color_factor;
  }
};

struct Mesh {
  std::vector<glm::vec3> positions;
  std::vector<glm::vec3> normals;
  std::vector<glm::vec2> uvs;
  std::vector<glm::uvec3> triangles;
  std::vector<uint32_t> material_ids;
  std::vector<Material> materials;

  size_t vertex_count() const { return positions.size(); }
  size_t triangle_count() const { return triangles.size(); }
  Bounds3 bounds() const;

  // Throws sl::Error naming `what` (e.g. the source file) and the first broken invariant.
  void validate(const std::string& what = "mesh") const;

  // Area-weighted vertex normals from the faces; zero-area faces contribute nothing, and a
  // vertex touched only by such faces gets +Y.
  void compute_vertex_normals();

  // Appends `other`, offsetting its vertex indices and material ids.
  void append(const Mesh& other);
};

}  // namespace sl::render
