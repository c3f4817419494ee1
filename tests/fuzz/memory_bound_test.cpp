// Memory bounds of the loaders under hostile input (issue 17): a tiny file that declares a huge
// tensor, accessor, image or header must be refused before anything of the declared size is
// allocated. Peak heap use is measured by tests/fuzz/alloc_counter.h (every malloc, operator new
// and aligned allocation of the process, OpenImageIO's C libraries included).
//
// Stated bounds, peak heap during one load (file = the input's size in bytes):
//   safetensors  8·file (tensors, widened up to 8x) + 64·header JSON (its DOM) + 1 MiB
//   glTF/GLB     the file and its decoded buffers (≤ 2·file) + 64·JSON (tinygltf's DOM)
//                + what its accessors and nodes declare, each accessor bounded by its
//                bufferView's bytes (instancing a mesh under many nodes is legitimate) + 1 MiB
//   images       8 bytes per declared value (w·h·c floats: the decode buffer and the tensor),
//                at most kMaxImageValues (2^28) values, + the decoder's own state (~1 MiB)
//   TFLite       the file (read whole) + 32·file + 1 MiB (nn::tflite::kMaxModelBytesPerFileByte: vectors,
//                strings, copied buffers and the structs themselves, shared objects counted per use)
//   velodyne     2·file + 1 MiB;  ray file: 3·file + 1 MiB (floats, then 32-byte Rays)
//   JSON files   (configs, calibration, index.json, meta.json, --batch lists) 64·file + 1 MiB:
//                nlohmann's DOM costs up to ~48 bytes per input byte for "[[[[..." nesting.
// Each case below uses a file of a few hundred bytes at most, so the bound is about 1 MiB,
// while what the file claims is gigabytes to terabytes.
#include <gtest/gtest.h>

#include <filesystem>

#include "data/image_io.h"
#include "data/kitti.h"
#include "nn/safetensors.h"
#include "nn/tflite.h"
#include "render/gltf_loader.h"
#include "render/ray_file.h"
#include "tests/fuzz/alloc_counter.h"
#include "tests/fuzz/hostile_files.h"
#include "tests/support/tflite_builder.h"
#include "tools/common/config.h"

namespace sl::test {

namespace {
constexpr size_t kMiB = size_t{1} << 20;

// Peak heap bytes while f runs; f is expected to throw sl::Error when `must_refuse`.
template <class F>
size_t peak_of(F&& f, bool must_refuse = true) {
  sl::test::reset_peak();
  bool refused = false;
  try {
    f();
  } catch (const sl::Error&) {
    refused = true;
  }
  const size_t peak = sl::test::peak_since_reset();
  EXPECT_EQ(refused, must_refuse);
  ::testing::Test::RecordProperty("peak_bytes", std::to_string(peak));  // in --gtest_output=xml
  return peak;
}

std::string be32(uint32_t v) {
  const char b[4] = {char(v >> 24), char(v >> 16), char(v >> 8), char(v)};
  return std::string(b, 4);
}

// CRC-32 (ISO-HDLC, reflected 0xEDB88320), as PNG chunks carry it.
uint32_t crc32_of(const std::string& s) {
  uint32_t c = 0xFFFFFFFFu;
  for (unsigned char b : s) {
    c ^= b;
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xEDB88320u & (0u - (c & 1u)));
  }
  return c ^ 0xFFFFFFFFu;
}

std::string png_chunk(const std::string& type, const std::string& data) {
  const std::string td = type + data;
  const uint32_t crc = crc32_of(td);
  return be32(static_cast<uint32_t>(data.size())) + td + be32(crc);
}

// A PNG whose IHDR declares width × height pixels (8-bit RGBA unless told: bit depth, colour
// type) and whose IDAT holds almost nothing.
std::string png_declaring(uint32_t width, uint32_t height, const std::string& depth_colour = "\x08\x06") {
  const std::string ihdr = be32(width) + be32(height) + depth_colour + std::string("\x00\x00\x00", 3);
  const std::string idat("\x78\x9c\x03\x00\x00\x00\x00\x01", 8);  // zlib stream of nothing
  return std::string("\x89PNG\r\n\x1a\n", 8) + png_chunk("IHDR", ihdr) + png_chunk("IDAT", idat) +
         png_chunk("IEND", "");
}

class MemoryBound : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!sl::test::alloc_counter_available()) GTEST_SKIP() << "malloc is owned by a sanitizer in this build";
  }
};

TEST_F(MemoryBound, SafetensorsHugeTensorClaimAllocatesNothingOfItsSize) {
  const std::string bytes =
      safetensors_bytes(R"({"w":{"dtype":"F32","shape":[67108864],"data_offsets":[0,268435456]}})", 16);
  const std::string path = write_temp("huge.safetensors", bytes);
  // 256 MiB: small enough that an unguarded reader's allocation would succeed and be counted.
  const size_t peak = peak_of([&] { sl::nn::read_safetensors(path); });
  EXPECT_LE(peak, 64 * bytes.size() + kMiB) << "claimed 256 MiB";
}

TEST_F(MemoryBound, SafetensorsHugeHeaderLengthAllocatesNothingOfItsSize) {
  std::string bytes = safetensors_bytes("{}", 0);
  const uint64_t claimed = 99ull << 20;  // under the 100 MB cap, far beyond the file
  std::memcpy(bytes.data(), &claimed, 8);
  const std::string path = write_temp("huge_header.safetensors", bytes);
  EXPECT_LE(peak_of([&] { sl::nn::read_safetensors(path); }), 64 * bytes.size() + kMiB);
}

TEST_F(MemoryBound, GltfHugeAccessorCountAllocatesNothingOfItsSize) {
  const std::string bytes = triangle_glb("16777216", "12");  // 192 MiB of positions claimed
  const std::string path = write_temp("huge_count.glb", bytes);
  EXPECT_LE(peak_of([&] { sl::render::load_gltf(path); }), 64 * bytes.size() + kMiB);
}

TEST_F(MemoryBound, ValidGltfStaysWithinItsBound) {
  const std::string bytes = triangle_glb("3", "12");
  const std::string path = write_temp("valid.glb", bytes);
  EXPECT_LE(peak_of([&] { sl::render::load_gltf(path); }, false), 64 * bytes.size() + kMiB);
}

TEST_F(MemoryBound, PngDeclaringFourBillionPixelsAllocatesNothingOfItsSize) {
  // Warm OpenImageIO up first: its one-time plugin and attribute tables are not this file's cost.
  const std::string small = write_temp("small.png", png_declaring(2, 2));
  try {
    sl::data::read_image(small);
  } catch (const sl::Error&) {
  }
  const std::string bytes = png_declaring(65535, 65535);  // 17 G values = 68 GB as floats
  const std::string path = write_temp("huge.png", bytes);
  const size_t peak = peak_of([&] { sl::data::read_image(path); });
  EXPECT_LE(peak, 64 * bytes.size() + kMiB);
}

TEST_F(MemoryBound, DepthPngDeclaringFourHundredMillionPixelsAllocatesNothingOfItsSize) {
  const std::string small = write_temp("small_depth.png", png_declaring(2, 2, std::string("\x10\x00", 2)));
  try {
    sl::data::read_depth(small);
  } catch (const sl::Error&) {
  }
  // 16-bit grey, 4e8 values: read_depth once allocated its 1.6 GB tensor before the size check.
  const std::string bytes = png_declaring(20000, 20000, std::string("\x10\x00", 2));
  const std::string path = write_temp("huge_depth.png", bytes);
  EXPECT_LE(peak_of([&] { sl::data::read_depth(path); }), 64 * bytes.size() + kMiB);
}

TEST_F(MemoryBound, ExrDeclaringFourBillionPixelsIsRefusedBeforeOpenExrOpensIt) {
  const std::string small = write_temp("small.exr", exr_declaring(1, 1));
  try {
    sl::data::read_image_info(small);
  } catch (const sl::Error&) {
  }
  // The fuzzer's find: 398 bytes, a ZIP file whose window is 13893636 x 257 pixels. OpenEXR
  // sizes its decompression buffers by the window while opening (16 lines of 13.9 M floats).
  const std::string path = std::string(STREETLIGHT_SOURCE_DIR) + "/tests/fuzz/corpus/image/crash_exr_huge_window";
  EXPECT_LE(peak_of([&] { sl::data::read_image_info(path); }), 64 * std::filesystem::file_size(path) + kMiB);
}

TEST_F(MemoryBound, ExrAttributeDeclaringGigabytesIsRefusedBeforeOpenExrOpensIt) {
  const std::string small = write_temp("small.exr", exr_declaring(1, 1));
  try {
    sl::data::read_image_info(small);
  } catch (const sl::Error&) {
  }
  // The fuzzer's find: 412 bytes whose 'capDate' string attribute declares 1.7 GB.
  const std::string path = std::string(STREETLIGHT_SOURCE_DIR) + "/tests/fuzz/corpus/image/crash_exr_huge_attribute";
  EXPECT_LE(peak_of([&] { sl::data::read_image_info(path); }), 64 * std::filesystem::file_size(path) + kMiB);
}

TEST_F(MemoryBound, VelodyneAndRayFilesCostAFewTimesTheirSize) {
  const std::string points(16 * 4096, '\0');  // 4096 points at the origin
  const std::string vpath = write_temp("points.bin", points);
  EXPECT_LE(peak_of([&] { sl::data::read_velodyne(vpath); }, false), 2 * points.size() + kMiB);
  std::string rays(24 * 4096, '\0');
  const std::string rpath = write_temp("rays.bin", rays);
  EXPECT_LE(peak_of([&] { sl::render::read_ray_file(rpath); }, false), 3 * rays.size() + kMiB);
}

TEST_F(MemoryBound, DeeplyNestedJsonConfigCostsABoundedMultipleOfItsSize) {
  const std::string text = std::string(20000, '[') + std::string(20000, ']');
  const std::string path = write_temp("nested.json", text);
  sl::cli::Config config(nlohmann::json{{"a", 1}});
  EXPECT_LE(peak_of([&] { config.merge_file(path); }), 64 * text.size() + kMiB);
}

TEST_F(MemoryBound, TfliteTensorSharedTwentyThousandTimesIsRefusedWithinItsBound) {
  // One tensor whose buffer holds 64 KiB, referenced 20,000 times: 1.3 GB if each were copied.
  TinyTflite t = tiny_tflite();
  t.buffers->items[1] = fb_table()->ref(0, fb_vec(std::vector<uint8_t>(65536, 1)));
  t.tensor[1]->refs[0].second = fb_vec<int32_t>({2, 1, 1, 32768});
  t.tensor[1]->refs.back().second = fb_table()->ref(2, fb_vec<float>({1.0f}));
  t.tensors->items.assign(20000, t.tensor[1]);
  const std::string bytes = FbWriter().build(t.model);
  const std::string path = write_temp("shared.tflite", bytes);
  EXPECT_LE(peak_of([&] { sl::nn::tflite::read(path); }), 33 * bytes.size() + kMiB);
}

TEST_F(MemoryBound, TfliteVectorOfTwoBillionTensorsAllocatesNothingOfItsSize) {
  TinyTflite t = tiny_tflite();
  std::string bytes = t.bytes;
  const uint32_t claimed = 0x7FFFFFFFu;
  std::memcpy(&bytes[t.tensors->pos], &claimed, 4);
  const std::string path = write_temp("huge_vector.tflite", bytes);
  EXPECT_LE(peak_of([&] { sl::nn::tflite::read(path); }), 33 * bytes.size() + kMiB);
}

}  // namespace

}  // namespace sl::test
