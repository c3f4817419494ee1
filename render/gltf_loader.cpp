#include "render/gltf_loader.h"

#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <set>
#include <string_view>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>

#include "util/error.h"

namespace sl::render {
namespace {

constexpr const char* kCompressionExtensions[] = {"KHR_draco_mesh_compression", "EXT_meshopt_compression",
                                                  "KHR_meshopt_compression"};

std::vector<unsigned char> read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  SL_CHECK(in.good(), "gltf: cannot open '", path, "'");
  const std::streamoff size = in.tellg();
  SL_CHECK(size >= 0, "gltf: cannot read '", path, "'");
  std::vector<unsigned char> bytes(static_cast<size_t>(size));
  in.seekg(0);
  if (size > 0) in.read(reinterpret_cast<char*>(bytes.data()), size);
  SL_CHECK(in.good(), "gltf: cannot read '", path, "' (", size, " bytes)");
  return bytes;
}

uint32_t read_u32(const unsigned char* p) {
  uint32_t v;
  std::memcpy(&v, p, 4);
  return v;
}

// The GLB container (header, JSON chunk, optional BIN chunk) is checked here so that a
// truncated or inconsistent file is reported precisely and never reaches the parser.
void check_glb_container(const std::vector<unsigned char>& b, const std::string& path) {
  SL_CHECK(b.size() >= 20, "gltf: '", path, "' is truncated: ", b.size(), " bytes, a .glb needs at least 20");
  const uint32_t version = read_u32(&b[4]), length = read_u32(&b[8]);
  SL_CHECK(version == 2, "gltf: '", path, "' has .glb version ", version, ", only 2 is supported");
  SL_CHECK(length <= b.size(), "gltf: '", path, "' is truncated: header declares ", length, " bytes, file has ",
           b.size());
  const uint64_t json_len = read_u32(&b[12]);
  SL_CHECK(read_u32(&b[16]) == 0x4E4F534Au, "gltf: '", path, "': first .glb chunk is not JSON");
  SL_CHECK(20 + json_len <= length, "gltf: '", path, "' is truncated: JSON chunk of ", json_len,
           " bytes exceeds the file length ", length);
  const uint64_t bin_at = 20 + json_len;
  if (bin_at + 8 <= length) {
    const uint64_t bin_len = read_u32(&b[bin_at]);
    SL_CHECK(bin_at + 8 + bin_len <= length, "gltf: '", path, "' is truncated: BIN chunk of ", bin_len,
             " bytes exceeds the file length ", length);
  }
}

// Compressed geometry makes tinygltf fail with unrelated messages ("Invalid byteLength",
// "invalid bufferView"), so the JSON text is scanned for the extension names before parsing:
// a name in quotes is an extension key or an entry of extensionsUsed/extensionsRequired.
void reject_compression(const char* json, size_t size, const std::string& path) {
  const std::string_view text(json, size);
  for (const char* ext : kCompressionExtensions)
    SL_CHECK(text.find(std::string("\"") + ext + "\"") == std::string_view::npos, "gltf: '", path, "' uses ", ext,
             ": compressed geometry is not supported (decompress it first, e.g. gltf-transform copy)");
}

std::string directory_of(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  return slash == std::string::npos ? std::string(".") : path.substr(0, slash);
}

const char* mode_name(int mode) {
  switch (mode) {
    case 0: return "POINTS";
    case 1: return "LINES";
    case 2: return "LINE_LOOP";
    case 3: return "LINE_STRIP";
    default: return "unknown";
  }
}

float srgb_to_linear(float c) {
  return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}

class Importer {
 public:
  Importer(const tinygltf::Model& model, const std::string& path) : m_(model), path_(path) {}

  Mesh run() {
    check_extensions();
    std::vector<int> roots;
    if (!m_.scenes.empty()) {
      const int s = m_.defaultScene >= 0 && m_.defaultScene < static_cast<int>(m_.scenes.size()) ? m_.defaultScene : 0;
      roots = m_.scenes[s].nodes;
    } else {
      std::vector<bool> is_child(m_.nodes.size(), false);
      for (const auto& n : m_.nodes)
        for (int c : n.children)
          if (c >= 0 && c < static_cast<int>(m_.nodes.size())) is_child[c] = true;
      for (size_t i = 0; i < m_.nodes.size(); ++i)
        if (!is_child[i]) roots.push_back(static_cast<int>(i));
    }
    for (int r : roots) visit(r, glm::dmat4(1.0), 0);
    out_.validate("gltf: '" + path_ + "'");
    return std::move(out_);
  }

 private:
  void check_extensions() const {
    for (const char* ext : kCompressionExtensions) {
      for (const auto& list : {m_.extensionsRequired, m_.extensionsUsed})
        for (const auto& e : list)
          SL_CHECK(e != ext, "gltf: '", path_, "' uses ", ext, ": compressed geometry is not supported");
      for (size_t i = 0; i < m_.bufferViews.size(); ++i)
        SL_CHECK(!m_.bufferViews[i].extensions.count(ext), "gltf: '", path_, "' bufferView ", i, " uses ", ext,
                 ": compressed geometry is not supported");
    }
  }

  glm::dmat4 local_transform(const tinygltf::Node& n) const {
    if (n.matrix.size() == 16) return glm::make_mat4(n.matrix.data());  // column-major, as glTF stores it
    glm::dmat4 t(1.0), r(1.0), s(1.0);
    if (n.translation.size() == 3) t[3] = glm::dvec4(n.translation[0], n.translation[1], n.translation[2], 1.0);
    if (n.rotation.size() == 4) {
      // glTF quaternions are (x, y, z, w); glm's constructor takes (w, x, y, z).
      glm::dquat q(n.rotation[3], n.rotation[0], n.rotation[1], n.rotation[2]);
      const double len = glm::length(q);
      if (len > 0.0 && std::isfinite(len)) r = glm::mat4_cast(q / len);
    }
    if (n.scale.size() == 3) s = glm::scale(glm::dmat4(1.0), glm::dvec3(n.scale[0], n.scale[1], n.scale[2]));
    return t * r * s;
  }

  void visit(int index, const glm::dmat4& parent, int depth) {
    SL_CHECK(index >= 0 && index < static_cast<int>(m_.nodes.size()), "gltf: '", path_, "' references node ",
             index, " but has ", m_.nodes.size(), " nodes");
    SL_CHECK(!on_path_.count(index) && depth < 1024, "gltf: '", path_, "' has a cycle in its node hierarchy at node ",
             index);
    // glTF 2.0 §3.5.3: the hierarchy is a set of disjoint trees. A node reached twice (a DAG, e.g.
    // each node listing the next one twice) would multiply the mesh exponentially in the depth.
    SL_CHECK(visited_.insert(index).second, "gltf: '", path_, "' reaches node ", index,
             " twice: the node hierarchy must be a set of disjoint trees");
    on_path_.insert(index);
    const tinygltf::Node& node = m_.nodes[index];
    const glm::dmat4 world = parent * local_transform(node);
    if (node.mesh >= 0) {
      SL_CHECK(node.mesh < static_cast<int>(m_.meshes.size()), "gltf: '", path_, "' node ", index,
               " references mesh ", node.mesh, " but has ", m_.meshes.size(), " meshes");
      const auto& mesh = m_.meshes[node.mesh];
      for (size_t p = 0; p < mesh.primitives.size(); ++p) add_primitive(mesh.primitives[p], world, node.mesh, p);
    }
    for (int c : node.children) visit(c, world, depth + 1);
    on_path_.erase(index);
  }

  struct View {
    const unsigned char* data = nullptr;
    size_t stride = 0, count = 0;
    int component_type = 0, components = 0;
    bool normalized = false;
  };

  View view(int accessor_index, const std::string& what) const {
    SL_CHECK(accessor_index >= 0 && accessor_index < static_cast<int>(m_.accessors.size()), "gltf: '", path_, "' ",
             what, " references accessor ", accessor_index, " but there are ", m_.accessors.size());
    const auto& a = m_.accessors[accessor_index];
    SL_CHECK(!a.sparse.isSparse, "gltf: '", path_, "' ", what, " accessor ", accessor_index,
             " is sparse, which is unsupported");
    SL_CHECK(a.bufferView >= 0 && a.bufferView < static_cast<int>(m_.bufferViews.size()), "gltf: '", path_, "' ",
             what, " accessor ", accessor_index, " has bufferView ", a.bufferView, " (missing or out of range)");
    const auto& bv = m_.bufferViews[a.bufferView];
    SL_CHECK(bv.buffer >= 0 && bv.buffer < static_cast<int>(m_.buffers.size()), "gltf: '", path_, "' bufferView ",
             a.bufferView, " references missing buffer ", bv.buffer);
    const auto& buf = m_.buffers[bv.buffer];
    // Each sum is bounded term by term: offsets and lengths are arbitrary 64-bit numbers in the
    // file, and a wrapped sum would pass a naive check.
    SL_CHECK(bv.byteOffset <= buf.data.size() && bv.byteLength <= buf.data.size() - bv.byteOffset, "gltf: '", path_,
             "' bufferView ", a.bufferView, " spans bytes [", bv.byteOffset, ", ", bv.byteOffset + bv.byteLength,
             ") but buffer ", bv.buffer, " has ", buf.data.size(), " bytes (missing or truncated buffer)");
    View v;
    const int comp_size = tinygltf::GetComponentSizeInBytes(static_cast<uint32_t>(a.componentType));
    v.components = tinygltf::GetNumComponentsInType(static_cast<uint32_t>(a.type));
    const int stride = a.ByteStride(bv);
    SL_CHECK(comp_size > 0 && v.components > 0 && stride > 0, "gltf: '", path_, "' ", what, " accessor ",
             accessor_index, " has an invalid component type ", a.componentType, ", type ", a.type,
             " or byteStride ", bv.byteStride);
    const uint64_t elem = static_cast<uint64_t>(comp_size) * v.components;
    // count < 2^32 and stride < 2^31 keep stride·(count − 1) + elem below 2^63.
    SL_CHECK(a.count == 0 || (a.count < (uint64_t{1} << 32) && a.byteOffset <= bv.byteLength &&
                              static_cast<uint64_t>(stride) * (a.count - 1) + elem <= bv.byteLength - a.byteOffset),
             "gltf: '", path_, "' ", what, " accessor ", accessor_index, " (", a.count,
             " elements) reads past the end of bufferView ", a.bufferView, " (", bv.byteLength, " bytes)");
    v.data = buf.data.data() + bv.byteOffset + a.byteOffset;
    v.stride = static_cast<size_t>(stride);
    v.count = a.count;
    v.component_type = a.componentType;
    v.normalized = a.normalized;
    return v;
  }

  // Component c of element i as float; integer types are normalised when the accessor says so.
  static float component(const View& v, size_t i, int c) {
    const unsigned char* p = v.data + i * v.stride;
    switch (v.component_type) {
      case TINYGLTF_COMPONENT_TYPE_FLOAT: { float x; std::memcpy(&x, p + 4 * c, 4); return x; }
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: { const float x = p[c]; return v.normalized ? x / 255.0f : x; }
      case TINYGLTF_COMPONENT_TYPE_BYTE: {
        const float x = static_cast<signed char>(p[c]);
        return v.normalized ? std::max(x / 127.0f, -1.0f) : x;
      }
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
        uint16_t x; std::memcpy(&x, p + 2 * c, 2);
        return v.normalized ? x / 65535.0f : static_cast<float>(x);
      }
      case TINYGLTF_COMPONENT_TYPE_SHORT: {
        int16_t x; std::memcpy(&x, p + 2 * c, 2);
        return v.normalized ? std::max(x / 32767.0f, -1.0f) : static_cast<float>(x);
      }
      default: return 0.0f;
    }
  }

  void require(const View& v, int components, bool float_only, const std::string& what, int accessor) const {
    SL_CHECK(v.components == components, "gltf: '", path_, "' ", what, " accessor ", accessor, " has ", v.components,
             " components, expected ", components);
    SL_CHECK(!float_only || v.component_type == TINYGLTF_COMPONENT_TYPE_FLOAT, "gltf: '", path_, "' ", what,
             " accessor ", accessor, " has component type ", v.component_type, ", expected FLOAT (5126)");
    SL_CHECK(v.component_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT &&
                 v.component_type != TINYGLTF_COMPONENT_TYPE_DOUBLE && v.component_type != TINYGLTF_COMPONENT_TYPE_INT,
             "gltf: '", path_, "' ", what, " accessor ", accessor, " has unsupported component type ",
             v.component_type);
  }

  std::vector<uint32_t> read_indices(const tinygltf::Primitive& prim, size_t vertex_count,
                                     const std::string& what) const {
    std::vector<uint32_t> idx;
    if (prim.indices < 0) {
      idx.resize(vertex_count);
      for (size_t i = 0; i < vertex_count; ++i) idx[i] = static_cast<uint32_t>(i);
      return idx;
    }
    const View v = view(prim.indices, what + " indices");
    SL_CHECK(v.components == 1, "gltf: '", path_, "' ", what, " index accessor is not SCALAR");
    idx.resize(v.count);
    for (size_t i = 0; i < v.count; ++i) {
      const unsigned char* p = v.data + i * v.stride;
      uint32_t x;
      switch (v.component_type) {
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: x = p[0]; break;
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: { uint16_t s; std::memcpy(&s, p, 2); x = s; break; }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: std::memcpy(&x, p, 4); break;
        default:
          fail("gltf: '", path_, "' ", what, " indices have component type ", v.component_type,
               ", expected an unsigned integer type");
      }
      SL_CHECK(x < vertex_count, "gltf: '", path_, "' ", what, " index ", i, " is ", x,
               ", out of range for ", vertex_count, " vertices");
      idx[i] = x;
    }
    return idx;
  }

  std::vector<glm::uvec3> assemble(int mode, const std::vector<uint32_t>& idx, const std::string& what) const {
    std::vector<glm::uvec3> tris;
    const size_t n = idx.size();
    if (mode == TINYGLTF_MODE_TRIANGLES) {
      SL_CHECK(n % 3 == 0, "gltf: '", path_, "' ", what, " has ", n, " indices, not a multiple of 3");
      for (size_t i = 0; i + 2 < n; i += 3) tris.emplace_back(idx[i], idx[i + 1], idx[i + 2]);
    } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
      // Odd triangles swap their first two vertices to keep a consistent winding (glTF 2.0 §3.7.2.1).
      for (size_t i = 0; i + 2 < n; ++i)
        tris.push_back(i % 2 == 0 ? glm::uvec3(idx[i], idx[i + 1], idx[i + 2]) : glm::uvec3(idx[i + 1], idx[i], idx[i + 2]));
    } else if (mode == TINYGLTF_MODE_TRIANGLE_FAN) {
      for (size_t i = 1; i + 1 < n; ++i) tris.emplace_back(idx[i], idx[i + 1], idx[0]);
    } else {
      fail("gltf: '", path_, "' ", what, " has primitive mode ", mode_name(mode), " (", mode,
           "), only triangles are supported");
    }
    return tris;
  }

  void add_primitive(const tinygltf::Primitive& prim, const glm::dmat4& world, int mesh_index, size_t prim_index) {
    const std::string what = cat("mesh ", mesh_index, " primitive ", prim_index);
    for (const char* ext : kCompressionExtensions)
      SL_CHECK(!prim.extensions.count(ext), "gltf: '", path_, "' ", what, " uses ", ext,
               ": compressed geometry is not supported");
    const int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
    if (mode < TINYGLTF_MODE_TRIANGLES) assemble(mode, {}, what);  // throws, naming the mode
    const auto pos_it = prim.attributes.find("POSITION");
    SL_CHECK(pos_it != prim.attributes.end(), "gltf: '", path_, "' ", what, " has no POSITION attribute");
    const View pos = view(pos_it->second, what + " POSITION");
    require(pos, 3, true, what + " POSITION", pos_it->second);

    Mesh part;
    part.positions.resize(pos.count);
    for (size_t i = 0; i < pos.count; ++i) {
      const glm::dvec4 p = world * glm::dvec4(component(pos, i, 0), component(pos, i, 1), component(pos, i, 2), 1.0);
      part.positions[i] = glm::vec3(p);
      const glm::vec3& q = part.positions[i];
      SL_CHECK(std::isfinite(q.x) && std::isfinite(q.y) && std::isfinite(q.z), "gltf: '", path_, "' ", what,
               " POSITION ", i, " is not finite (", q.x, ", ", q.y, ", ", q.z, ")");
    }
    const bool mirrored = glm::determinant(glm::dmat3(world)) < 0.0;
    part.triangles = assemble(mode, read_indices(prim, pos.count, what), what);
    if (mirrored)
      for (auto& t : part.triangles) std::swap(t.y, t.z);

    const auto nrm_it = prim.attributes.find("NORMAL");
    if (nrm_it != prim.attributes.end()) {
      const View nrm = view(nrm_it->second, what + " NORMAL");
      require(nrm, 3, true, what + " NORMAL", nrm_it->second);
      SL_CHECK(nrm.count == pos.count, "gltf: '", path_, "' ", what, " NORMAL has ", nrm.count,
               " entries but POSITION has ", pos.count);
      const glm::dmat3 normal_matrix = glm::transpose(glm::inverse(glm::dmat3(world)));
      part.normals.resize(nrm.count);
      for (size_t i = 0; i < nrm.count; ++i) {
        glm::vec3 n(normal_matrix * glm::dvec3(component(nrm, i, 0), component(nrm, i, 1), component(nrm, i, 2)));
        const float len = glm::length(n);
        part.normals[i] = len > 0.0f && std::isfinite(len) ? n / len : glm::vec3(0.0f, 1.0f, 0.0f);
      }
    } else {
      part.compute_vertex_normals();
    }
    const auto uv_it = prim.attributes.find("TEXCOORD_0");
    if (uv_it != prim.attributes.end()) {
      const View uv = view(uv_it->second, what + " TEXCOORD_0");
      require(uv, 2, false, what + " TEXCOORD_0", uv_it->second);
      SL_CHECK(uv.count == pos.count, "gltf: '", path_, "' ", what, " TEXCOORD_0 has ", uv.count,
               " entries but POSITION has ", pos.count);
      part.uvs.resize(uv.count);
      for (size_t i = 0; i < uv.count; ++i) part.uvs[i] = glm::vec2(component(uv, i, 0), component(uv, i, 1));
    }
    part.materials.push_back(material(prim.material));
    part.material_ids.assign(part.triangles.size(), 0);
    const uint32_t before = static_cast<uint32_t>(out_.materials.size());
    out_.append(part);
    // Share one Material per glTF material instead of one per primitive.
    const uint32_t shared = material_slot(prim.material, before);
    if (shared != before) {
      out_.materials.pop_back();
      std::fill(out_.material_ids.end() - static_cast<std::ptrdiff_t>(part.triangles.size()), out_.material_ids.end(),
                shared);
    }
  }

  uint32_t material_slot(int gltf_material, uint32_t candidate) {
    auto [it, inserted] = slot_of_material_.emplace(gltf_material, candidate);
    return it->second;
  }

  Material material(int index) {
    Material mat;
    if (index < 0) {
      mat.name = "default";
      return mat;
    }
    SL_CHECK(index < static_cast<int>(m_.materials.size()), "gltf: '", path_, "' references material ", index,
             " but has ", m_.materials.size(), " materials");
    const auto& g = m_.materials[index];
    const auto& pbr = g.pbrMetallicRoughness;
    mat.name = g.name;
    if (pbr.baseColorFactor.size() == 4)
      mat.base_color_factor = glm::vec4(pbr.baseColorFactor[0], pbr.baseColorFactor[1], pbr.baseColorFactor[2],
                                        pbr.baseColorFactor[3]);
    mat.metallic = static_cast<float>(std::clamp(pbr.metallicFactor, 0.0, 1.0));
    mat.roughness = static_cast<float>(std::clamp(pbr.roughnessFactor, 0.0, 1.0));
    if (pbr.baseColorTexture.index >= 0) mat.base_color_texture = texture(pbr.baseColorTexture.index);
    const auto cc = g.extensions.find("KHR_materials_clearcoat");
    if (cc != g.extensions.end() && cc->second.IsObject()) {
      auto number = [&](const char* key, double fallback) {
        return cc->second.Has(key) && cc->second.Get(key).IsNumber() ? cc->second.Get(key).GetNumberAsDouble()
                                                                       : fallback;
      };
      mat.clearcoat = static_cast<float>(std::clamp(number("clearcoatFactor", 0.0), 0.0, 1.0));
      mat.clearcoat_roughness = static_cast<float>(std::clamp(number("clearcoatRoughnessFactor", 0.0), 0.0, 1.0));
    }
    return mat;
  }

  std::shared_ptr<const Texture> texture(int texture_index) {
    SL_CHECK(texture_index < static_cast<int>(m_.textures.size()), "gltf: '", path_, "' references texture ",
             texture_index, " but has ", m_.textures.size());
    const int source = m_.textures[texture_index].source;
    if (source < 0 || source >= static_cast<int>(m_.images.size())) return nullptr;  // e.g. an extension-only image
    if (auto it = textures_.find(source); it != textures_.end()) return it->second;
    const auto& img = m_.images[source];
    const int channels = img.component;
    const int bytes = img.bits / 8;
    SL_CHECK(img.width > 0 && img.height > 0 && channels >= 1 && channels <= 4 && (bytes == 1 || bytes == 2) &&
                 img.image.size() >= static_cast<size_t>(img.width) * img.height * channels * bytes,
             "gltf: '", path_, "' image ", source, " ('", img.name, img.uri, "') could not be decoded (", img.width,
             "x", img.height, "x", channels, ", ", img.bits, " bits)");
    auto tex = std::make_shared<Texture>();
    tex->width = img.width;
    tex->height = img.height;
    tex->rgba.resize(static_cast<size_t>(img.width) * img.height * 4);
    const size_t n = static_cast<size_t>(img.width) * img.height;
    for (size_t i = 0; i < n; ++i) {
      float c[4] = {0, 0, 0, 1};
      for (int k = 0; k < channels; ++k) {
        const unsigned char* p = &img.image[(i * channels + k) * bytes];
        c[k] = bytes == 1 ? p[0] / 255.0f : (p[0] | (p[1] << 8)) / 65535.0f;
      }
      if (channels <= 2) {  // grey or grey+alpha
        c[3] = channels == 2 ? c[1] : 1.0f;
        c[1] = c[2] = c[0];
      }
      for (int k = 0; k < 3; ++k) tex->rgba[i * 4 + k] = srgb_to_linear(c[k]);  // base colour is sRGB (glTF §3.9.2)
      tex->rgba[i * 4 + 3] = c[3];
    }
    textures_[source] = tex;
    return tex;
  }

  const tinygltf::Model& m_;
  std::string path_;
  Mesh out_;
  std::set<int> on_path_, visited_;
  std::map<int, uint32_t> slot_of_material_;
  std::map<int, std::shared_ptr<const Texture>> textures_;
};

}  // namespace

Mesh load_gltf(const std::string& path) {
  const std::vector<unsigned char> bytes = read_bytes(path);
  tinygltf::Model model;
  tinygltf::TinyGLTF parser;
  std::string err, warn;
  bool ok = false;
  const bool is_glb = bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0;
  try {
    if (is_glb) {
      check_glb_container(bytes, path);
      reject_compression(reinterpret_cast<const char*>(bytes.data()) + 20, read_u32(&bytes[12]), path);
      ok = parser.LoadBinaryFromMemory(&model, &err, &warn, bytes.data(), static_cast<unsigned int>(bytes.size()),
                                       directory_of(path));
    } else {
      SL_CHECK(!bytes.empty(), "gltf: '", path, "' is empty");
      reject_compression(reinterpret_cast<const char*>(bytes.data()), bytes.size(), path);
      ok = parser.LoadASCIIFromString(&model, &err, &warn, reinterpret_cast<const char*>(bytes.data()),
                                      static_cast<unsigned int>(bytes.size()), directory_of(path));
    }
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    fail("gltf: '", path, "' could not be parsed: ", e.what());
  }
  if (!ok) {
    while (!err.empty() && (err.back() == '\n' || err.back() == '\r')) err.pop_back();
    for (char& c : err)
      if (c == '\n') c = ' ';
    fail("gltf: '", path, "' could not be parsed: ", err.empty() ? std::string("unknown error") : err);
  }
  return Importer(model, path).run();
}

}  // namespace sl::render
