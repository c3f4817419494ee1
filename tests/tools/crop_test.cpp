// streetlight-crop: the view of a panorama with a labelled sun shows the sun at the pixel the tool
// reports, its intrinsics JSON is what streetlight-insert reads, and bad input gets one line,
// exit 2 and no output file.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "data/image_io.h"
#include "render/equirect.h"
#include "support/tool_fixture.h"
#include "train/photo_input.h"
#include "util/math.h"

namespace sl::test {
namespace {

namespace fs = std::filesystem;

// An 8-bit panorama (grey street, blue sky) with a clipped disk around (azimuth, elevation), and
// its sun_labels.csv row in the 2048×1024 label frame.
void write_panorama(const std::string& dir, double azimuth_deg, double elevation_deg) {
  const int w = 512, h = 256;
  const glm::dvec3 sun(std::cos(elevation_deg * kDegToRad) * std::sin(azimuth_deg * kDegToRad),
                       std::sin(elevation_deg * kDegToRad),
                       -std::cos(elevation_deg * kDegToRad) * std::cos(azimuth_deg * kDegToRad));
  Tensor t = Tensor::empty({3, h, w});
  float* p = t.data<float>();
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) {
      const auto d = render::equirect::uv_to_direction(c + 0.5, r + 0.5, w, h);
      const bool disk = d.x * sun.x + d.y * sun.y + d.z * sun.z >= std::cos(2.0 * kDegToRad);
      const float sky[3] = {0.45f, 0.6f, 0.85f}, ground[3] = {0.35f, 0.33f, 0.3f};
      for (int ch = 0; ch < 3; ++ch) p[(ch * h + r) * w + c] = disk ? 1.0f : (d.y > 0 ? sky[ch] : ground[ch]);
    }
  data::ImageWriteOptions wo;
  wo.transfer = data::Transfer::Linear;
  data::write_image(dir + "/street.png", t, wo);
  const auto uv = render::equirect::direction_to_uv(sun.x, sun.y, sun.z, 2048, 1024);
  std::ofstream(dir + "/sun_labels.csv") << "file,sun,u,v,confidence,scene,note\nstreet.png,visible," << uv.u << ","
                                         << uv.v << ",high,street,\n";
}

TEST(CropTool, TheViewShowsTheLabelledSunWhereItSaysAndInsertReadsItsIntrinsics) {
  if (!tool_built("streetlight-crop")) GTEST_SKIP() << "streetlight-crop not built";
  const std::string dir = tool_dir("crop_sun");
  write_panorama(dir, 30.0, 12.0);
  const ToolRun r = run_tool("streetlight-crop", "--panorama " + dir + "/street.png --out " + dir +
                                                     "/view.png --yaw 20 --pitch 5 --fov 60 --width 160 --height 90 --json");
  ASSERT_EQ(r.code, 0) << r.out;
  const size_t at = r.out.find('{');  // stdout's JSON line, beside the log line on stderr
  ASSERT_NE(at, std::string::npos) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out.substr(at, r.out.find('\n', at) - at));
  ASSERT_TRUE(j["sun"]["in_view"].get<bool>()) << j.dump();
  const double su = j["sun"]["pixel"][0].get<double>(), sv = j["sun"]["pixel"][1].get<double>();
  data::ImageReadOptions ro;
  ro.transfer = data::Transfer::Linear;
  const Tensor v = data::read_image(dir + "/view.png", ro).contiguous();
  ASSERT_EQ(v.size(1), 90);
  ASSERT_EQ(v.size(2), 160);
  const float* p = v.data<float>();
  const int64_t plane = 90 * 160;
  double u = 0, vv = 0, n = 0;
  for (int64_t i = 0; i < plane; ++i)
    if (p[i] + p[plane + i] + p[2 * plane + i] > 2.95f) u += i % 160 + 0.5, vv += i / 160 + 0.5, n += 1;
  ASSERT_GT(n, 0);
  EXPECT_NEAR(u / n, su, 1.0);
  EXPECT_NEAR(vv / n, sv, 1.0);
  // Above the horizon the view is sky-blue, below it street-grey: the pitch's sign is right.
  EXPECT_GT(p[2 * plane + 5 * 160 + 5], p[5 * 160 + 5]);
  EXPECT_LT(std::abs(p[2 * plane + 85 * 160 + 5] - p[85 * 160 + 5]), 0.1f);
  const render::Intrinsics k = train::read_intrinsics(dir + "/view.json", 160, 90);
  EXPECT_NEAR(k.horizontal_fov_rad(), 60.0 * kDegToRad, 1e-9);
}

TEST(CropTool, BadInputGetsOneLineExitTwoAndNoFile) {
  if (!tool_built("streetlight-crop")) GTEST_SKIP() << "streetlight-crop not built";
  const std::string dir = tool_dir("crop_bad");
  write_panorama(dir, 0.0, 30.0);
  const std::string base = "--panorama " + dir + "/street.png --out " + dir + "/out/view.png";
  expect_clean_error(run_tool("streetlight-crop", base + " --fov 200"), dir + "/out", "--fov");
  expect_clean_error(run_tool("streetlight-crop", "--panorama " + dir + "/missing.png --out " + dir + "/out/v.png"),
                     dir + "/out", "missing.png");
  std::ofstream(dir + "/other.csv") << "file,sun,u,v,confidence,scene,note\nelse.png,none,,,high,street,\n";
  expect_clean_error(run_tool("streetlight-crop", base + " --sun-labels " + dir + "/other.csv"), dir + "/out",
                     "other.csv");
  expect_clean_error(run_tool("streetlight-crop", "--panorama " + dir + "/street.png --out " + dir + "/out/view.tif"),
                     dir + "/out", ".tif");
}

}  // namespace
}  // namespace sl::test
