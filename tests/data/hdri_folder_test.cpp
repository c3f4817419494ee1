#include "data/hdri_folder.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "data/image_io.h"
#include "data/panorama.h"
#include "data/sun_extraction.h"
#include "support/test_files.h"
#include "util/math.h"

using sl::data::HdriFolder;

namespace sl::test {

namespace {

double angle_deg(const glm::dvec3& a, const glm::dvec3& b) {
  return std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b)) * 180.0 / sl::kPi;
}

}  // namespace

TEST(HdriFolder, ListsOnlyHdrAndExrFilesInSortedOrder) {
  const auto dir = sl::test::scratch_dir() / "hdri_list";
  std::filesystem::create_directories(dir);
  const sl::Tensor pano = sl::Tensor::uniform({3, 8, 16}, 0.1, 1.0, 3);
  sl::data::write_image((dir / "b.exr").string(), pano);
  sl::data::write_image((dir / "a.hdr").string(), pano);
  sl::data::write_image((dir / "C.EXR").string(), pano);
  sl::data::write_image((dir / "d.png").string(), pano);
  std::filesystem::create_directories(dir / "sub.hdr");
  const sl::data::HdriFolder folder(dir.string());
  ASSERT_EQ(folder.size(), 3u);
  EXPECT_EQ(std::filesystem::path(folder.path(0)).filename(), "C.EXR");
  EXPECT_EQ(std::filesystem::path(folder.path(1)).filename(), "a.hdr");
  EXPECT_EQ(std::filesystem::path(folder.path(2)).filename(), "b.exr");
  EXPECT_EQ(folder.load(2).to_vector(), pano.to_vector());
  EXPECT_THROW(folder.path(3), sl::Error);
  EXPECT_THROW(sl::data::HdriFolder((dir / "missing").string()), sl::Error);
  std::filesystem::create_directories(dir / "empty");
  EXPECT_THROW(sl::data::HdriFolder((dir / "empty").string()), sl::Error);
}

TEST(HdriFolder, AugmentationIsSeededAndRotatesBothImageAndSun) {
  sl::Tensor pano = sl::Tensor::full({3, 32, 64}, 1.0);
  for (int c = 0; c < 3; ++c) pano.data<float>()[(c * 32 + 10) * 64 + 40] = 1e5f;
  const sl::data::SunEstimate before = sl::data::extract_sun(pano);
  const sl::data::HdriAugmentation aug{.rotate = true, .whole_pixel_rotation = true, .exposure_stops = 2.0};
  bool any_rotation = false;
  for (uint64_t seed = 0; seed < 8; ++seed) {
    const sl::data::AugmentedPanorama a = sl::data::augment_panorama(pano, seed, 1, aug);
    const sl::data::AugmentedPanorama b = sl::data::augment_panorama(pano, seed, 1, aug);
    EXPECT_EQ(a.image.to_vector(), b.image.to_vector());
    EXPECT_GE(a.exposure, 0.25);
    EXPECT_LE(a.exposure, 4.0);
    any_rotation |= a.azimuth_rad != 0.0;
    const sl::data::SunEstimate after = sl::data::extract_sun(a.image);
    EXPECT_LT(angle_deg(after.direction, sl::data::rotate_direction_azimuth(before.direction, a.azimuth_rad)), 1e-6);
    EXPECT_NEAR(sl::data::radiant_power(a.image, 0), a.exposure * sl::data::radiant_power(pano, 0),
                1e-5 * a.exposure * sl::data::radiant_power(pano, 0));
  }
  EXPECT_TRUE(any_rotation);
  const sl::data::AugmentedPanorama none =
      sl::data::augment_panorama(pano, 3, 1, {.rotate = false, .exposure_stops = 0.0});
  EXPECT_EQ(none.image.to_vector(), pano.to_vector());
}

TEST(HdriFolder, ReadsTheSharedHdris) {
  const std::string dir = sl::test::shared_data("hdri");
  if (!std::filesystem::exists(dir)) GTEST_SKIP() << "shared data absent: " << dir;
  const sl::data::HdriFolder folder(dir);
  // The folder grows over time: select files by name and assert properties, not counts.
  size_t index = folder.size();
  for (size_t i = 0; i < folder.size(); ++i) {
    const std::string name = std::filesystem::path(folder.path(i)).filename().string();
    EXPECT_TRUE(name.ends_with(".hdr") || name.ends_with(".exr")) << name;
    if (i > 0) {
      EXPECT_LT(folder.path(i - 1), folder.path(i)) << "files are listed in sorted order";
    }
    if (name == "chinese_garden_1k.hdr") index = i;
  }
  ASSERT_LT(index, folder.size()) << "chinese_garden_1k.hdr is missing from " << dir;
  const sl::data::AugmentedPanorama a = folder.load_augmented(index, 42);
  EXPECT_EQ(a.image.shape(), (sl::Shape{3, 512, 1024}));
  // An OpenEXR panorama reads as well as a Radiance one, when the folder has one.
  for (size_t i = 0; i < folder.size(); ++i)
    if (folder.path(i).ends_with(".exr")) {
      const sl::Tensor exr = folder.load(i);
      EXPECT_EQ(exr.size(0), 3);
      EXPECT_EQ(exr.size(2), 2 * exr.size(1)) << folder.path(i);
      break;
    }
}

}  // namespace sl::test
