// streetlight-render: the panorama orientation seen in a mirror sphere, budgets,
// and bad input (one line "error: ...", exit 2, no output file).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "data/image_io.h"
#include "render/equirect.h"
#include "render/gltf_writer.h"
#include "render/primitives.h"
#include "support/tool_fixture.h"
#include "util/math.h"

using sl::data::read_image;
using sl::data::write_image;
using sl::render::make_icosphere;
using sl::render::Material;
using sl::render::write_glb;

namespace sl::test {
namespace {

namespace fs = std::filesystem;

glm::dvec3 direction(double azimuth_deg, double elevation_deg) {
  const double a = azimuth_deg * kDegToRad, e = elevation_deg * kDegToRad;
  return {std::cos(e) * std::sin(a), std::sin(e), -std::cos(e) * std::cos(a)};  // render/equirect.h
}

// A black panorama with a red, a green and a blue disc (12° radius) at the given directions,
// painted by the panorama convention of render/equirect.h.
void marker_hdri(const std::string& path, const glm::dvec3 dirs[3]) {
  const int W = 128, H = 64;
  Tensor t = Tensor::zeros({3, H, W});
  for (int i = 0; i < H; ++i)
    for (int j = 0; j < W; ++j) {
      const auto d = render::equirect::uv_to_direction(j + 0.5, i + 0.5, W, H);
      for (int c = 0; c < 3; ++c)
        if (d.x * dirs[c].x + d.y * dirs[c].y + d.z * dirs[c].z > std::cos(12 * kDegToRad))
          t.data<float>()[(c * H + i) * W + j] = 4.0f;
    }
  write_image(path, t);
}

// Where a unit mirror sphere at the origin, seen from (0, 0, 4) looking down −Z with a 40°
// horizontal field of view on S×S pixels, reflects direction m: the pixel whose centre ray
// reflects closest to m (analytic ray-sphere intersection, independent of the renderer).
glm::dvec2 expected_pixel(const glm::dvec3& m, int S) {
  const double f = 0.5 * S / std::tan(20 * kDegToRad);
  double best = -2;
  glm::dvec2 at(-1);
  for (int r = 0; r < S; ++r)
    for (int c = 0; c < S; ++c) {
      const glm::dvec3 d = glm::normalize(glm::dvec3((c + 0.5 - 0.5 * S) / f, -(r + 0.5 - 0.5 * S) / f, -1.0));
      const glm::dvec3 o(0, 0, 4);
      const double b = glm::dot(o, d), disc = b * b - (glm::dot(o, o) - 1.0);
      if (disc <= 0) continue;
      const glm::dvec3 n = glm::normalize(o + (-b - std::sqrt(disc)) * d);
      const double score = glm::dot(d - 2.0 * glm::dot(d, n) * n, m);
      if (score > best) best = score, at = {c + 0.5, r + 0.5};
    }
  return at;
}

// Centroid of the pixels where channel c dominates the image.
glm::dvec2 marker_centroid(const Tensor& img, int c) {
  const int H = int(img.size(1)), W = int(img.size(2));
  glm::dvec2 sum(0.0);
  double mass = 0.0;
  for (int r = 0; r < H; ++r)
    for (int col = 0; col < W; ++col) {
      const float v = img.data<float>()[(c * H + r) * W + col];
      float others = 0.0f;
      for (int k = 0; k < 3; ++k)
        if (k != c) others = std::max(others, img.data<float>()[(k * H + r) * W + col]);
      if (v > 0.5f && v > 4.0f * others) sum += double(v) * glm::dvec2(col + 0.5, r + 0.5), mass += v;
    }
  return mass > 0 ? sum / mass : glm::dvec2(-100.0);
}

struct MirrorScene {
  std::string dir, hdri, sphere;
  glm::dvec3 dirs[3] = {direction(90, 0), direction(0, 89), direction(180, 25)};  // +X, zenith, behind the camera
  MirrorScene() {
    // One folder per test: ctest runs the tests of this file in parallel processes, and a
    // shared folder let one test's set-up delete another's files.
    dir = test::tool_dir(std::string("render_") + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    hdri = dir + "/markers.exr";
    sphere = dir + "/mirror.glb";
    marker_hdri(hdri, dirs);
    Material mirror;
    mirror.base_color_factor = glm::vec4(1.0f);
    mirror.metallic = 1.0f;
    mirror.roughness = 0.0f;
    write_glb(make_icosphere({0, 0, 0}, 1.0f, 5, mirror), sphere);
  }
  std::string args(const std::string& out, const std::string& extra = "", int spp = 16) const {
    return "--scene " + sphere + " --hdri " + hdri + " --cam 0,0,4 --look 0,0,0 --fov 40 --width 64 --height 64 " +
           "--spp " + std::to_string(spp) + " --out " + out + " " + extra;
  }
};

TEST(RenderTool, MarkersSeenInAMirrorSphereLandWhereThePanoramaConventionSays) {
  if (!test::tool_built("streetlight-render")) GTEST_SKIP() << "streetlight-render not built";
  const MirrorScene s;
  const std::string out = s.dir + "/mirror.exr";
  const test::ToolRun r = test::run_tool("streetlight-render", s.args(out));
  ASSERT_EQ(r.code, 0) << r.out;
  const Tensor img = read_image(out);
  const char* names[3] = {"red (+X)", "green (zenith)", "blue (behind the camera)"};
  for (int c = 0; c < 3; ++c) {
    const glm::dvec2 want = expected_pixel(s.dirs[c], 64), got = marker_centroid(img, c);
    std::printf("%s: expected pixel (%.1f, %.1f), rendered centroid (%.1f, %.1f)\n", names[c], want.x, want.y, got.x,
                got.y);
    EXPECT_LT(glm::length(got - want), 2.0) << names[c];
  }
  // Read as a photo: +X on the right of the sphere, the zenith at its top, the view behind the
  // camera in its middle.
  EXPECT_GT(marker_centroid(img, 0).x, 40.0);
  EXPECT_LT(marker_centroid(img, 1).y, 24.0);
  EXPECT_NEAR(marker_centroid(img, 2).x, 32.0, 2.0);

  // --rotate-deg 90 moves every feature by +90° of azimuth: red (+X, azimuth 90°) goes behind
  // the camera (180°), where blue was.
  const std::string rotated = s.dir + "/rotated.exr";
  ASSERT_EQ(test::run_tool("streetlight-render", s.args(rotated, "--rotate-deg 90")).code, 0);
  const glm::dvec2 red = marker_centroid(read_image(rotated), 0);
  EXPECT_LT(glm::length(red - expected_pixel(direction(180, 0), 64)), 2.0) << red.x << "," << red.y;
}

TEST(RenderTool, TimeAndNoiseBudgetsStopTheRenderAndReportIt) {
  if (!test::tool_built("streetlight-render")) GTEST_SKIP() << "streetlight-render not built";
  const MirrorScene s;
  const std::string out = s.dir + "/noise.png";
  const test::ToolRun r =
      test::run_tool("streetlight-render", s.args(out, "--target-noise 0.02 --exposure 1 --json", 4096));
  ASSERT_EQ(r.code, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out.substr(r.out.rfind('{')));
  EXPECT_LE(j["noise"].get<double>(), 0.02);
  EXPECT_GT(j["noise"].get<double>(), 0.0);
  EXPECT_LT(j["spp"].get<int>(), 4096);
  EXPECT_TRUE(fs::exists(out));
  const std::string timed = s.dir + "/timed.exr";
  const test::ToolRun t = test::run_tool("streetlight-render", s.args(timed, "--seconds 0.5 --json", 1000000));
  ASSERT_EQ(t.code, 0) << t.out;
  const nlohmann::json jt = nlohmann::json::parse(t.out.substr(t.out.rfind('{')));
  EXPECT_LT(jt["spp"].get<int>(), 1000000);
  EXPECT_TRUE(fs::exists(timed));
}

TEST(RenderTool, BadInputGetsOneErrorLineExitTwoAndNoFile) {
  if (!test::tool_built("streetlight-render")) GTEST_SKIP() << "streetlight-render not built";
  const MirrorScene s;
  const std::string out = s.dir + "/bad.exr";
  const std::string text = s.dir + "/not_an_image.hdr";
  std::ofstream(text) << "this is not an image\n";
  const std::string base = "--scene " + s.sphere + " --cam 0,0,4 --look 0,0,0 --spp 1 --width 8 --height 8 ";
  struct Case {
    std::string args, names;
  };
  const Case cases[] = {
      {base + "--hdri " + s.dir + "/missing.hdr --out " + out, "missing.hdr"},
      {base + "--hdri " + text + " --out " + out, "not_an_image.hdr"},
      {"--scene " + s.sphere + " --hdri " + s.hdri + " --cam 0,0 --look 0,0,0 --out " + out, "--cam"},
      {"--scene " + s.sphere + " --hdri " + s.hdri + " --cam 0,0,x --look 0,0,0 --out " + out, "--cam"},
      {"--scene " + s.sphere + " --hdri " + s.hdri + " --cam 0,0,4 --look 0,0,4 --out " + out, "--look"},
      {"--scene " + s.dir + "/missing.glb --hdri " + s.hdri + " --cam 0,0,4 --look 0,0,0 --out " + out, "missing.glb"},
      {"--scene " + text + " --hdri " + s.hdri + " --cam 0,0,4 --look 0,0,0 --out " + out, "not_an_image.hdr"},
      {base + "--hdri " + s.hdri + " --out " + s.dir + "/no_such_folder/x.exr", "no_such_folder"},
      {base + "--hdri " + s.hdri + " --out " + text + "/x.exr", "not_an_image.hdr"},
      {base + "--hdri " + s.hdri + " --out " + s.dir + "/bad.jpg", "bad.jpg"},
      {base + "--hdri " + s.hdri + " --out " + out + " --fov 180", "--fov"},
      {base + "--hdri " + s.hdri + " --out " + out + " --ground 2", "--ground"},
      {base + "--hdri " + s.hdri + " --out " + out + " --spp 0", "--spp"},
      {base + "--hdri " + s.hdri + " --out " + out + " --target-noise -1", "--target-noise"},
      {base + "--hdri " + s.hdri + " --out " + out + " --seconds 0", "--seconds"},
      {base + "--hdri " + s.hdri + " --out " + out + " --fresnel fancy", "--fresnel"},
      {base + "--out " + out, "--hdri"},
      {base + "--hdri " + s.hdri + " --out " + out + " --bogus 1", "--bogus"},
  };
  for (const Case& c : cases) {
    const test::ToolRun r = test::run_tool("streetlight-render", c.args);
    EXPECT_EQ(r.code, 2) << c.args << "\n" << r.out;
    EXPECT_EQ(r.out.rfind("error: ", 0), 0u) << r.out;
    EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
    EXPECT_NE(r.out.find(c.names), std::string::npos) << "error should name '" << c.names << "': " << r.out;
    EXPECT_FALSE(fs::exists(out)) << c.args;
  }
  for (const auto& e : fs::directory_iterator(s.dir))
    EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path();
  const test::ToolRun help = test::run_tool("streetlight-render", "--help");
  EXPECT_EQ(help.code, 0);
  EXPECT_NE(help.out.find("--target-noise"), std::string::npos);
}

}  // namespace
}  // namespace sl::test
