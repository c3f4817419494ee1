// The KITTI reader on the real frame 000008 (../shared/data/street/kitti_000008/).
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "data/kitti.h"
#include "support/test_files.h"

using sl::data::densify_depth;
using sl::data::GroundPlane;
using sl::data::KittiCalibration;
using sl::data::KittiFrame;
using sl::data::KittiLidar;
using sl::data::load_kitti_frame;
using sl::data::load_kitti_lidar;
using sl::data::read_kitti_calibration;
using sl::data::read_velodyne;

namespace sl::test {
namespace {

std::string kitti(const std::string& f) { return test::shared_data("street/kitti_000008/" + f); }

#define SKIP_WITHOUT_KITTI()                                                    \
  if (!std::filesystem::exists(kitti("000008.png")))                            \
  GTEST_SKIP() << "shared data " << kitti("") << " is absent"

TEST(Kitti, LidarGivesSparseMetricDepth) {
  SKIP_WITHOUT_KITTI();
  const KittiFrame f = load_kitti_frame(kitti("000008.png"), kitti("000008_calib.json"), kitti("000008_velodyne.bin"));
  EXPECT_EQ(f.points.size(), 17238u);
  EXPECT_EQ(f.image.shape(), (Shape{3, 375, 1242}));
  EXPECT_NEAR(f.calibration.p2.intrinsics.fx, 721.5377, 1e-9);
  ASSERT_EQ(f.sparse_depth.shape(), (Shape{375, 1242}));
  const float* d = f.sparse_depth.data<float>();
  float lo = 1e9f, hi = 0.0f;
  int valid = 0;
  for (int64_t i = 0; i < f.sparse_depth.numel(); ++i)
    if (d[i] > 0.0f) lo = std::min(lo, d[i]), hi = std::max(hi, d[i]), ++valid;
  EXPECT_GT(valid, 10000);  // most points land on distinct pixels
  EXPECT_NEAR(lo, 2.6, 0.2);
  EXPECT_NEAR(hi, 76.6, 0.5);
  // The same depth as the file's own lidar2img (P2 · lidar2cam): spot-check the first points.
  std::ifstream js(kitti("000008_calib.json"));
  const auto j = nlohmann::json::parse(js);
  const auto& m = j["data_list"][0]["images"]["CAM2"]["lidar2img"];
  for (size_t i = 0; i < 50; ++i) {
    const glm::vec4& p = f.points[i];
    const double z = m[2][0].get<double>() * p.x + m[2][1].get<double>() * p.y + m[2][2].get<double>() * p.z +
                     m[2][3].get<double>();
    const double u = (m[0][0].get<double>() * p.x + m[0][1].get<double>() * p.y + m[0][2].get<double>() * p.z +
                      m[0][3].get<double>()) / z;
    const double v = (m[1][0].get<double>() * p.x + m[1][1].get<double>() * p.y + m[1][2].get<double>() * p.z +
                      m[1][3].get<double>()) / z;
    const long c = std::lround(u), r = std::lround(v);
    if (z <= 0.5 || c < 0 || r < 0 || c >= 1242 || r >= 375) continue;
    EXPECT_LE(d[r * 1242 + c], z + 1e-3);  // the pixel keeps the nearest point
  }
}

TEST(Kitti, DensifiedDepthFillsTheRoadAndKeepsTheSky) {
  SKIP_WITHOUT_KITTI();
  const KittiFrame f = load_kitti_frame(kitti("000008.png"), kitti("000008_calib.json"), kitti("000008_velodyne.bin"));
  GroundPlane g;
  const Tensor dense = densify_depth(f.sparse_depth, f.calibration.p2.intrinsics, f.camera_points, {}, &g);
  ASSERT_TRUE(g.found);
  EXPECT_NEAR(g.c, 1.65, 0.15);  // KITTI's camera is ~1.65 m above the road
  const float* d = dense.data<float>();
  int bottom_filled = 0, top_filled = 0;
  for (int c = 0; c < 1242; ++c) {
    bottom_filled += d[370 * 1242 + c] > 0.0f;
    top_filled += d[2 * 1242 + c] > 0.0f;
  }
  EXPECT_GT(bottom_filled, 1200);  // the road below the lidar's field of view is filled
  EXPECT_LT(top_filled, 100);      // the top rows (above the lidar) stay empty
  for (int64_t i = 0; i < dense.numel(); ++i) ASSERT_TRUE(std::isfinite(d[i]) && d[i] >= 0.0f);
}

TEST(Kitti, TextProjectionAndBadVelodyne) {
  SKIP_WITHOUT_KITTI();
  const KittiCalibration c = read_kitti_calibration(kitti("000008.txt"), 1242, 375);
  EXPECT_NEAR(c.p2.intrinsics.cy, 172.854, 1e-9);
  EXPECT_FALSE(c.has_lidar);
  const std::string bad = test::scratch("bad.bin");
  test::write_bytes(bad, std::string(17, '\0'));
  try {
    read_velodyne(bad);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("bad.bin"), std::string::npos);
  }
  EXPECT_THROW(load_kitti_frame(kitti("000008.png"), kitti("000008.txt"), kitti("000008_velodyne.bin")), Error);
}

// The lidar of a photo already read (streetlight-insert --lidar reads the photo once, upright) is
// the frame's own, bit for bit; a size the calibration does not fit is refused, naming the file.
TEST(Kitti, LidarOfAPhotoAlreadyReadIsTheFramesOwn) {
  SKIP_WITHOUT_KITTI();
  const KittiFrame f = load_kitti_frame(kitti("000008.png"), kitti("000008_calib.json"), kitti("000008_velodyne.bin"));
  const KittiLidar l = load_kitti_lidar(kitti("000008_calib.json"), kitti("000008_velodyne.bin"), 1242, 375);
  ASSERT_EQ(l.points.size(), f.points.size());
  ASSERT_EQ(l.camera_points.size(), f.camera_points.size());
  for (size_t i = 0; i < l.camera_points.size(); ++i) ASSERT_EQ(l.camera_points[i], f.camera_points[i]) << i;
  ASSERT_EQ(l.sparse_depth.shape(), f.sparse_depth.shape());
  EXPECT_TRUE(std::equal(l.sparse_depth.data<float>(), l.sparse_depth.data<float>() + l.sparse_depth.numel(),
                         f.sparse_depth.data<float>()));
  const KittiLidar none = load_kitti_lidar(kitti("000008_calib.json"), "", 1242, 375);
  EXPECT_TRUE(none.points.empty());
  EXPECT_FALSE(none.sparse_depth.defined());
  EXPECT_NEAR(none.calibration.p2.intrinsics.fx, 721.5377, 1e-9);
  try {
    load_kitti_lidar(kitti("000008_calib.json"), kitti("000008_velodyne.bin"), 375, 1242);  // turned a quarter
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("000008_calib.json"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace sl::test
