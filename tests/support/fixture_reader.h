// A minimal safetensors reader for test fixtures (F32 / F64 only). Tests use it instead of the
// checkpoint module so that the fixtures check the ops independently of the checkpoint code.
#pragma once
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <map>
#include <nlohmann/json.hpp>
#include <string>

#include "autodiff/tensor.h"

namespace sl::test {

struct Fixture {
  std::map<std::string, Tensor> tensors;
  std::map<std::string, std::string> metadata;
  bool has(const std::string& name) const { return tensors.count(name) != 0; }
  const Tensor& at(const std::string& name) const {
    auto it = tensors.find(name);
    SL_CHECK(it != tensors.end(), "fixture: no tensor '", name, "'");
    return it->second;
  }
};

inline Fixture read_fixture(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  SL_CHECK(in, "fixture: cannot open ", path);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  SL_CHECK(bytes.size() >= 8, "fixture: ", path, " is too short");
  uint64_t n = 0;
  for (int i = 7; i >= 0; --i) n = (n << 8) | static_cast<uint8_t>(bytes[static_cast<size_t>(i)]);
  SL_CHECK(n <= bytes.size() - 8, "fixture: ", path, " header length ", n, " exceeds the file");
  const nlohmann::json header = nlohmann::json::parse(bytes.substr(8, n));
  const size_t data_start = 8 + n;
  Fixture f;
  for (const auto& [name, entry] : header.items()) {
    if (name == "__metadata__") {
      for (const auto& [k, v] : entry.items()) f.metadata[k] = v.get<std::string>();
      continue;
    }
    const std::string dtype = entry.at("dtype").get<std::string>();
    SL_CHECK(dtype == "F32" || dtype == "F64", "fixture: ", path, ": tensor ", name, " has dtype ", dtype);
    const Shape shape = entry.at("shape").get<Shape>();
    const auto offsets = entry.at("data_offsets").get<std::vector<uint64_t>>();
    const DType dt = dtype == "F32" ? DType::F32 : DType::F64;
    Tensor t = Tensor::empty(shape, dt);
    const uint64_t size = static_cast<uint64_t>(t.numel()) * dtype_size(dt);
    SL_CHECK(offsets.size() == 2 && offsets[1] - offsets[0] == size && data_start + offsets[1] <= bytes.size(),
             "fixture: ", path, ": tensor ", name, " has bad data_offsets");
    if (size) std::memcpy(t.raw_data(), bytes.data() + data_start + offsets[0], size);  // little-endian host
    f.tensors[name] = t;
  }
  return f;
}

}  // namespace sl::test
