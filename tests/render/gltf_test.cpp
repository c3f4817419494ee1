// glTF import/export: round trips, node transforms, and clean errors on damaged files.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>

#include "render/gltf_loader.h"
#include "render/gltf_writer.h"
#include "util/error.h"

using sl::render::Texture;

namespace sl::test {

namespace {

namespace fs = std::filesystem;

std::string temp_path(const std::string& name) {
  const fs::path dir = fs::path(STREETLIGHT_BINARY_DIR) / "test_tmp" / "render";
  fs::create_directories(dir);
  return (dir / name).string();
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

std::string read_all(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// Base64 of little-endian float32 / uint16 data, for hand-written .gltf files.
std::string base64(const std::string& bytes) {
  static const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const unsigned v = (uint8_t(bytes[i]) << 16) | (uint8_t(bytes[i + 1]) << 8) | uint8_t(bytes[i + 2]);
    for (int s = 18; s >= 0; s -= 6) out += k[(v >> s) & 63];
  }
  if (i + 1 == bytes.size()) {
    const unsigned v = uint8_t(bytes[i]) << 16;
    out += k[(v >> 18) & 63], out += k[(v >> 12) & 63], out += "==";
  } else if (i + 2 == bytes.size()) {
    const unsigned v = (uint8_t(bytes[i]) << 16) | (uint8_t(bytes[i + 1]) << 8);
    out += k[(v >> 18) & 63], out += k[(v >> 12) & 63], out += k[(v >> 6) & 63], out += '=';
  }
  return out;
}

template <class T>
std::string raw(std::initializer_list<T> v) {
  std::string s(v.size() * sizeof(T), '\0');
  std::memcpy(s.data(), std::data(v), s.size());
  return s;
}

// One triangle (3 float positions + 3 uint16 indices, padded) with a node transform and a
// primitive snippet that tests can vary.
std::string one_triangle_gltf(const std::string& node_extra, const std::string& index_values_override = "",
                              const std::string& prim_extra = "", const std::string& top_extra = "",
                              float x0 = 0.0f) {
  std::string bin = raw<float>({x0, 0, 0, 1, 0, 0, 0, 1, 0});
  bin += index_values_override.empty() ? raw<uint16_t>({0, 1, 2, 0}) : index_values_override;
  const std::string uri = "data:application/octet-stream;base64," + base64(bin);
  return R"({"asset":{"version":"2.0"},)" + top_extra + R"("scene":0,"scenes":[{"nodes":[0]}],
  "nodes":[{"mesh":0)" + node_extra + R"(}],
  "meshes":[{"primitives":[{"attributes":{"POSITION":0},"indices":1)" + prim_extra + R"(}]}],
  "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"},
               {"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}],
  "bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":36},{"buffer":0,"byteOffset":36,"byteLength":8}],
  "buffers":[{"byteLength":44,"uri":")" + uri + R"("}]})";
}

void expect_error_mentions(const std::string& path, const std::string& needle) {
  try {
    sl::render::load_gltf(path);
    ADD_FAILURE() << "expected sl::Error for " << path;
  } catch (const sl::Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(needle), std::string::npos) << msg;
    EXPECT_NE(msg.find(path), std::string::npos) << "message should name the file: " << msg;
  }
}

sl::render::Mesh two_material_mesh() {
  sl::render::Mesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  m.triangles = {{0, 1, 2}, {0, 2, 3}, {0, 3, 1}};
  m.material_ids = {0, 1, 0};
  m.materials.resize(2);
  m.materials[0].base_color_factor = glm::vec4(0.8f, 0.1f, 0.1f, 1.0f);
  m.materials[0].metallic = 0.25f;
  m.materials[1].roughness = 0.3f;
  m.materials[1].clearcoat = 1.0f;
  m.materials[1].clearcoat_roughness = 0.05f;
  m.compute_vertex_normals();
  return m;
}

TEST(Gltf, WrittenGlbLoadsBackWithSameGeometryAndMaterials) {
  const sl::render::Mesh m = two_material_mesh();
  const std::string path = temp_path("roundtrip.glb");
  sl::render::write_glb(m, path);
  const sl::render::Mesh r = sl::render::load_gltf(path);
  ASSERT_EQ(r.triangle_count(), 3u);
  ASSERT_EQ(r.materials.size(), 2u);
  // Primitives are grouped by material: material 0's two triangles come first.
  EXPECT_EQ(r.material_ids, (std::vector<uint32_t>{0, 0, 1}));
  auto corners = [](const sl::render::Mesh& mesh, size_t t) {
    return std::vector<glm::vec3>{mesh.positions[mesh.triangles[t].x], mesh.positions[mesh.triangles[t].y],
                                  mesh.positions[mesh.triangles[t].z]};
  };
  EXPECT_EQ(corners(r, 0), corners(m, 0));
  EXPECT_EQ(corners(r, 1), corners(m, 2));
  EXPECT_EQ(corners(r, 2), corners(m, 1));
  EXPECT_FLOAT_EQ(r.materials[0].metallic, 0.25f);
  EXPECT_FLOAT_EQ(r.materials[0].base_color_factor.r, 0.8f);
  EXPECT_FLOAT_EQ(r.materials[1].roughness, 0.3f);
  EXPECT_FLOAT_EQ(r.materials[1].clearcoat, 1.0f);
  EXPECT_FLOAT_EQ(r.materials[1].clearcoat_roughness, 0.05f);
  ASSERT_EQ(r.normals.size(), r.positions.size());
  EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));
}

TEST(Gltf, EmptyMeshRoundTripsToEmptyMesh) {
  const std::string path = temp_path("empty.glb");
  sl::render::write_glb(sl::render::Mesh{}, path);
  const sl::render::Mesh r = sl::render::load_gltf(path);
  EXPECT_EQ(r.triangle_count(), 0u);
  EXPECT_TRUE(r.bounds().empty());
}

TEST(Gltf, NodeTranslationRotationScaleAreAppliedInWorldSpace) {
  // T·R·S with S = 2, R = 90° about +Y, T = (10, 0, 0): (1,0,0) -> (2,0,0) -> (0,0,-2) -> (10,0,-2).
  const float s = std::sqrt(0.5f);
  const std::string path = temp_path("trs.gltf");
  write_text(path, one_triangle_gltf(R"(,"translation":[10,0,0],"rotation":[0,)" + std::to_string(s) + ",0," +
                                     std::to_string(s) + R"(],"scale":[2,2,2])"));
  const sl::render::Mesh m = sl::render::load_gltf(path);
  ASSERT_EQ(m.triangle_count(), 1u);
  const glm::vec3 p1 = m.positions[m.triangles[0].y];
  EXPECT_NEAR(p1.x, 10.0f, 1e-5f);
  EXPECT_NEAR(p1.y, 0.0f, 1e-5f);
  EXPECT_NEAR(p1.z, -2.0f, 1e-5f);
}

TEST(Gltf, NodeMatrixIsColumnMajorAndMirroringKeepsOutwardNormals) {
  // Mirror x and translate by (0, 5, 0); the face normal of the input is +Z and must stay +Z.
  const std::string path = temp_path("matrix.gltf");
  write_text(path, one_triangle_gltf(R"(,"matrix":[-1,0,0,0, 0,1,0,0, 0,0,1,0, 0,5,0,1])"));
  const sl::render::Mesh m = sl::render::load_gltf(path);
  const glm::uvec3 t = m.triangles[0];
  EXPECT_NEAR(m.positions[t.x].y, 5.0f, 1e-6f);
  const glm::vec3 n = glm::cross(m.positions[t.y] - m.positions[t.x], m.positions[t.z] - m.positions[t.x]);
  EXPECT_GT(n.z, 0.0f);
  EXPECT_NEAR(m.normals[t.x].z, 1.0f, 1e-6f);
}

TEST(Gltf, OutOfRangeIndexFailsNamingTheIndex) {
  const std::string path = temp_path("bad_index.gltf");
  write_text(path, one_triangle_gltf("", raw<uint16_t>({0, 1, 7, 0})));
  expect_error_mentions(path, "out of range");
}

TEST(Gltf, NanPositionFailsNamingThePosition) {
  const std::string path = temp_path("nan.gltf");
  write_text(path, one_triangle_gltf("", "", "", "", std::nanf("")));
  expect_error_mentions(path, "not finite");
}

TEST(Gltf, LinePrimitiveModeIsRejected) {
  const std::string path = temp_path("lines.gltf");
  write_text(path, one_triangle_gltf("", "", R"(,"mode":1)"));
  expect_error_mentions(path, "LINES");
}

TEST(Gltf, DracoCompressionIsRejected) {
  const std::string path = temp_path("draco.gltf");
  write_text(path, one_triangle_gltf("", "", "", R"("extensionsUsed":["KHR_draco_mesh_compression"],)"));
  expect_error_mentions(path, "KHR_draco_mesh_compression");
}

TEST(Gltf, MeshoptCompressionIsRejected) {
  const std::string path = temp_path("meshopt.gltf");
  write_text(path, one_triangle_gltf("", "", "", R"("extensionsRequired":["EXT_meshopt_compression"],"extensionsUsed":["EXT_meshopt_compression"],)"));
  expect_error_mentions(path, "EXT_meshopt_compression");
}

// What a compressing exporter actually writes: the accessors have no bufferView, the primitive
// points at a compressed bufferView, and the buffer is shorter than declared. tinygltf alone
// fails here with "Invalid byteLength"; the user must instead hear which extension it is.
std::string compressed_gltf(const std::string& ext, bool required) {
  const std::string primitive_ext = ext == "KHR_draco_mesh_compression"
                                        ? R"(,"extensions":{"KHR_draco_mesh_compression":{"bufferView":0,"attributes":{"POSITION":0}}})"
                                        : "";
  const std::string view_ext = ext == "EXT_meshopt_compression"
                                   ? R"(,"extensions":{"EXT_meshopt_compression":{"buffer":0,"byteLength":36,"byteStride":12,"count":3,"mode":"ATTRIBUTES"}})"
                                   : "";
  return std::string(R"({"asset":{"version":"2.0"},"extensionsUsed":[")") + ext + R"("],)" +
         (required ? R"("extensionsRequired":[")" + ext + R"("],)" : std::string()) +
         R"("buffers":[{"byteLength":4096,"uri":"data:application/octet-stream;base64,AAAA"}],)"
         R"("bufferViews":[{"buffer":0,"byteLength":4096)" + view_ext + R"(}],)"
         R"("accessors":[{"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}],)"
         R"("meshes":[{"primitives":[{"attributes":{"POSITION":0})" + primitive_ext + R"(}]}],)"
         R"("nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}]})";
}

std::string glb_of(const std::string& json) {
  std::string j = json;
  while (j.size() % 4) j += ' ';
  auto u32 = [](uint32_t v) { return std::string(reinterpret_cast<const char*>(&v), 4); };
  return "glTF" + u32(2) + u32(uint32_t(12 + 8 + j.size())) + u32(uint32_t(j.size())) + u32(0x4E4F534Au) + j;
}

void expect_unsupported_extension(const std::string& path, const std::string& ext) {
  try {
    sl::render::load_gltf(path);
    ADD_FAILURE() << path << " loaded";
  } catch (const sl::Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(ext), std::string::npos) << msg;
    EXPECT_NE(msg.find("not supported"), std::string::npos) << msg;
    EXPECT_EQ(msg.find("byteLength"), std::string::npos) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  }
}

TEST(Gltf, CompressedGeometryNamesTheExtensionInGltfAndGlb) {
  for (const std::string ext : {"KHR_draco_mesh_compression", "EXT_meshopt_compression"})
    for (bool required : {true, false}) {  // false: the extension is only in extensionsUsed
      const std::string tag = ext.substr(0, 8) + (required ? "_req" : "_used");
      const std::string gltf = temp_path("compressed_" + tag + ".gltf"), glb = temp_path("compressed_" + tag + ".glb");
      write_text(gltf, compressed_gltf(ext, required));
      write_text(glb, glb_of(compressed_gltf(ext, required)));
      expect_unsupported_extension(gltf, ext);
      expect_unsupported_extension(glb, ext);
    }
}

TEST(Gltf, MissingExternalBufferFails) {
  const std::string path = temp_path("missing_buffer.gltf");
  std::string text = one_triangle_gltf("");
  const size_t at = text.find("data:application");
  text.replace(at, text.find('"', at) - at, "no_such_buffer.bin");
  write_text(path, text);
  expect_error_mentions(path, "");
}

TEST(Gltf, AccessorPastBufferEndFails) {
  const std::string path = temp_path("short_view.gltf");
  std::string text = one_triangle_gltf("");
  const size_t at = text.find(R"("count":3,"type":"VEC3")");
  text.replace(at, 9, R"("count":9)");
  write_text(path, text);
  expect_error_mentions(path, "reads past the end");
}

TEST(Gltf, MissingFileAndGarbageFailCleanly) {
  expect_error_mentions(temp_path("does_not_exist.glb"), "cannot open");
  const std::string garbage = temp_path("garbage.gltf");
  write_text(garbage, "{ this is not json");
  expect_error_mentions(garbage, "could not be parsed");
}

TEST(Gltf, EveryTruncationOfAGlbFailsCleanly) {
  const std::string full_path = temp_path("full.glb");
  sl::render::write_glb(two_material_mesh(), full_path);
  const std::string bytes = read_all(full_path);
  const std::string cut = temp_path("truncated.glb");
  for (size_t len = 0; len < bytes.size(); len += std::max<size_t>(1, bytes.size() / 97)) {
    write_text(cut, bytes.substr(0, len));
    EXPECT_THROW(sl::render::load_gltf(cut), sl::Error) << "length " << len;
  }
}

TEST(Gltf, CorruptedGlbBytesNeverCrash) {
  const std::string full_path = temp_path("full2.glb");
  sl::render::write_glb(two_material_mesh(), full_path);
  const std::string bytes = read_all(full_path);
  const std::string bad = temp_path("corrupt.glb");
  uint64_t state = 12345;
  for (int trial = 0; trial < 200; ++trial) {
    std::string b = bytes;
    for (int k = 0; k < 4; ++k) {
      state = state * 6364136223846793005ULL + 1442695040888963407ULL;
      b[(state >> 33) % b.size()] = static_cast<char>(state >> 13);
    }
    write_text(bad, b);
    try {
      const sl::render::Mesh m = sl::render::load_gltf(bad);
      m.validate();  // a file that still parses must give a valid mesh
    } catch (const sl::Error&) {
    }
  }
}

TEST(Gltf, RealModelsLoadWithTexturesAndFiniteGeometry) {
  const std::string dir = std::string(STREETLIGHT_SHARED_DATA) + "/models";
  if (!fs::exists(dir + "/CesiumMilkTruck.glb")) GTEST_SKIP() << "shared models not found in " << dir;
  const sl::render::Mesh truck = sl::render::load_gltf(dir + "/CesiumMilkTruck.glb");
  EXPECT_GT(truck.triangle_count(), 3000u);
  bool textured = false;
  for (const auto& m : truck.materials)
    if (m.base_color_texture) {
      textured = true;
      EXPECT_GT(m.base_color_texture->width, 0);
      const glm::vec4 c = m.base_color(glm::vec2(0.5f, 0.5f));
      EXPECT_TRUE(c.r >= 0.0f && c.r <= 1.0f && c.a >= 0.0f && c.a <= 1.0f);
    }
  EXPECT_TRUE(textured);
  const sl::render::Bounds3 b = truck.bounds();
  EXPECT_GT(b.extent().x, 1.0f);  // a truck a few metres long
  EXPECT_LT(b.extent().x, 20.0f);
  for (const char* name : {"Shadow_Tester.glb", "Shadow_Tester_2.glb", "Shadow_Tester_4.glb", "Wood_Tower.glb"}) {
    const sl::render::Mesh m = sl::render::load_gltf(dir + "/" + name);
    EXPECT_GT(m.triangle_count(), 0u) << name;
  }
}

TEST(Texture, SamplingIsBilinearWithRepeatWrapping) {
  sl::render::Texture t;
  t.width = 2, t.height = 1;
  t.rgba = {0, 0, 0, 1, 1, 1, 1, 1};
  EXPECT_FLOAT_EQ(t.sample({0.25f, 0.5f}).r, 0.0f);   // texel 0 centre
  EXPECT_FLOAT_EQ(t.sample({0.75f, 0.5f}).r, 1.0f);   // texel 1 centre
  EXPECT_FLOAT_EQ(t.sample({0.5f, 0.5f}).r, 0.5f);    // between them
  EXPECT_FLOAT_EQ(t.sample({0.0f, 0.5f}).r, 0.5f);    // wraps to texel 1
  EXPECT_FLOAT_EQ(t.sample({1.25f, 0.5f}).r, 0.0f);
  EXPECT_EQ(sl::render::Texture{}.sample({0.3f, 0.3f}), glm::vec4(1.0f));
}

}  // namespace

}  // namespace sl::test
