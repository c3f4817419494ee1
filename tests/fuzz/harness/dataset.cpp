// Harness: data/street_dataset.h. The input up to its first NUL byte is DIR/index.json, the
// rest is DIR/samples/000000/meta.json (absent when there is no NUL byte). The sample folder
// also holds tiny valid image files under the generator's names (written once with our own
// writers), so a well-formed meta.json reaches every reader.
// Invariant: StreetDataset lists ids; load() of the first two returns views whose LDR, depth
// and mask sizes match their intrinsics.
#include <algorithm>
#include <cstring>
#include <filesystem>

#include "data/image_io.h"
#include "data/street_dataset.h"
#include "tests/fuzz/harness/fuzz_harness.h"

using sl::data::StreetDataset;
using sl::data::StreetSample;
using sl::data::StreetView;
using sl::data::write_depth;
using sl::data::write_image;
using sl::render::Intrinsics;

namespace sl::test {

namespace fs = std::filesystem;

namespace {

// 8x4 views, 8x4 panorama and sky: enough for every reader, cheap to read.
const std::string& dataset_dir() {
  static const std::string dir = [] {
    const fs::path d = fs::path(fuzz_scratch_dir()) / "dataset";
    const fs::path s = d / "samples" / "000000";
    fs::create_directories(s);
    const Tensor rgb = Tensor::full({3, 4, 8}, 0.5f), grey = Tensor::full({1, 4, 8}, 1.0f);
    for (const char* f : {"pano_hdr.exr", "sky_hdr.exr", "view_0_hdr.exr", "insert_with_object_hdr.exr",
                          "insert_without_object_hdr.exr"})
      write_image((s / f).string(), rgb);
    for (const char* f : {"pano_ldr.png", "view_0_ldr.png", "insert_with_object_ldr.png"})
      write_image((s / f).string(), rgb);
    for (const char* f : {"pano_sky_mask.png", "view_0_sky_mask.png", "insert_object_mask.png"})
      write_image((s / f).string(), grey);
    write_depth((s / "view_0_depth.exr").string(), Tensor::full({1, 4, 8}, 10.0f));
    const uint8_t glb[] = "glTF";
    write_scratch("dataset/samples/000000/object.glb", glb, 4);
    return d.string();
  }();
  return dir;
}

}  // namespace

void fuzz_dataset(const uint8_t* data, size_t size) {
  const char* target = "dataset";
  const std::string& dir = dataset_dir();
  const uint8_t* nul = static_cast<const uint8_t*>(std::memchr(data, 0, size));
  const size_t index_size = nul ? static_cast<size_t>(nul - data) : size;
  write_scratch("dataset/index.json", data, index_size);
  const fs::path meta = fs::path(dir) / "samples" / "000000" / "meta.json";
  std::error_code ec;
  fs::remove(meta, ec);
  if (nul) write_scratch("dataset/samples/000000/meta.json", nul + 1, size - index_size - 1);
  refuses_cleanly_or_runs(target, [&] {
    const StreetDataset ds(dir, "train");
    for (size_t i = 0; i < std::min<size_t>(ds.size(), 2); ++i) {
      refuses_cleanly_or_runs(target, [&] {
        const StreetSample s = ds.load(i);
        for (const StreetView& v : s.views) {
          const Intrinsics& k = v.camera.intrinsics();
          const Shape hw{k.height, k.width};
          if (v.ldr.shape() != Shape{3, k.height, k.width} || v.depth.shape() != hw ||
              v.sky_mask.shape() != Shape{1, k.height, k.width})
            violation(target, "a view's image sizes differ from its intrinsics");
        }
      });
    }
  });
}

}  // namespace sl::test
