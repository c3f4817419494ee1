// Builders of small hostile files for the hardening tests of issue 17.
#pragma once
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>

#include <unistd.h>

namespace sl::test {

// A safetensors file: 8-byte little-endian header length, the header, `data_bytes` zero bytes.
inline std::string safetensors_bytes(const std::string& header, size_t data_bytes) {
  std::string out(8, '\0');
  const uint64_t n = header.size();
  std::memcpy(out.data(), &n, 8);
  return out + header + std::string(data_bytes, '\0');
}

// A .glb: 12-byte header, a JSON chunk padded with spaces, a BIN chunk padded with zeros.
inline std::string glb_bytes(std::string json, std::string bin) {
  json.append((4 - json.size() % 4) % 4, ' ');
  bin.append((4 - bin.size() % 4) % 4, '\0');
  auto u32 = [](uint32_t v) { return std::string(reinterpret_cast<const char*>(&v), 4); };
  const uint32_t length = static_cast<uint32_t>(12 + 8 + json.size() + 8 + bin.size());
  return "glTF" + u32(2) + u32(length) + u32(static_cast<uint32_t>(json.size())) + u32(0x4E4F534Au) + json +
         u32(static_cast<uint32_t>(bin.size())) + u32(0x004E4942u) + bin;
}

// One triangle's POSITION accessor over a 36-byte BIN chunk, with the accessor's count and the
// bufferView's byteStride given as JSON number text (so they can exceed 64-bit arithmetic).
inline std::string triangle_glb(const std::string& count, const std::string& byte_stride,
                                const std::string& accessor_offset = "0") {
  const std::string json =
      R"({"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],)"
      R"("meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],)"
      R"("buffers":[{"byteLength":36}],"bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":36,"byteStride":)" +
      byte_stride + R"(}],"accessors":[{"bufferView":0,"byteOffset":)" + accessor_offset +
      R"(,"componentType":5126,"count":)" + count + R"(,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}]})";
  const float p[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  return glb_bytes(json, std::string(reinterpret_cast<const char*>(p), sizeof(p)));
}

// A single-part, uncompressed OpenEXR header with one FLOAT channel "Y" whose dataWindow is
// (0, 0) - (x_max, y_max), followed by no pixel data at all (not even the line-offset table).
inline std::string exr_declaring(int32_t x_max, int32_t y_max) {
  auto i32 = [](int32_t v) { return std::string(reinterpret_cast<const char*>(&v), 4); };
  auto f32 = [](float v) { return std::string(reinterpret_cast<const char*>(&v), 4); };
  auto attribute = [&](const std::string& name, const std::string& type, const std::string& value) {
    return name + '\0' + type + '\0' + i32(static_cast<int32_t>(value.size())) + value;
  };
  const std::string channel = std::string("Y\0", 2) + i32(2) + std::string(4, '\0') + i32(1) + i32(1);
  const std::string window = i32(0) + i32(0) + i32(x_max) + i32(y_max);
  return std::string("\x76\x2f\x31\x01", 4) + i32(2) + attribute("channels", "chlist", channel + '\0') +
         attribute("compression", "compression", std::string(1, '\0')) + attribute("dataWindow", "box2i", window) +
         attribute("displayWindow", "box2i", window) + attribute("lineOrder", "lineOrder", std::string(1, '\0')) +
         attribute("pixelAspectRatio", "float", f32(1.0f)) +
         attribute("screenWindowCenter", "v2f", f32(0.0f) + f32(0.0f)) +
         attribute("screenWindowWidth", "float", f32(1.0f)) + '\0';
}

inline std::string write_temp(const std::string& name, const std::string& bytes) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("streetlight-hostile-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string path = (dir / name).string();
  std::ofstream(path, std::ios::binary) << bytes;
  return path;
}

}  // namespace sl::test
