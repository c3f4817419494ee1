// Harness: data/image_io.h read_image_info, read_image and read_depth. The extension follows the
// file's magic number (OpenEXR, Radiance HDR, PNG, JPEG; anything else is tried as .png).
// Invariant: read_image returns F32 [C, H, W] with the size and channels read_image_info reports.
#include <cstring>

#include "data/image_io.h"
#include "tests/fuzz/harness/fuzz_harness.h"

using sl::data::ImageInfo;
using sl::data::kMaxImageValues;
using sl::data::read_depth;
using sl::data::read_image;
using sl::data::read_image_info;

namespace sl::test {

namespace {
constexpr int64_t kFuzzMaxDecodedValues = int64_t{1} << 20;

const char* extension_of(const uint8_t* d, size_t n) {
  if (n >= 4 && std::memcmp(d, "\x76\x2f\x31\x01", 4) == 0) return ".exr";
  if (n >= 2 && d[0] == '#' && d[1] == '?') return ".hdr";
  if (n >= 2 && d[0] == 0xFF && d[1] == 0xD8) return ".jpg";
  return ".png";
}
}  // namespace

void fuzz_image(const uint8_t* data, size_t size) {
  const char* target = "image";
  const std::string path = write_scratch(std::string("input") + extension_of(data, size), data, size);
  ImageInfo info;
  if (!refuses_cleanly_or_runs(target, [&] { info = read_image_info(path); })) return;
  // A header may legitimately declare up to kMaxImageValues values (1 GiB of decode buffer,
  // zero-filled, then read from a file of a few bytes): such inputs cost the fuzzer ~0.5 s
  // each and exercise nothing a smaller declared size does not. Sizes past the limit are still
  // read, since refusing them is what is checked; the limit itself is tests/fuzz/memory_bound_test.
  const int64_t declared = int64_t{info.width} * info.height * info.channels;
  if (declared > kFuzzMaxDecodedValues && declared <= kMaxImageValues) return;
  refuses_cleanly_or_runs(target, [&] {
    const Tensor t = read_image(path);
    if (t.dtype() != DType::F32 || t.shape() != Shape{info.channels, info.height, info.width})
      violation(target, "read_image returned " + t.describe() + " for a file of " + std::to_string(info.width) + "x" +
                            std::to_string(info.height) + "x" + std::to_string(info.channels));
  });
  if (info.channels == 1)
    refuses_cleanly_or_runs(target, [&] {
      const Tensor d = read_depth(path);
      if (d.numel() != static_cast<int64_t>(info.width) * info.height) violation(target, "read_depth size mismatch");
    });
}

}  // namespace sl::test
