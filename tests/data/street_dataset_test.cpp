// StreetDataset and SampleLoader: round trip of the generated format, deterministic shuffling,
// prefetch thread shutdown, and errors that name the broken file.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <set>

#include "data/contact_sheet.h"
#include "data/image_io.h"
#include "data/street_dataset.h"
#include "render/equirect.h"
#include "support/street_fixture.h"

using sl::data::compose_contact_sheet;
using sl::data::epoch_order;
using sl::data::SampleLoader;
using sl::data::StreetDataset;
using sl::data::StreetSample;
using sl::data::StreetView;
using sl::render::CameraRay;

namespace sl::test {
namespace {

namespace fs = std::filesystem;

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

// A private copy of the tiny dataset that a test may damage.
std::string damaged_copy(const std::string& name) {
  const std::string src = test::tiny_dataset();
  const std::string dst = test::scratch(name);
  fs::remove_all(dst);
  fs::copy(src, dst, fs::copy_options::recursive);
  return dst;
}

TEST(StreetDataset, RoundTripMatchesTheFilesAndMeta) {
  const std::string dir = test::tiny_dataset();
  std::set<std::string> all;
  for (const char* split : {"train", "val", "test"}) {
    const StreetDataset ds(dir, split);
    for (const std::string& id : ds.ids()) EXPECT_TRUE(all.insert(id).second) << id << " in two splits";
  }
  EXPECT_EQ(all.size(), 3u);

  const StreetDataset ds(dir, "train");
  ASSERT_GT(ds.size(), 0u);
  const StreetSample s = ds.load(0);
  EXPECT_EQ(s.id, ds.ids()[0]);
  EXPECT_EQ(s.pano_hdr.shape(), (Shape{3, 16, 32}));
  EXPECT_EQ(s.pano_ldr.shape(), (Shape{3, 16, 32}));
  EXPECT_EQ(s.pano_sky_mask.shape(), (Shape{1, 16, 32}));
  EXPECT_EQ(s.sky_hdr.shape(), (Shape{3, 8, 32}));
  ASSERT_EQ(s.views.size(), 2u);
  for (const StreetView& v : s.views) {
    EXPECT_EQ(v.ldr.shape(), (Shape{3, 24, 48}));
    EXPECT_EQ(v.depth.shape(), (Shape{24, 48}));
    EXPECT_EQ(v.sky_mask.shape(), (Shape{1, 24, 48}));
    ASSERT_TRUE(v.hdr.defined());
    // LDR is the stored clip((e·L)^(1/2.2)) up to 8-bit rounding; depth is 0 exactly on sky.
    const float* l = v.ldr.data<float>();
    const float* h = v.hdr.data<float>();
    const float* d = v.depth.data<float>();
    const float* m = v.sky_mask.data<float>();
    for (int64_t i = 0; i < v.ldr.numel(); ++i)
      ASSERT_NEAR(l[i], std::min(1.0, std::pow(s.exposure * h[i], 1.0 / 2.2)), 0.5 / 255 + 1e-4);
    for (int64_t i = 0; i < v.depth.numel(); ++i) ASSERT_EQ(d[i] == 0.0f, m[i] == 1.0f) << i;
  }
  // The exposure maps view 0's median luminance to the LDR value 0.4.
  {
    std::vector<float> lum;
    const float* h = s.views[0].hdr.data<float>();
    const int64_t n = s.views[0].depth.numel();
    for (int64_t i = 0; i < n; ++i) lum.push_back(0.2126f * h[i] + 0.7152f * h[n + i] + 0.0722f * h[2 * n + i]);
    std::nth_element(lum.begin(), lum.begin() + n / 2, lum.end());
    EXPECT_NEAR(std::pow(s.exposure * lum[n / 2], 1.0 / 2.2), 0.4, 1e-3);
  }
  EXPECT_NEAR(glm::length(s.sun_direction), 1.0, 1e-9);
  EXPECT_NEAR(s.pano_position.y, 1.6, 1e-12);
  EXPECT_NEAR(s.views[0].camera.position().y, 1.6, 1e-12);
  EXPECT_GT(s.exposure, 0.0);
  if (s.has_insertion) {
    EXPECT_TRUE(fs::exists(s.object_glb));
    EXPECT_EQ(s.insert_object_mask.shape(), (Shape{1, 24, 48}));
    EXPECT_GT(s.object_scale, 0.0);
  }
}

// View 0 stands where the panorama was taken, so both sky masks agree direction by direction
// (render/equirect.h and render/camera.h conventions meet here).
TEST(StreetDataset, PanoramaAndView0SkyMasksAgree) {
  const StreetDataset ds(test::tiny_dataset(), "train");
  const StreetSample s = ds.load(0);
  const StreetView& v = s.views[0];
  ASSERT_NEAR(glm::length(v.camera.position() - s.pano_position), 0.0, 1e-12);
  const int W = v.camera.intrinsics().width, H = v.camera.intrinsics().height;
  const int pw = static_cast<int>(s.pano_sky_mask.size(2)), ph = static_cast<int>(s.pano_sky_mask.size(1));
  int agree = 0;
  for (int r = 0; r < H; ++r)
    for (int c = 0; c < W; ++c) {
      const CameraRay ray = v.camera.pixel_ray(c, r);
      const render::equirect::UV uv =
          render::equirect::direction_to_uv(ray.direction.x, ray.direction.y, ray.direction.z, pw, ph);
      const int pc = std::min(pw - 1, static_cast<int>(uv.u)), pr = std::min(ph - 1, static_cast<int>(uv.v));
      agree += v.sky_mask.data<float>()[r * W + c] == s.pano_sky_mask.data<float>()[pr * pw + pc];
    }
  EXPECT_GT(static_cast<double>(agree) / (W * H), 0.85);  // the panorama is coarser: edges differ
}

// The meta-only reader (used for the evaluation's constant baseline) says what load() says.
TEST(StreetDataset, SunLabelMatchesTheFullLoad) {
  const StreetDataset ds(test::tiny_dataset(), "train");
  ASSERT_GT(ds.size(), 0u);
  for (size_t i = 0; i < ds.size(); ++i) {
    const StreetSample s = ds.load(i);
    const data::SunLabel l = ds.load_sun_label(i);
    EXPECT_EQ(l.sun_direction, s.sun_direction);
    EXPECT_EQ(l.sun_known, s.sun_known);
    EXPECT_EQ(l.camera.position(), s.views[0].camera.position());
    EXPECT_EQ(l.camera.rotation(), s.views[0].camera.rotation());
    EXPECT_EQ(l.camera.intrinsics().fx, s.views[0].camera.intrinsics().fx);
  }
}

TEST(ContactSheet, ComposesRowsOfTiles) {
  const Tensor sheet = compose_contact_sheet(test::tiny_dataset(), 2, 16);
  EXPECT_EQ(sheet.size(0), 3);
  EXPECT_EQ(sheet.size(1), 2 * (16 + 4) + 4);
  EXPECT_GT(sheet.size(2), 7 * 16);
}

TEST(SampleLoader, ShufflesDeterministicallyByEpoch) {
  const auto a = epoch_order(10, 5, 0), b = epoch_order(10, 5, 0), c = epoch_order(10, 5, 1);
  EXPECT_EQ(a, b);
  EXPECT_NE(a, c);
  std::vector<size_t> sorted = a;
  std::sort(sorted.begin(), sorted.end());
  for (size_t i = 0; i < 10; ++i) EXPECT_EQ(sorted[i], i);

  const std::string dir = test::tiny_dataset();
  const StreetDataset ds(dir, "train");
  SampleLoader l1(ds, 9, 2), l2(ds, 9, 1);
  for (size_t k = 0; k < 2 * ds.size() + 1; ++k) {
    const StreetSample x = l1.next(), y = l2.next();
    EXPECT_EQ(x.id, y.id);
    EXPECT_EQ(l1.epoch(), k / ds.size());
  }
}

// A destructor that failed to stop its thread would hang here: ctest's timeout catches that
// (no wall-clock assertion, which fails spuriously on a loaded machine).
TEST(SampleLoader, StopsCleanlyWithAFullQueue) {
  const StreetDataset ds(test::tiny_dataset(), "train");
  {
    SampleLoader l(ds, 1, 3);
    std::this_thread::sleep_for(std::chrono::milliseconds(100));  // the prefetch queue fills up
  }
  { SampleLoader never_read(ds, 2, 1); }  // destroyed at once, possibly mid-load
  SUCCEED();
}

TEST(SampleLoader, RethrowsLoadErrorsFromNext) {
  const std::string dir = damaged_copy("loader_damaged");
  const StreetDataset ds(dir, "train");
  for (const std::string& id : ds.ids()) fs::remove(fs::path(dir) / "samples" / id / "sky_hdr.exr");
  SampleLoader l(ds, 0);
  const std::string e = error_of([&] { l.next(); });
  EXPECT_NE(e.find("sky_hdr.exr"), std::string::npos) << e;
}

TEST(StreetDataset, MissingIndexOrSplitIsNamed) {
  const std::string empty = test::scratch("no_index");
  fs::create_directories(empty);
  std::string e = error_of([&] { StreetDataset(empty, "train"); });
  EXPECT_NE(e.find("index.json"), std::string::npos) << e;
  EXPECT_NE(e.find(empty), std::string::npos) << e;
  e = error_of([&] { StreetDataset(test::tiny_dataset(), "training"); });
  EXPECT_NE(e.find("training"), std::string::npos) << e;
  const std::string bad = test::scratch("bad_index");
  fs::create_directories(bad);
  test::write_bytes(bad + "/index.json", "{ not json");
  e = error_of([&] { StreetDataset(bad, "train"); });
  EXPECT_NE(e.find("index.json"), std::string::npos) << e;
}

TEST(StreetDataset, MissingFileIsNamedWithItsSample) {
  const std::string dir = damaged_copy("missing_file");
  const StreetDataset ds(dir, "train");
  const std::string id = ds.ids()[0];
  fs::remove(fs::path(dir) / "samples" / id / "view_1_depth.exr");
  const std::string e = error_of([&] { ds.load(0); });
  EXPECT_NE(e.find("view_1_depth.exr"), std::string::npos) << e;
  EXPECT_NE(e.find(id), std::string::npos) << e;
}

TEST(StreetDataset, CorruptExrIsNamed) {
  const std::string dir = damaged_copy("corrupt_exr");
  const StreetDataset ds(dir, "train");
  const std::string id = ds.ids()[0];
  test::truncate_file((fs::path(dir) / "samples" / id / "pano_hdr.exr").string(), 0.5);
  const std::string e = error_of([&] { ds.load(0); });
  EXPECT_NE(e.find("pano_hdr.exr"), std::string::npos) << e;
}

TEST(StreetDataset, BrokenMetaKeyIsNamed) {
  const std::string dir = damaged_copy("broken_meta");
  const StreetDataset ds(dir, "train");
  const fs::path meta = fs::path(dir) / "samples" / ds.ids()[0] / "meta.json";
  std::ifstream f(meta);
  nlohmann::json j = nlohmann::json::parse(f);
  j.erase("exposure");
  test::write_bytes(meta.string(), j.dump());
  const std::string e = error_of([&] { ds.load(0); });
  EXPECT_NE(e.find("exposure"), std::string::npos) << e;
  EXPECT_NE(e.find("meta.json"), std::string::npos) << e;
}

}  // namespace
}  // namespace sl::test
