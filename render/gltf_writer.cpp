#include "render/gltf_writer.h"

#include <cstdio>
#include <cstring>
#include <fstream>

#include <nlohmann/json.hpp>

#include "util/error.h"
#include "util/file.h"

namespace sl::render {
namespace {

using json = nlohmann::json;

constexpr int kFloat = 5126, kUnsignedInt = 5125;
constexpr int kArrayBuffer = 34962, kElementArrayBuffer = 34963;

void pad_to_4(std::vector<unsigned char>& b, unsigned char fill) {
  while (b.size() % 4) b.push_back(fill);
}

template <class T>
size_t append_bytes(std::vector<unsigned char>& bin, const std::vector<T>& v) {
  pad_to_4(bin, 0);
  const size_t at = bin.size();
  bin.resize(at + v.size() * sizeof(T));
  if (!v.empty()) std::memcpy(bin.data() + at, v.data(), v.size() * sizeof(T));
  return at;
}

void put_u32(std::vector<unsigned char>& out, uint32_t x) {
  for (int k = 0; k < 4; ++k) out.push_back(static_cast<unsigned char>(x >> (8 * k)));
}

}  // namespace

void write_glb(const Mesh& mesh, const std::string& path) {
  mesh.validate("write_glb: mesh for '" + path + "'");
  std::vector<unsigned char> bin;
  json doc;
  doc["asset"] = {{"version", "2.0"}, {"generator", "streetlight"}};
  json buffer_views = json::array(), accessors = json::array();

  auto add_view = [&](size_t offset, size_t length, int target) {
    buffer_views.push_back({{"buffer", 0}, {"byteOffset", offset}, {"byteLength", length}, {"target", target}});
    return buffer_views.size() - 1;
  };
  auto add_accessor = [&](size_t view, int component_type, size_t count, const char* type) {
    accessors.push_back({{"bufferView", view}, {"componentType", component_type}, {"count", count}, {"type", type}});
    return accessors.size() - 1;
  };

  json attributes;
  const size_t nv = mesh.positions.size();
  if (nv > 0) {
    const size_t pos_view = add_view(append_bytes(bin, mesh.positions), nv * 12, kArrayBuffer);
    const size_t pos = add_accessor(pos_view, kFloat, nv, "VEC3");
    const Bounds3 b = [&] {
      Bounds3 all;
      for (const auto& p : mesh.positions) all.extend(p);
      return all;
    }();
    accessors[pos]["min"] = {b.lo.x, b.lo.y, b.lo.z};  // required for POSITION (glTF §5.1.1)
    accessors[pos]["max"] = {b.hi.x, b.hi.y, b.hi.z};
    attributes["POSITION"] = pos;
    if (!mesh.normals.empty())
      attributes["NORMAL"] =
          add_accessor(add_view(append_bytes(bin, mesh.normals), nv * 12, kArrayBuffer), kFloat, nv, "VEC3");
    if (!mesh.uvs.empty())
      attributes["TEXCOORD_0"] =
          add_accessor(add_view(append_bytes(bin, mesh.uvs), nv * 8, kArrayBuffer), kFloat, nv, "VEC2");
  }

  bool uses_clearcoat = false;
  json materials = json::array(), primitives = json::array();
  for (size_t m = 0; m < mesh.materials.size(); ++m) {
    std::vector<uint32_t> indices;
    for (size_t t = 0; t < mesh.triangles.size(); ++t)
      if (mesh.material_ids[t] == m)
        for (int k = 0; k < 3; ++k) indices.push_back(mesh.triangles[t][k]);
    if (indices.empty()) continue;
    const Material& mat = mesh.materials[m];
    const glm::vec4& c = mat.base_color_factor;
    json jm = {{"pbrMetallicRoughness",
                {{"baseColorFactor", {c.r, c.g, c.b, c.a}},
                 {"metallicFactor", mat.metallic},
                 {"roughnessFactor", mat.roughness}}}};
    if (!mat.name.empty()) jm["name"] = mat.name;
    if (mat.clearcoat > 0.0f) {
      jm["extensions"]["KHR_materials_clearcoat"] = {{"clearcoatFactor", mat.clearcoat},
                                                     {"clearcoatRoughnessFactor", mat.clearcoat_roughness}};
      uses_clearcoat = true;
    }
    materials.push_back(jm);
    const size_t view = add_view(append_bytes(bin, indices), indices.size() * 4, kElementArrayBuffer);
    primitives.push_back({{"attributes", attributes},
                          {"indices", add_accessor(view, kUnsignedInt, indices.size(), "SCALAR")},
                          {"material", materials.size() - 1},
                          {"mode", 4}});
  }
  pad_to_4(bin, 0);

  doc["scene"] = 0;
  doc["scenes"] = json::array({{{"nodes", json::array({0})}}});
  if (!primitives.empty()) {
    doc["nodes"] = json::array({{{"mesh", 0}}});
    doc["meshes"] = json::array({{{"primitives", primitives}}});
    doc["materials"] = materials;
    doc["accessors"] = accessors;
    doc["bufferViews"] = buffer_views;
    doc["buffers"] = json::array({{{"byteLength", bin.size()}}});
  } else {
    doc["nodes"] = json::array({json::object()});
  }
  if (uses_clearcoat) doc["extensionsUsed"] = json::array({"KHR_materials_clearcoat"});

  std::string text = doc.dump();
  std::vector<unsigned char> json_chunk(text.begin(), text.end());
  pad_to_4(json_chunk, ' ');  // the JSON chunk pads with spaces (GLB §4.4.3.1)
  const bool has_bin = !primitives.empty();
  const uint64_t total = 12 + 8 + json_chunk.size() + (has_bin ? 8 + bin.size() : 0);
  SL_CHECK(total < (uint64_t{1} << 32), "write_glb: '", path, "' would be ", total, " bytes, over the 4 GiB GLB limit");
  std::vector<unsigned char> out;
  out.reserve(total);
  put_u32(out, 0x46546C67u);  // "glTF"
  put_u32(out, 2);
  put_u32(out, static_cast<uint32_t>(total));
  put_u32(out, static_cast<uint32_t>(json_chunk.size()));
  put_u32(out, 0x4E4F534Au);  // "JSON"
  out.insert(out.end(), json_chunk.begin(), json_chunk.end());
  if (has_bin) {
    put_u32(out, static_cast<uint32_t>(bin.size()));
    put_u32(out, 0x004E4942u);  // "BIN\0"
    out.insert(out.end(), bin.begin(), bin.end());
  }

  write_file_atomic(path, std::string_view(reinterpret_cast<const char*>(out.data()), out.size()));
}

}  // namespace sl::render
