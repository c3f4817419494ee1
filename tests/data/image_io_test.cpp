#include "data/image_io.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include <sys/stat.h>
#include <unistd.h>

#include "support/exif_photo.h"
#include "support/test_files.h"
#include "util/random.h"

namespace sl::test {

namespace {

sl::Tensor random_image(int c, int h, int w, double lo, double hi, uint64_t seed) {
  return sl::Tensor::uniform({c, h, w}, lo, hi, seed);
}

// Expects `fn` to throw sl::Error whose message contains `path` and `needle`.
template <class Fn>
void expect_error_naming(Fn&& fn, const std::string& path, const std::string& needle = "") {
  try {
    fn();
    ADD_FAILURE() << "expected sl::Error for " << path;
  } catch (const sl::Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find(path), std::string::npos) << m;
    if (!needle.empty()) {
      EXPECT_NE(m.find(needle), std::string::npos) << m;
    }
  }
}

bool has_temporary_files(const std::string& folder) {
  for (const auto& entry : std::filesystem::directory_iterator(folder))
    if (entry.path().filename().string().find(".tmp-") != std::string::npos) return true;
  return false;
}

// Removes this process's scratch folder after all data tests have run.
class ScratchCleanup : public ::testing::Environment {
 public:
  void TearDown() override {
    std::error_code ignored;
    std::filesystem::remove_all(sl::test::scratch_dir(), ignored);
  }
};
[[maybe_unused]] ::testing::Environment* const kScratchCleanup =
    ::testing::AddGlobalTestEnvironment(new ScratchCleanup);

}  // namespace

TEST(ImageIo, SrgbCurveIsTheExactPiecewiseStandard) {
  EXPECT_NEAR(sl::data::srgb_to_linear(0.5f), 0.2140411f, 1e-6);
  EXPECT_NEAR(sl::data::srgb_to_linear(0.04045f), 0.04045f / 12.92f, 1e-7);
  EXPECT_NEAR(sl::data::linear_to_srgb(0.0031308f), 0.0031308f * 12.92f, 1e-6);
  EXPECT_FLOAT_EQ(sl::data::srgb_to_linear(1.0f), 1.0f);
  EXPECT_FLOAT_EQ(sl::data::srgb_to_linear(0.0f), 0.0f);
  for (int i = 0; i <= 255; ++i) {
    const float e = i / 255.0f;
    EXPECT_NEAR(sl::data::linear_to_srgb(sl::data::srgb_to_linear(e)), e, 2e-6);
  }
}

TEST(ImageIo, ExrRoundTripIsExactForHdrValues) {
  const std::string path = scratch("roundtrip.exr");
  sl::Tensor img = random_image(3, 5, 7, 0.0, 1.0, 1);
  img.data<float>()[3] = 65000.0f;  // a sun texel
  img.data<float>()[4] = 1e-6f;
  sl::data::write_image(path, img);
  const sl::Tensor back = sl::data::read_image(path);
  ASSERT_EQ(back.shape(), img.shape());
  const auto a = img.to_vector(), b = back.to_vector();
  for (size_t i = 0; i < a.size(); ++i) EXPECT_EQ(a[i], b[i]) << i;
  const sl::data::ImageInfo info = sl::data::read_image_info(path);
  EXPECT_TRUE(info.is_float);
  EXPECT_EQ(info.channels, 3);
}

TEST(ImageIo, RadianceHdrRoundTripIsWithinRgbePrecision) {
  const std::string path = scratch("roundtrip.hdr");
  sl::Tensor img = random_image(3, 4, 8, 0.1, 1.0, 2);
  img.data<float>()[0] = 50000.0f;
  sl::data::write_image(path, img);
  const auto a = img.to_vector(), b = sl::data::read_image(path, {.channels = 3}).to_vector();
  // RGBE shares one exponent per pixel: every channel is accurate to ~1% of the pixel's largest.
  const size_t plane = 32;
  for (size_t i = 0; i < a.size(); ++i) {
    const size_t p = i % plane;
    const double pixel_max = std::max({a[p], a[p + plane], a[p + 2 * plane]});
    EXPECT_NEAR(b[i], a[i], 0.01 * pixel_max) << i;
  }
  expect_error_naming([&] { sl::data::write_image(scratch("four.hdr"), random_image(4, 2, 2, 0, 1, 3)); },
                      scratch("four.hdr"), "3 channels");
}

TEST(ImageIo, Png8RoundTripDecodesAndEncodesSrgb) {
  const std::string path = scratch("codes.png");
  // Linear values that are exactly sRGB codes k/255 survive the round trip.
  sl::Tensor img = sl::Tensor::empty({3, 16, 16});
  float* p = img.data<float>();
  for (int i = 0; i < 3 * 256; ++i) p[i] = sl::data::srgb_to_linear((i % 256) / 255.0f);
  sl::data::write_image(path, img);
  const sl::Tensor back = sl::data::read_image(path);
  const auto raw = sl::data::read_image(path, {.transfer = sl::data::Transfer::Linear}).to_vector();
  const auto b = back.to_vector();
  for (int i = 0; i < 3 * 256; ++i) {
    EXPECT_NEAR(b[i], p[i], 1e-6) << i;
    EXPECT_NEAR(raw[i], (i % 256) / 255.0, 1e-7) << i;  // raw codes
  }
  EXPECT_EQ(sl::data::read_image_info(path).bits, 8);
}

TEST(ImageIo, Png16AndJpegRoundTrip) {
  const std::string png = scratch("sixteen.png");
  const sl::Tensor img = random_image(4, 6, 9, 0.0, 1.0, 4);
  sl::data::write_image(png, img, {.transfer = sl::data::Transfer::Linear, .bits = 16});
  EXPECT_EQ(sl::data::read_image_info(png).bits, 16);
  const auto a = img.to_vector(), b = sl::data::read_image(png, {.transfer = sl::data::Transfer::Linear}).to_vector();
  for (size_t i = 0; i < a.size(); ++i) EXPECT_NEAR(b[i], a[i], 0.51 / 65535.0) << i;

  const std::string jpg = scratch("smooth.jpg");
  sl::Tensor smooth = sl::Tensor::empty({3, 16, 16});
  for (int i = 0; i < 3 * 256; ++i) smooth.data<float>()[i] = 0.2f + 0.3f * ((i % 256) / 256.0f);
  sl::data::write_image(jpg, smooth);
  const auto s = smooth.to_vector(), j = sl::data::read_image(jpg).to_vector();
  for (size_t i = 0; i < s.size(); ++i) EXPECT_NEAR(j[i], s[i], 0.03) << i;
}

TEST(ImageIo, ChannelRequestsReplicateGreyDropAlphaAndRejectTheRest) {
  const std::string grey = scratch("grey.png"), rgba = scratch("rgba.png");
  sl::data::write_image(grey, random_image(1, 3, 4, 0, 1, 5));
  sl::data::write_image(rgba, random_image(4, 3, 4, 0, 1, 6));
  const sl::Tensor g3 = sl::data::read_image(grey, {.channels = 3});
  EXPECT_EQ(g3.shape(), (sl::Shape{3, 3, 4}));
  EXPECT_EQ(g3.at({0, 1, 2}), g3.at({2, 1, 2}));
  EXPECT_EQ(sl::data::read_image(rgba, {.channels = 3}).shape(), (sl::Shape{3, 3, 4}));
  // Alpha is stored unassociated and never curve-mapped.
  const sl::Tensor rgba_in = random_image(4, 3, 4, 0, 1, 6);
  const sl::Tensor rgba_back = sl::data::read_image(rgba);
  EXPECT_NEAR(rgba_back.at({3, 2, 1}), rgba_in.at({3, 2, 1}), 0.5 / 255.0);
  EXPECT_NEAR(rgba_back.at({0, 2, 1}), rgba_in.at({0, 2, 1}), 0.01);
  expect_error_naming([&] { sl::data::read_image(rgba, {.channels = 1}); }, rgba, "4 channels");
  expect_error_naming([&] { sl::data::read_image(grey, {.width = 4, .height = 5}); }, grey, "3");
}

TEST(ImageIo, DamagedFilesRaiseErrorsNamingTheFile) {
  const std::string png = scratch("cut.png"), exr = scratch("cut.exr"), hdr = scratch("cut.hdr");
  const sl::Tensor img = random_image(3, 64, 64, 0, 1, 7);
  sl::data::write_image(png, img);
  sl::data::write_image(exr, img);
  sl::data::write_image(hdr, img);
  sl::test::truncate_file(png, 0.5);
  sl::test::truncate_file(exr, 0.5);
  sl::test::truncate_file(hdr, 0.5);
  expect_error_naming([&] { sl::data::read_image(png); }, png);
  expect_error_naming([&] { sl::data::read_image(exr); }, exr);
  expect_error_naming([&] { sl::data::read_image(hdr); }, hdr);

  const std::string garbage = scratch("garbage.png");
  sl::test::write_bytes(garbage, std::string("\x89PNG\r\n\x1a\n this is not a png at all", 33));
  expect_error_naming([&] { sl::data::read_image(garbage); }, garbage);
  const std::string noise = scratch("noise.exr");
  std::string bytes;
  for (int i = 0; i < 4096; ++i) bytes.push_back(static_cast<char>(sl::hash_counter(9, i) & 0xff));
  sl::test::write_bytes(noise, bytes);
  expect_error_naming([&] { sl::data::read_image(noise); }, noise);
  expect_error_naming([&] { sl::data::read_image(scratch("absent.exr")); }, scratch("absent.exr"), "no such file");
}

// A read collects what the decoder prints on descriptor 2 (data/image_io.cpp). Reads of several
// threads overlap; afterwards descriptor 2 must be the process's own stderr again, not a
// temporary file: a loader with two threads once silenced every later log line this way.
TEST(ImageIo, OverlappingReadsInThreadsGiveStderrBack) {
  const std::string png = scratch("threads.png");
  sl::data::write_image(png, random_image(3, 256, 256, 0, 1, 11));
  struct stat before {}, after {};
  ASSERT_EQ(::fstat(STDERR_FILENO, &before), 0);
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&] {
      for (int k = 0; k < 25; ++k) (void)sl::data::read_image(png);
    });
  for (auto& th : threads) th.join();
  ASSERT_EQ(::fstat(STDERR_FILENO, &after), 0);
  EXPECT_EQ(before.st_dev, after.st_dev);
  EXPECT_EQ(before.st_ino, after.st_ino) << "descriptor 2 was left redirected";
}

TEST(ImageIo, FailedWritesLeaveNoPartialFile) {
  const std::string path = scratch("keep.png");
  sl::data::write_image(path, random_image(3, 4, 4, 0, 1, 8));
  const auto before = std::filesystem::file_size(path);
  // Each of these fails; the existing file stays intact and no temporary is left behind.
  EXPECT_THROW(sl::data::write_image(path, random_image(3, 4, 4, 0, 1, 9), {.bits = 12}), sl::Error);
  EXPECT_THROW(sl::data::write_image(path, sl::Tensor::zeros({5, 4, 4})), sl::Error);
  EXPECT_THROW(sl::data::write_image(path, sl::Tensor::zeros({4, 4})), sl::Error);
  expect_error_naming(
      [&] {
        sl::data::write_image(scratch("nofolder/x.exr"), sl::Tensor::zeros({3, 2, 2}));
      },
      scratch("nofolder/x.exr"), "folder");
  expect_error_naming(
      [&] {
        sl::data::write_image(scratch("x.bmpx"), sl::Tensor::zeros({3, 2, 2}));
      },
      scratch("x.bmpx"), "extension");
  EXPECT_EQ(std::filesystem::file_size(path), before);
  EXPECT_EQ(sl::data::read_image(path).shape(), (sl::Shape{3, 4, 4}));
  EXPECT_FALSE(has_temporary_files(sl::test::scratch_dir().string()));
}

TEST(ImageIo, KittiDepthPngStoresMetresTimes256WithZeroAsMissing) {
  const std::string path = scratch("depth.png");
  sl::Tensor d = sl::Tensor::from_vector({0.0, 2.5, 76.6, std::nan(""), INFINITY, -1.0, 255.99, 1e-4},
                                         {1, 2, 4});
  sl::data::write_depth(path, d);
  EXPECT_EQ(sl::data::read_image_info(path).bits, 16);
  const auto zero = sl::data::read_depth(path).to_vector();
  const auto nan = sl::data::read_depth(path, sl::data::MissingDepth::NaN).to_vector();
  const double expected[] = {0, 2.5, std::round(76.6 * 256) / 256, 0, 0, 0, std::round(255.99 * 256) / 256,
                             1.0 / 256};
  for (int i = 0; i < 8; ++i) {
    EXPECT_NEAR(zero[i], expected[i], 1e-6) << i;
    if (expected[i] == 0) EXPECT_TRUE(std::isnan(nan[i])) << i;
    else EXPECT_EQ(nan[i], zero[i]) << i;
  }
  expect_error_naming([&] { sl::data::write_depth(path, sl::Tensor::full({1, 1, 1}, 300.0)); }, path, "300");
  expect_error_naming([&] { sl::data::read_depth(scratch("rgba.png")); }, scratch("rgba.png"));
}

TEST(ImageIo, ExrDepthKeepsMetresAndMarksHoles) {
  const std::string path = scratch("depth.exr");
  sl::data::write_depth(path, sl::Tensor::from_vector({0.0, 1234.5, std::nan(""), 3.25}, {2, 2}));
  const auto v = sl::data::read_depth(path, sl::data::MissingDepth::NaN, 2, 2).to_vector();
  EXPECT_TRUE(std::isnan(v[0]));
  EXPECT_EQ(v[1], 1234.5);
  EXPECT_TRUE(std::isnan(v[2]));
  EXPECT_EQ(v[3], 3.25);
  EXPECT_EQ(sl::data::read_depth(path).to_vector()[2], 0.0);
  expect_error_naming([&] { sl::data::read_depth(path, sl::data::MissingDepth::Zero, 3, 2); }, path);
}

TEST(ImageIo, ReadsTheRealKittiPhotograph) {
  const std::string path = sl::test::shared_data("street/kitti_000008/000008.png");
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "shared data absent: " << path;
  const sl::Tensor img = sl::data::read_image(path, {.channels = 3});
  EXPECT_EQ(img.shape(), (sl::Shape{3, 375, 1242}));
  double mean = 0;
  for (double x : img.to_vector()) mean += x;
  mean /= static_cast<double>(img.numel());
  EXPECT_GT(mean, 0.02);
  EXPECT_LT(mean, 0.8);
}

// A phone's photo: stored rows and an EXIF Orientation tag. With `upright` the tensor is the picture
// as a viewer shows it. The expected pictures of the stored rows [[1 2 3] [4 5 6]] are those of
// PIL's ImageOps.exif_transpose, an independent implementation of the tag.
TEST(ImageIo, UprightAppliesEveryExifOrientation) {
  const std::vector<std::vector<std::vector<int>>> upright = {
      {{1, 2, 3}, {4, 5, 6}}, {{3, 2, 1}, {6, 5, 4}}, {{6, 5, 4}, {3, 2, 1}}, {{4, 5, 6}, {1, 2, 3}},
      {{1, 4}, {2, 5}, {3, 6}}, {{4, 1}, {5, 2}, {6, 3}}, {{6, 3}, {5, 2}, {4, 1}}, {{3, 6}, {2, 5}, {1, 4}}};
  const sl::Tensor stored = sl::Tensor::from_vector({40 / 255.0, 80 / 255.0, 120 / 255.0, 160 / 255.0, 200 / 255.0, 240 / 255.0}, {1, 2, 3});
  for (int o = 1; o <= 8; ++o) {
    SCOPED_TRACE("orientation " + std::to_string(o));
    const std::string path = sl::test::scratch("orientation_" + std::to_string(o) + ".tif");
    sl::test::write_exif_photo(path, stored, o);
    EXPECT_EQ(sl::data::read_image_info(path).orientation, o);
    sl::data::ImageReadOptions ro{.transfer = sl::data::Transfer::Linear, .channels = 1};
    const auto expect_picture = [](const sl::Tensor& t, const std::vector<std::vector<int>>& want) {
      ASSERT_EQ(t.shape(), (sl::Shape{1, int64_t(want.size()), int64_t(want[0].size())}));
      const auto v = t.to_vector();
      for (size_t r = 0; r < want.size(); ++r)
        for (size_t c = 0; c < want[0].size(); ++c)
          EXPECT_NEAR(v[r * want[0].size() + c] * 255.0 / 40.0, want[r][c], 1e-5) << r << "," << c;
    };
    expect_picture(sl::data::read_image(path, ro), upright[0]);  // without upright: the stored rows
    ro.upright = true;
    const auto& want = upright[static_cast<size_t>(o - 1)];
    expect_picture(sl::data::read_image(path, ro), want);
    // The size check is of the upright picture.
    ro.width = static_cast<int>(want[0].size()), ro.height = static_cast<int>(want.size());
    EXPECT_NO_THROW(sl::data::read_image(path, ro));
    if (o >= 5) {
      ro.width = 3, ro.height = 2;
      expect_error_naming([&] { sl::data::read_image(path, ro); }, path, "2x3 upright");
    }
  }
}

TEST(ImageIo, InfoReadsTheExif35mmFocalLengthAndAnAbsentOneIsZero) {
  const sl::Tensor img = random_image(3, 8, 12, 0.0, 1.0, 3);
  const std::string with = sl::test::scratch("focal_26.jpg"), without = sl::test::scratch("focal_none.png");
  sl::test::write_exif_photo(with, img, 1, 26);
  sl::data::write_image(without, img);
  EXPECT_EQ(sl::data::read_image_info(with).focal_35mm, 26.0);
  EXPECT_EQ(sl::data::read_image_info(with).orientation, 1);
  EXPECT_EQ(sl::data::read_image_info(without).focal_35mm, 0.0);
  EXPECT_EQ(sl::data::read_image_info(without).orientation, 1);
}

}  // namespace sl::test
