// The hardening tests of issue 17: hostile headers are refused with one clean sl::Error, before
// anything sized by the header is allocated. Each test fails when its protection is removed
// (checked by deleting the check: the loader then reads out of bounds, allocates the claimed
// size, or throws std::bad_alloc / std::length_error instead of sl::Error).
#include <gtest/gtest.h>

#include "util/error.h"
#include "data/exr_header.h"
#include "data/image_io.h"
#include "nn/safetensors.h"
#include "render/gltf_loader.h"
#include "tests/fuzz/hostile_files.h"
#include "util/error.h"

namespace sl::test {

namespace {

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
  const std::string msg = clean_error([&] { sl::render::load_gltf(path); });
  EXPECT_NE(msg.find("reads past the end of bufferView 0"), std::string::npos) << msg;
}

TEST(GltfHostileAccessor, AccessorOffsetNearTwoToTheSixtyFourIsRefused) {
  // byteOffset 2^64 − 8 wraps the sum offset + stride·(count − 1) + element back into range.
  const std::string path = write_temp("offset.glb", triangle_glb("3", "12", "18446744073709551608"));
  const std::string msg = clean_error([&] { sl::render::load_gltf(path); });
  EXPECT_NE(msg.find("reads past the end of bufferView 0"), std::string::npos) << msg;
}

TEST(ExrHostileHeader, DataWindowPastTheValueLimitIsRefusedByEveryReader) {
  // 10^12 pixels declared in 300 bytes; also the fuzzer's find, a window of 3.6e9 pixels.
  const std::string path = write_temp("huge_window.exr", exr_declaring(99999, 9999999));
  EXPECT_EQ(sl::data::summarize_exr_header(path).largest_window_pixels, int64_t{100000} * 10000000);
  for (const std::string& msg :
       {clean_error([&] { sl::data::read_image_info(path); }), clean_error([&] { sl::data::read_image(path); }),
        clean_error([&] { sl::data::read_depth(path); })})
    EXPECT_NE(msg.find("declares a data window of 1000000000000 pixels"), std::string::npos) << msg;
  const std::string fuzz_find = std::string(STREETLIGHT_SOURCE_DIR) + "/tests/fuzz/corpus/image/crash_exr_huge_window";
  EXPECT_NE(clean_error([&] { sl::data::read_depth(fuzz_find); }).find("declares a data window"), std::string::npos);
}

TEST(ExrHostileHeader, WindowAtTheInt32ExtremesSaturatesTheCount) {
  const int32_t lo = INT32_MIN, hi = INT32_MAX;
  std::string bytes = exr_declaring(hi, hi);
  // Move the window's minimum corner to (INT32_MIN, INT32_MIN): 2^32 x 2^32 pixels.
  const size_t at = bytes.find(std::string("dataWindow\0box2i\0", 17)) + 17 + 4;
  std::memcpy(&bytes[at], &lo, 4);
  std::memcpy(&bytes[at + 4], &lo, 4);
  const std::string path = write_temp("extreme_window.exr", bytes);
  EXPECT_EQ(sl::data::summarize_exr_header(path).largest_window_pixels, INT64_MAX) << "2^32 x 2^32 saturates";
  EXPECT_FALSE(clean_error([&] { sl::data::read_image_info(path); }).empty());
}

TEST(ExrHostileHeader, AttributeLargerThanTheFileIsRefusedByEveryReader) {
  std::string bytes = exr_declaring(7, 3);
  const int32_t claimed = 1744830464;  // the fuzzer's find: a 1.7 GB string in a 412-byte file
  std::memcpy(&bytes[bytes.find(std::string("chlist\0", 7)) + 7], &claimed, 4);
  const std::string path = write_temp("huge_attribute.exr", bytes);
  const sl::data::ExrHeaderSummary summary = sl::data::summarize_exr_header(path);
  EXPECT_EQ(summary.attribute_past_end, "channels");
  EXPECT_EQ(summary.attribute_bytes, claimed);
  for (const std::string& msg :
       {clean_error([&] { sl::data::read_image_info(path); }), clean_error([&] { sl::data::read_image(path); }),
        clean_error([&] { sl::data::read_depth(path); })})
    EXPECT_NE(msg.find("attribute 'channels' declares 1744830464 bytes, past the end"), std::string::npos) << msg;
  const std::string fuzz_find =
      std::string(STREETLIGHT_SOURCE_DIR) + "/tests/fuzz/corpus/image/crash_exr_huge_attribute";
  EXPECT_NE(clean_error([&] { sl::data::read_image(fuzz_find); }).find("attribute 'capDate' declares"),
            std::string::npos);
}

TEST(ExrHostileHeader, OrdinaryFilesAndOtherFormatsDeclareWhatTheyHold) {
  const std::string exr = write_temp("small_window.exr", exr_declaring(7, 3));
  EXPECT_EQ(sl::data::summarize_exr_header(exr).largest_window_pixels, 32);
  EXPECT_EQ(sl::data::summarize_exr_header(exr).attribute_past_end, "");
  const std::string not_exr = write_temp("not.exr", "P6 1 1 255 xyz");
  EXPECT_EQ(sl::data::summarize_exr_header(not_exr).largest_window_pixels, 0);
  EXPECT_EQ(sl::data::summarize_exr_header(write_temp("empty.exr", "")).largest_window_pixels, 0);
}

TEST(GltfHostileAccessor, ValidTriangleStillLoads) {
  const std::string path = write_temp("valid.glb", triangle_glb("3", "12"));
  EXPECT_EQ(sl::render::load_gltf(path).triangle_count(), 1u);
}

}  // namespace

}  // namespace sl::test
