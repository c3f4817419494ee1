// The hardening tests of issue 17: hostile headers are refused with one clean sl::Error, before
// anything sized by the header is allocated. Each test fails when its protection is removed
// (checked by deleting the check: the loader then reads out of bounds, allocates the claimed
// size, or throws std::bad_alloc / std::length_error instead of sl::Error).
#include <gtest/gtest.h>

#include "nn/safetensors.h"
#include "render/gltf_loader.h"
#include "tests/fuzz/hostile_files.h"
#include "util/error.h"

namespace {

using sl::fuzz::test::glb_bytes;
using sl::fuzz::test::safetensors_bytes;
using sl::fuzz::test::triangle_glb;
using sl::fuzz::test::write_temp;

// Runs f and returns the sl::Error message; fails the test on success or on any other exception.
template <class F>
std::string clean_error(F&& f) {
  try {
    f();
  } catch (const sl::Error& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "not a clean sl::Error: " << typeid(e).name() << ": " << e.what();
    return "";
  }
  ADD_FAILURE() << "the hostile file was accepted";
  return "";
}

TEST(SafetensorsHostileHeader, TensorPastTheEndOfTheFileIsRefused) {
  // 12 floats claimed, 16 data bytes present.
  const std::string path = write_temp(
      "past_end.safetensors",
      safetensors_bytes(R"({"w":{"dtype":"F32","shape":[12],"data_offsets":[0,48]}})", 16));
  const std::string msg = clean_error([&] { sl::nn::read_safetensors(path); });
  EXPECT_NE(msg.find("'w'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("beyond the 16 data bytes"), std::string::npos) << msg;
}

TEST(SafetensorsHostileHeader, OverlappingTensorsAreRefused) {
  const std::string path = write_temp(
      "overlap.safetensors",
      safetensors_bytes(R"({"a":{"dtype":"F32","shape":[4],"data_offsets":[0,16]},)"
                        R"("b":{"dtype":"F32","shape":[4],"data_offsets":[8,24]}})",
                        24));
  const std::string msg = clean_error([&] { sl::nn::read_safetensors(path); });
  EXPECT_NE(msg.find("overlap"), std::string::npos) << msg;
}

TEST(SafetensorsHostileHeader, ShapeWhoseProductOverflowsInt64IsRefused) {
  // 2^32 · 2^32 · 4 bytes wraps to 0 in 64-bit arithmetic, which would match data_offsets [0, 0].
  const std::string path = write_temp(
      "overflow.safetensors",
      safetensors_bytes(R"({"w":{"dtype":"F32","shape":[4294967296,4294967296],"data_offsets":[0,0]}})", 8));
  const std::string msg = clean_error([&] { sl::nn::read_safetensors(path); });
  EXPECT_NE(msg.find("more than 2^62"), std::string::npos) << msg;
}

TEST(GltfHostileAccessor, CountTimesStrideOverflowIsRefused) {
  // count − 1 = 2^62 and stride 12: 12 · 2^62 = 3 · 2^64 wraps to 0 in 64-bit arithmetic, so an
  // unguarded bounds check passes and the importer sizes its arrays by 2^62 + 1 vertices.
  const std::string path = write_temp("overflow.glb", triangle_glb("4611686018427387905", "12"));
  const std::string msg = clean_error([&] { sl::load_gltf(path); });
  EXPECT_NE(msg.find("reads past the end of bufferView 0"), std::string::npos) << msg;
}

TEST(GltfHostileAccessor, AccessorOffsetNearTwoToTheSixtyFourIsRefused) {
  // byteOffset 2^64 − 8 wraps the sum offset + stride·(count − 1) + element back into range.
  const std::string path = write_temp("offset.glb", triangle_glb("3", "12", "18446744073709551608"));
  const std::string msg = clean_error([&] { sl::load_gltf(path); });
  EXPECT_NE(msg.find("reads past the end of bufferView 0"), std::string::npos) << msg;
}

TEST(GltfHostileAccessor, ValidTriangleStillLoads) {
  const std::string path = write_temp("valid.glb", triangle_glb("3", "12"));
  EXPECT_EQ(sl::load_gltf(path).triangle_count(), 1u);
}

}  // namespace
