// streetlight-insert end to end on a tiny synthetic photo with a random-weight checkpoint, and
// every bad input the tool documents: one line "error: ...", exit 2, and no output folder left behind.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "data/image_io.h"
#include "autodiff/ops.h"
#include "data/procedural_car.h"
#include "render/gltf_writer.h"
#include "train/photo_insertion.h"
#include "util/math.h"
#include "support/exif_photo.h"
#include "support/tool_fixture.h"
#include "nn/checkpoint.h"
#include "train/lighting_predictor.h"

namespace sl::test {

namespace fs = std::filesystem;

namespace {

struct InsertCase {
  std::string dir, ckpt, base;
};

InsertCase setup(const std::string& name) {
  InsertCase c;
  c.dir = sl::test::tool_dir(name);
  c.ckpt = sl::test::tiny_lighting_checkpoint(c.dir);
  sl::test::tiny_photo(c.dir);
  c.base = " --checkpoint " + c.ckpt + " --object procedural:car --aa 1 --light-samples 4 --shadow-rays 8"
           " --shadow-width 16 --shadow-height 8 ";
  return c;
}

TEST(InsertTool, WritesEveryOutputWithTheGroundPlaneFallback) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP() << "streetlight-insert not built";
  const InsertCase c = setup("insert_ok");
  const std::string out = c.dir + "/out";
  const auto r = run_tool("streetlight-insert", "--image " + c.dir + "/photo.png --intrinsics " + c.dir +
                                                    "/intrinsics.json --at 0,8 --exr --out " + out + c.base);
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("depth: ground-plane"), std::string::npos) << r.out;
  for (const char* f : {"composite.png", "composite.exr", "object_mask.png", "shadow_map.png", "sky.exr", "sky.png",
                        "depth.exr", "result.json", "label.txt"})
    EXPECT_TRUE(fs::exists(fs::path(out) / f)) << f;
  std::ifstream jf(out + "/result.json");
  const auto j = nlohmann::json::parse(jf);
  EXPECT_EQ(j["depth_source"], "ground-plane");
  const glm::dvec3 sun(j["sun"]["direction_world"][0], j["sun"]["direction_world"][1], j["sun"]["direction_world"][2]);
  EXPECT_NEAR(glm::length(sun), 1.0, 1e-6);
  // The network's confidence: the angle between its sun and its mirror pass's (train/inference.h).
  ASSERT_TRUE(j["sun"]["flip_spread_deg"].is_number()) << j["sun"].dump();
  EXPECT_GE(j["sun"]["flip_spread_deg"].get<double>(), 0.0);
  EXPECT_LE(j["sun"]["flip_spread_deg"].get<double>(), 180.0);
  ASSERT_TRUE(j["sun"]["hedge"].is_number()) << j["sun"].dump();
  EXPECT_GE(j["sun"]["hedge"].get<double>(), 0.0);
  EXPECT_LE(j["sun"]["hedge"].get<double>(), 1.0);
  // Whether a sun disk in the photo set the direction (train/inference.h visible sun).
  ASSERT_TRUE(j["sun"]["visible_sun"]["found"].is_boolean()) << j["sun"].dump();
  if (j["sun"]["visible_sun"]["found"]) {
    EXPECT_TRUE(j["sun"]["visible_sun"]["learned"].is_boolean()) << j["sun"].dump();
  }
  EXPECT_NEAR(j["box3d"]["z"].get<double>(), 8.0, 1e-6);  // 8 m ahead in the camera frame
  EXPECT_GT(j["box2d"][2].get<double>(), j["box2d"][0].get<double>());
  EXPECT_EQ(j["kitti_label"].get<std::string>().rfind("Car ", 0), 0u);
  // What was rendered: the flags given, and the defaults' exact corrections (train/photo_insertion.h).
  EXPECT_EQ(j["insertion"]["light_samples"], 4);
  EXPECT_EQ(j["insertion"]["shadow_rays"], 8);
  EXPECT_EQ(j["insertion"]["exact_light_rays"], 2);
  EXPECT_EQ(j["insertion"]["exact_shadow_rays"], 16);
  EXPECT_EQ(j["insertion"]["radiance_cache"], true);
  const sl::Tensor comp = sl::data::read_image(out + "/composite.png");
  EXPECT_EQ(comp.size(1), 32);
  EXPECT_EQ(comp.size(2), 64);
}

// A generated street sample (docs/DATASET.md) as streetlight-datagen writes one: view 0's LDR and
// depth of a 64x32 camera looking down -Z from 1.65 m, and its inserted object, a green car 8 m ahead.
std::string green_car_sample(const std::string& dir) {
  const std::string sample = dir + "/samples/000000";
  fs::create_directories(sample);
  sl::test::tiny_photo(sample);
  fs::rename(sample + "/photo.png", sample + "/view_0_ldr.png");
  const render::Intrinsics k{.fx = 38.4, .fy = 38.4, .cx = 32, .cy = 16, .width = 64, .height = 32};
  const glm::dmat3 cam_to_world(glm::dvec3(1, 0, 0), glm::dvec3(0, -1, 0), glm::dvec3(0, 0, -1));
  const render::Camera camera(k, cam_to_world, glm::dvec3(0, 1.65, 0));
  data::write_depth(sample + "/view_0_depth.exr", unsqueeze(train::ground_plane_depth(camera), 0));
  data::ProceduralCarParams green;
  green.paint_rgb = glm::vec3(0.05f, 0.6f, 0.05f);
  render::write_glb(data::make_procedural_car(green), sample + "/object.glb");
  const nlohmann::json view = {
      {"intrinsics", {{"fx", k.fx}, {"fy", k.fy}, {"cx", k.cx}, {"cy", k.cy}, {"width", 64}, {"height", 32}}},
      {"rotation_cam_to_world", {1, 0, 0, 0, -1, 0, 0, 0, -1}},
      {"position", {0, 1.65, 0}},
      {"files", {{"ldr", "view_0_ldr.png"}, {"depth", "view_0_depth.exr"}}}};
  const nlohmann::json meta = {
      {"views", {view}},
      {"object", {{"file", "object.glb"}, {"placement", {{"x_m", 0}, {"z_m", -8}, {"yaw_deg", 90}, {"scale", 1}}}}}};
  std::ofstream(sample + "/meta.json") << meta.dump(2);
  return sample;
}

TEST(InsertTool, SampleInsertsItsOwnObjectUnlessOneIsGiven) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP() << "streetlight-insert not built";
  const std::string dir = sl::test::tool_dir("insert_sample");
  const std::string ckpt = sl::test::tiny_lighting_checkpoint(dir);
  const std::string sample = green_car_sample(dir);
  const std::string knobs = " --checkpoint " + ckpt + " --aa 1 --light-samples 4 --shadow-rays 8 --shadow-width 16"
                            " --shadow-height 8 --no-visible-sun";
  auto r = run_tool("streetlight-insert", "--sample " + sample + " --out " + dir + "/own" + knobs);
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream jf(dir + "/own/result.json");
  const auto j = nlohmann::json::parse(jf);
  EXPECT_EQ(j["object"], sample + "/object.glb");
  // The composite's object is the sample's green car, not the default red one.
  const Tensor comp = data::read_image(dir + "/own/composite.png");
  const Tensor mask = data::read_image(dir + "/own/object_mask.png");
  double red = 0, green = 0;
  for (int64_t y = 0; y < 32; ++y)
    for (int64_t x = 0; x < 64; ++x)
      if (mask.at({0, y, x}) > 0.99) red += comp.at({0, y, x}), green += comp.at({1, y, x});
  EXPECT_GT(green, 1.5 * red) << "green " << green << ", red " << red;
  r = run_tool("streetlight-insert", "--sample " + sample + " --object procedural:car --out " + dir + "/given" + knobs);
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream gf(dir + "/given/result.json");
  EXPECT_EQ(nlohmann::json::parse(gf)["object"], "procedural:car");
}

TEST(InsertTool, VersionPrintsTheRelease) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP() << "streetlight-insert not built";
  const auto r = run_tool("streetlight-insert", "--version");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(r.out.rfind("streetlight-insert ", 0), 0u) << r.out;
  EXPECT_NE(r.out.find('.'), std::string::npos) << r.out;
}

TEST(InsertTool, SunEditingMovesTheEstimatedSun) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP();
  const InsertCase c = setup("insert_sun");
  const std::string out = c.dir + "/out";
  const auto r = run_tool("streetlight-insert", "--image " + c.dir + "/photo.png --intrinsics " + c.dir +
                                                    "/intrinsics.json --at 0,8 --sun-azimuth 30 --sun-elevation 40"
                                                    " --sun-intensity 2 --out " + out + c.base);
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream jf(out + "/result.json");
  const auto j = nlohmann::json::parse(jf);
  EXPECT_NEAR(j["sun"]["azimuth_deg"].get<double>(), 30.0, 1e-3);
  EXPECT_NEAR(j["sun"]["elevation_deg"].get<double>(), 40.0, 1e-3);
  EXPECT_TRUE(j["sun"]["edited"].get<bool>());
}

// --sun-from-shadows on an analytic photo with a depth file: two boxes on the ground, the ground
// dark exactly where they block a sun at azimuth 60°, elevation 40° (a slab test).
TEST(InsertTool, SunFromShadowsTakesTheSunFromThePhotosShadows) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP();
  const InsertCase c = setup("insert_sun_shadows");
  const int W = 240, H = 120;
  const double f = 120.0, cam_h = 1.65;
  const glm::dvec3 sun(std::cos(40 * kPi / 180) * std::sin(60 * kPi / 180), std::sin(40 * kPi / 180),
                       -std::cos(40 * kPi / 180) * std::cos(60 * kPi / 180));
  const std::vector<std::pair<glm::dvec3, glm::dvec3>> boxes = {{{-3.5, 0, -12}, {-1.7, 1.5, -7.5}},
                                                                {{1.5, 0, -18}, {3.3, 1.5, -13.5}}};
  const auto hit = [&](const glm::dvec3& o, const glm::dvec3& d, const std::pair<glm::dvec3, glm::dvec3>& b) {
    double t0 = 1e-9, t1 = 1e30;
    for (int a = 0; a < 3; ++a) {
      if (std::abs(d[a]) < 1e-15) {
        if (o[a] < b.first[a] || o[a] > b.second[a]) return 1e30;
        continue;
      }
      double ta = (b.first[a] - o[a]) / d[a], tb = (b.second[a] - o[a]) / d[a];
      if (ta > tb) std::swap(ta, tb);
      t0 = std::max(t0, ta), t1 = std::min(t1, tb);
    }
    return t0 <= t1 ? t0 : 1e30;
  };
  Tensor img = Tensor::zeros({3, H, W}), depth = Tensor::zeros({1, H, W});
  for (int row = 0; row < H; ++row)
    for (int col = 0; col < W; ++col) {
      const glm::dvec3 o(0, cam_h, 0), d = glm::normalize(glm::dvec3((col + 0.5 - W / 2.0) / f, -(row + 0.5 - H / 2.0) / f, -1));
      double t = d.y < 0 ? -cam_h / d.y : 1e30;
      bool on_box = false;
      for (const auto& b : boxes)
        if (const double tb = hit(o, d, b); tb < t) t = tb, on_box = true;
      float v = 0.9f;
      if (t < 200) {
        const glm::dvec3 p = o + t * d;
        depth.data<float>()[row * W + col] = static_cast<float>(-p.z);
        bool shadow = false;
        for (const auto& b : boxes) shadow |= !on_box && hit(p + 1e-6 * sun, sun, b) < 1e29;
        v = on_box ? 0.5f : shadow ? 0.3f : 0.8f;
      }
      for (int ch = 0; ch < 3; ++ch) img.data<float>()[(ch * H + row) * W + col] = v;
    }
  data::ImageWriteOptions lin;
  lin.transfer = data::Transfer::Linear;
  data::write_image(c.dir + "/shadow_photo.png", img, lin);
  data::write_depth(c.dir + "/shadow_depth.exr", depth);
  std::ofstream(c.dir + "/shadow_intrinsics.json") << nlohmann::json{{"fx", f}, {"fy", f}, {"cx", W / 2.0}, {"cy", H / 2.0}}.dump();
  const std::string out = c.dir + "/out";
  const auto r = run_tool("streetlight-insert", "--image " + c.dir + "/shadow_photo.png --intrinsics " + c.dir +
                                                    "/shadow_intrinsics.json --depth " + c.dir +
                                                    "/shadow_depth.exr --at 0,9 --sun-from-shadows --out " + out + c.base);
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream jf(out + "/result.json");
  const auto j = nlohmann::json::parse(jf);
  ASSERT_TRUE(j.contains("sun_from_shadows")) << j.dump();
  EXPECT_TRUE(j["sun_from_shadows"]["found"].get<bool>()) << j["sun_from_shadows"].dump();
  const glm::dvec3 got(j["sun"]["direction_world"][0], j["sun"]["direction_world"][1], j["sun"]["direction_world"][2]);
  EXPECT_LT(std::acos(std::clamp(glm::dot(got, sun), -1.0, 1.0)) * 180 / kPi, 15.0) << j["sun"].dump();
  EXPECT_TRUE(j["sun"]["edited"].get<bool>());
  EXPECT_GT(j["sun_from_shadows"]["intensity_scale"].get<double>(), 0.0);
}

// Without geometry that casts a shadow (the ground-plane fallback), the network's sun stays, the
// tool says so, and result.json records the attempt.
TEST(InsertTool, SunFromShadowsWithoutGeometryKeepsTheNetworksSun) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP();
  const InsertCase c = setup("insert_sun_shadows_none");
  const std::string args = "--image " + c.dir + "/photo.png --intrinsics " + c.dir + "/intrinsics.json --at 0,8";
  const auto plain = run_tool("streetlight-insert", args + " --out " + c.dir + "/plain" + c.base);
  const auto flagged = run_tool("streetlight-insert", args + " --sun-from-shadows --out " + c.dir + "/flagged" + c.base);
  ASSERT_EQ(plain.code, 0) << plain.out;
  ASSERT_EQ(flagged.code, 0) << flagged.out;
  EXPECT_NE(flagged.out.find("warning: --sun-from-shadows found no shadow"), std::string::npos) << flagged.out;
  std::ifstream pf(c.dir + "/plain/result.json"), ff(c.dir + "/flagged/result.json");
  const auto jp = nlohmann::json::parse(pf), jf = nlohmann::json::parse(ff);
  EXPECT_FALSE(jf["sun_from_shadows"]["found"].get<bool>());
  EXPECT_EQ(jp["sun"]["direction_world"], jf["sun"]["direction_world"]);
}

// A model with a sun head (model.sun_grid) and random weights spreads its sun over the sky: its
// probability within 20° is far below one half, and the tool says the sun is a guess, with the
// probability result.json records and, for a photo without depth, the flags that set the sun by
// hand. An edited sun is no guess: no note. A model without a sun head has no probability: no note.
TEST(InsertTool, ANetworkSunItselfUnsureOfIsCalledAGuess) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP();
  const InsertCase c = setup("insert_sun_guess");
  nlohmann::json cfg = sl::test::tiny_lighting_config();
  cfg["model"]["sun_grid"] = {{"elevation_bins", 4}, {"azimuth_bins", 16}};
  const std::string ckpt = c.dir + "/sun_head.safetensors";
  nn::Module holder("LightingModel");
  holder.register_module("predictor", std::make_shared<train::LightingPredictor>(train::predictor_options(cfg)));
  nn::save_checkpoint(ckpt, holder, nullptr, nn::CheckpointInfo{.stage = "lighting", .step = 1, .config_json = cfg.dump()});
  std::string base = c.base;
  base.replace(base.find(c.ckpt), c.ckpt.size(), ckpt);  // the same flags with the sun-head model
  const std::string args = "--image " + c.dir + "/photo.png --intrinsics " + c.dir + "/intrinsics.json --at 0,8" + base;
  const auto guess = run_tool("streetlight-insert", args + " --out " + c.dir + "/guess");
  ASSERT_EQ(guess.code, 0) << guess.out;
  std::ifstream jf(c.dir + "/guess/result.json");
  const auto j = nlohmann::json::parse(jf);
  const double p = j["sun"]["probability"].get<double>();
  ASSERT_LT(p, 0.5);
  char expected[64];
  std::snprintf(expected, sizeof expected, "probability %.2f of lying within", p);
  EXPECT_NE(guess.out.find("note: the sun's direction is the model's guess"), std::string::npos) << guess.out;
  EXPECT_NE(guess.out.find(expected), std::string::npos) << guess.out;
  EXPECT_NE(guess.out.find("--sun-azimuth and --sun-elevation"), std::string::npos) << guess.out;
  const auto edited = run_tool("streetlight-insert", args + " --sun-azimuth 30 --sun-elevation 40 --out " + c.dir + "/edited");
  ASSERT_EQ(edited.code, 0) << edited.out;
  EXPECT_EQ(edited.out.find("note:"), std::string::npos) << edited.out;
  const auto no_head = run_tool("streetlight-insert", "--image " + c.dir + "/photo.png --intrinsics " + c.dir +
                                                        "/intrinsics.json --at 0,8 --out " + c.dir + "/no_head" + c.base);
  ASSERT_EQ(no_head.code, 0) << no_head.out;
  EXPECT_EQ(no_head.out.find("note:"), std::string::npos) << no_head.out;
}

TEST(InsertTool, SunFromShadowsWithAnEditedSunIsACleanError) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP();
  const InsertCase c = setup("insert_sun_shadows_conflict");
  const auto r = run_tool("streetlight-insert", "--image " + c.dir + "/photo.png --intrinsics " + c.dir +
                                                    "/intrinsics.json --at 0,8 --sun-from-shadows --sun-azimuth 30 --out " +
                                                    c.dir + "/out" + c.base);
  expect_clean_error(r, c.dir + "/out", "--sun-from-shadows");
}

// --fast: the settings before the exact corrections (train/photo_insertion.h fast_insertion_options),
// with the flags given explicitly still in force.
TEST(InsertTool, FastTakesTheFormerSettingsAndExplicitFlagsWin) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP() << "streetlight-insert not built";
  const InsertCase c = setup("insert_fast");
  const std::string out = c.dir + "/out";
  const auto r = run_tool("streetlight-insert", "--image " + c.dir + "/photo.png --intrinsics " + c.dir +
                                                    "/intrinsics.json --at 0,8 --fast --exact-shadow-rays 3 --out " +
                                                    out + c.base);
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream jf(out + "/result.json");
  const auto j = nlohmann::json::parse(jf);
  EXPECT_EQ(j["insertion"]["exact_light_rays"], 0);
  EXPECT_EQ(j["insertion"]["exact_shadow_rays"], 3);  // given explicitly
  EXPECT_EQ(j["insertion"]["light_samples"], 4);      // the fixture's --light-samples 4
}

TEST(InsertTool, BadSamplingKnobsAreCleanErrors) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP();
  const InsertCase c = setup("insert_bad_knobs");
  for (const auto& [flag, value] : std::vector<std::pair<std::string, std::string>>{
           {"--adaptive-samples", "-1"}, {"--adaptive-samples", "nan"}, {"--denoise-radius", "-2"}, {"--denoise-radius", "99"},
           {"--exact-light-rays", "-1"}, {"--exact-shadow-rays", "65"}}) {
    const auto r = run_tool("streetlight-insert", "--image " + c.dir + "/photo.png --intrinsics " + c.dir +
                                                      "/intrinsics.json --at 0,8 --out " + c.dir + "/out" + c.base + " " +
                                                      flag + " " + value);
    expect_clean_error(r, c.dir + "/out", flag);
  }
}

// --sun-glare must name a sun-glare detector: a missing file or another kind of checkpoint is one
// line and exit 2, before anything is written.
TEST(InsertTool, ABadSunGlareFileIsACleanError) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP();
  const InsertCase c = setup("insert_bad_glare");
  for (const std::string& glare : {c.dir + "/absent.safetensors", c.dir + "/intrinsics.json"}) {
    const auto r = run_tool("streetlight-insert", "--image " + c.dir + "/photo.png --intrinsics " + c.dir +
                                                      "/intrinsics.json --at 0,8 --out " + c.dir + "/out" + c.base +
                                                      " --sun-glare " + glare);
    expect_clean_error(r, c.dir + "/out", glare);
  }
}

TEST(InsertTool, MissingImageIsACleanError) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP();
  const InsertCase c = setup("insert_missing");
  const auto r = run_tool("streetlight-insert", "--image " + c.dir + "/nope.png --intrinsics " + c.dir +
                                                    "/intrinsics.json --at 0,8 --out " + c.dir + "/out" + c.base);
  expect_clean_error(r, c.dir + "/out", "nope.png");
}

TEST(InsertTool, CorruptImageIsACleanError) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP();
  const InsertCase c = setup("insert_corrupt");
  std::ofstream(c.dir + "/bad.png") << "not a png at all";
  const auto r = run_tool("streetlight-insert", "--image " + c.dir + "/bad.png --intrinsics " + c.dir +
                                                    "/intrinsics.json --at 0,8 --out " + c.dir + "/out" + c.base);
  expect_clean_error(r, c.dir + "/out", "bad.png");
}

// libpng and OpenImageIO each print their own lines for a cut-off PNG; the user gets one.
TEST(InsertTool, TruncatedPngIsOneLine) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP();
  const InsertCase c = setup("insert_truncated");
  sl::Tensor noise = sl::Tensor::uniform({3, 120, 240}, 0.0, 1.0, 7);
  sl::data::ImageWriteOptions lin;
  lin.transfer = sl::data::Transfer::Linear;
  sl::data::write_image(c.dir + "/big.png", noise, lin);
  const auto size = fs::file_size(c.dir + "/big.png");
  fs::resize_file(c.dir + "/big.png", size / 2);
  std::ofstream(c.dir + "/k.json") << R"({"fx": 150, "fy": 150, "cx": 120, "cy": 60})";
  const auto r = run_tool("streetlight-insert", "--image " + c.dir + "/big.png --intrinsics " + c.dir +
                                                    "/k.json --at 0,8 --out " + c.dir + "/out" + c.base);
  expect_clean_error(r, c.dir + "/out", "big.png");
  EXPECT_NE(r.out.find("truncated or corrupt"), std::string::npos) << r.out;
}

TEST(InsertTool, DepthOfAnotherSizeIsACleanError) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP();
  const InsertCase c = setup("insert_depth");
  sl::data::write_depth(c.dir + "/depth.exr", sl::Tensor::full({1, 16, 32}, 5.0));
  const auto r = run_tool("streetlight-insert", "--image " + c.dir + "/photo.png --intrinsics " + c.dir +
                                                    "/intrinsics.json --depth " + c.dir + "/depth.exr --at 0,8 --out " +
                                                    c.dir + "/out" + c.base);
  expect_clean_error(r, c.dir + "/out", "depth file");
}

TEST(InsertTool, IntrinsicsOfAnotherImageAreACleanError) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP();
  const InsertCase c = setup("insert_intrinsics");
  std::ofstream(c.dir + "/k.json") << R"({"fx": 700, "fy": 700, "cx": 609.5, "cy": 172.8})";
  const auto r = run_tool("streetlight-insert", "--image " + c.dir + "/photo.png --intrinsics " + c.dir +
                                                    "/k.json --at 0,8 --out " + c.dir + "/out" + c.base);
  expect_clean_error(r, c.dir + "/out", "principal point");
  std::ofstream(c.dir + "/k2.json") << R"({"fx": 40, "fy": 40, "cx": 32, "cy": 16, "width": 1242, "height": 375})";
  const auto r2 = run_tool("streetlight-insert", "--image " + c.dir + "/photo.png --intrinsics " + c.dir +
                                                     "/k2.json --at 0,8 --out " + c.dir + "/out" + c.base);
  expect_clean_error(r2, c.dir + "/out", "1242x375");
}

// A phone's JPEG: its rows stored sideways with EXIF Orientation 6, and a 35 mm-equivalent focal
// length of 26 mm, no intrinsics file. The tool turns it upright and takes the focal length from the
// EXIF (the diagonal of the 35 mm frame, 43.27 mm, spans the image's); --fov sets a field of view
// instead; a photo with neither is a clean error naming it.
TEST(InsertTool, APhonePhotoNeedsNoIntrinsicsFile) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP();
  const InsertCase c = setup("insert_phone");
  const sl::Tensor up = sl::data::read_image(c.dir + "/photo.png", {.transfer = sl::data::Transfer::Linear});
  const int64_t H = up.size(1), W = up.size(2);  // 32 x 64 upright; stored 64 rows of 32
  sl::Tensor stored = sl::Tensor::empty({3, W, H});
  const auto u = up.to_vector();
  float* s = stored.data<float>();
  for (int64_t ch = 0; ch < 3; ++ch)
    for (int64_t sr = 0; sr < W; ++sr)
      for (int64_t sc = 0; sc < H; ++sc)  // orientation 6 shows stored (sr, sc) at upright (sc, W - 1 - sr)
        s[(ch * W + sr) * H + sc] = static_cast<float>(u[static_cast<size_t>((ch * H + sc) * W + (W - 1 - sr))]);
  sl::test::write_exif_photo(c.dir + "/phone.jpg", stored, 6, 26);
  const std::string out = c.dir + "/out";
  const auto r = run_tool("streetlight-insert", "--image " + c.dir + "/phone.jpg --at 0,8 --out " + out + c.base);
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("intrinsics: from the photo's EXIF"), std::string::npos) << r.out;
  std::ifstream jf(out + "/result.json");
  const auto j = nlohmann::json::parse(jf);
  EXPECT_EQ(j["intrinsics"]["source"], "exif");
  const double f = 26.0 * std::sqrt(double(W * W + H * H)) / 43.266615305567875;
  EXPECT_NEAR(j["intrinsics"]["fx"].get<double>(), f, 1e-9);
  EXPECT_NEAR(j["intrinsics"]["fy"].get<double>(), f, 1e-9);
  EXPECT_EQ(j["intrinsics"]["cx"].get<double>(), W / 2.0);
  EXPECT_EQ(j["intrinsics"]["cy"].get<double>(), H / 2.0);
  const sl::Tensor comp = sl::data::read_image(out + "/composite.png", {.transfer = sl::data::Transfer::Linear});
  ASSERT_EQ(comp.shape(), (sl::Shape{3, H, W})) << "the composite is the upright picture";
  const auto v = comp.to_vector();
  EXPECT_GT(v[0], v[static_cast<size_t>((H - 1) * W)]) << "the photo's bright sky stays at the top";

  const std::string out2 = c.dir + "/out_fov";
  const auto r2 = run_tool("streetlight-insert", "--image " + c.dir + "/photo.png --fov 90 --at 0,8 --out " + out2 + c.base);
  ASSERT_EQ(r2.code, 0) << r2.out;
  std::ifstream jf2(out2 + "/result.json");
  const auto j2 = nlohmann::json::parse(jf2);
  EXPECT_EQ(j2["intrinsics"]["source"], "fov");
  EXPECT_NEAR(j2["intrinsics"]["fx"].get<double>(), W / 2.0, 1e-9);  // tan(45°) = 1

  const auto r3 = run_tool("streetlight-insert", "--image " + c.dir + "/photo.png --at 0,8 --out " + c.dir + "/out3" + c.base);
  expect_clean_error(r3, c.dir + "/out3", "photo.png");
  EXPECT_NE(r3.out.find("--fov"), std::string::npos) << r3.out;
  for (const char* bad : {"0", "180", "-5", "nan"}) {
    const auto r4 = run_tool("streetlight-insert", "--image " + c.dir + "/photo.png --fov " + std::string(bad) +
                                                       " --at 0,8 --out " + c.dir + "/out4" + c.base);
    expect_clean_error(r4, c.dir + "/out4", "--fov");
  }
}

// --at-pixel U,V stands the object on what that pixel shows: here the ground plane seen from 1.65 m
// by a level camera (fx = fy = 38.4, principal point (32, 16)), so pixel (32, 28)'s centre lies
// 1.65 · 38.4 / 12.5 m ahead and 0.5 / 38.4 of that to the right. A sky pixel, or --at with it, is a
// clean error.
TEST(InsertTool, AtPixelStandsTheObjectOnWhatThePixelShows) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP();
  const InsertCase c = setup("insert_at_pixel");
  const std::string out = c.dir + "/out", in = " --image " + c.dir + "/photo.png --intrinsics " + c.dir + "/intrinsics.json";
  const auto r = run_tool("streetlight-insert", in + " --at-pixel 32,28 --out " + out + c.base);
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream jf(out + "/result.json");
  const auto j = nlohmann::json::parse(jf);
  const double forward = 1.65 * 38.4 / 12.5;
  EXPECT_NEAR(j["placement"]["at_camera_ground_xz"][1].get<double>(), forward, 1e-6);
  EXPECT_NEAR(j["placement"]["at_camera_ground_xz"][0].get<double>(), 0.5 / 38.4 * forward, 1e-6);
  EXPECT_NEAR(j["box3d"]["z"].get<double>(), forward, 1e-6);
  const auto sky = run_tool("streetlight-insert", in + " --at-pixel 32,3 --out " + c.dir + "/out2" + c.base);
  expect_clean_error(sky, c.dir + "/out2", "sees no surface");
  EXPECT_NE(sky.out.find("--at-pixel 32,3"), std::string::npos) << sky.out;
  const auto both = run_tool("streetlight-insert", in + " --at 0,8 --at-pixel 32,28 --out " + c.dir + "/out3" + c.base);
  expect_clean_error(both, c.dir + "/out3", "not both");
  const auto bad = run_tool("streetlight-insert", in + " --at-pixel 32 --out " + c.dir + "/out4" + c.base);
  expect_clean_error(bad, c.dir + "/out4", "'U,V'");
}

TEST(InsertTool, ObjectBehindTheCameraIsACleanError) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP();
  const InsertCase c = setup("insert_behind");
  const auto r = run_tool("streetlight-insert", "--image " + c.dir + "/photo.png --intrinsics " + c.dir +
                                                    "/intrinsics.json --at 0,-6 --out " + c.dir + "/out" + c.base);
  expect_clean_error(r, c.dir + "/out", "behind the camera");
}

TEST(InsertTool, ObjectOffTheGroundIsACleanError) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP();
  const InsertCase c = setup("insert_offground");
  // A depth map with no surface at all: nothing to stand on.
  sl::data::write_depth(c.dir + "/depth.exr", sl::Tensor::zeros({1, 32, 64}));
  const auto r = run_tool("streetlight-insert", "--image " + c.dir + "/photo.png --intrinsics " + c.dir +
                                                    "/intrinsics.json --depth " + c.dir + "/depth.exr --at 0,8 --out " +
                                                    c.dir + "/out" + c.base);
  expect_clean_error(r, c.dir + "/out", "not on the ground");
}

TEST(InsertTool, CompressedGltfIsACleanError) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP();
  const InsertCase c = setup("insert_draco");
  std::ofstream(c.dir + "/draco.gltf")
      << R"({"asset": {"version": "2.0"}, "extensionsUsed": ["KHR_draco_mesh_compression"],
             "extensionsRequired": ["KHR_draco_mesh_compression"], "meshes": [], "nodes": [], "scenes": [{"nodes": []}]})";
  const auto r = run_tool("streetlight-insert", "--image " + c.dir + "/photo.png --intrinsics " + c.dir +
                                                    "/intrinsics.json --at 0,8 --out " + c.dir + "/out --checkpoint " +
                                                    c.ckpt + " --object " + c.dir + "/draco.gltf");
  expect_clean_error(r, c.dir + "/out", "draco");
}

// A real exporter's Draco file: no bufferView on the accessor, a short buffer. The tool must
// name the extension, not tinygltf's "Invalid byteLength".
TEST(InsertTool, DracoGlbWithBrokenBuffersNamesTheExtension) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP();
  const InsertCase c = setup("insert_draco_glb");
  std::string j = R"({"asset":{"version":"2.0"},"extensionsUsed":["KHR_draco_mesh_compression"],)"
                  R"("buffers":[{"byteLength":4096}],"bufferViews":[{"buffer":0,"byteLength":4096}],)"
                  R"("accessors":[{"componentType":5126,"count":3,"type":"VEC3"}],)"
                  R"("meshes":[{"primitives":[{"attributes":{"POSITION":0},"extensions":{"KHR_draco_mesh_compression":)"
                  R"({"bufferView":0,"attributes":{"POSITION":0}}}}]}],"nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}]})";
  while (j.size() % 4) j += ' ';
  auto u32 = [](uint32_t v) { return std::string(reinterpret_cast<const char*>(&v), 4); };
  std::ofstream(c.dir + "/draco.glb", std::ios::binary)
      << "glTF" + u32(2) + u32(uint32_t(20 + j.size())) + u32(uint32_t(j.size())) + u32(0x4E4F534Au) + j;
  const auto r = run_tool("streetlight-insert", "--image " + c.dir + "/photo.png --intrinsics " + c.dir +
                                                    "/intrinsics.json --at 0,8 --out " + c.dir + "/out --checkpoint " +
                                                    c.ckpt + " --object " + c.dir + "/draco.glb");
  expect_clean_error(r, c.dir + "/out", "KHR_draco_mesh_compression");
  EXPECT_NE(r.out.find("not supported"), std::string::npos) << r.out;
}

TEST(InsertTool, BatchWritesAKittiLayoutDataset) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP();
  const InsertCase c = setup("insert_batch");
  std::ofstream(c.dir + "/list.json") << R"([{"image": "photo.png", "intrinsics": "intrinsics.json"},
                                             {"image": "photo.png", "intrinsics": "intrinsics.json"}])";
  const std::string out = c.dir + "/aug";
  const auto r = run_tool("streetlight-insert", "--batch " + c.dir + "/list.json --out " + out + c.base);
  ASSERT_EQ(r.code, 0) << r.out;
  for (const char* f : {"image_2/000000.png", "image_2/000001.png", "label_2/000000.txt", "calib/000001.txt"})
    EXPECT_TRUE(fs::exists(fs::path(out) / f)) << f;
  std::ifstream lf(out + "/label_2/000000.txt");
  std::string line;
  ASSERT_TRUE(std::getline(lf, line));
  EXPECT_EQ(line.rfind("Car ", 0), 0u) << line;
}

// --class names the object in label.txt and result.json, and in a batch's label_2 (once for every
// object, or once per --object); a class KITTI does not have, or a count that fits neither, is one line.
TEST(InsertTool, ClassNamesTheObjectInItsLabels) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP();
  const InsertCase c = setup("insert_class");
  const std::string photo = "--image " + c.dir + "/photo.png --intrinsics " + c.dir + "/intrinsics.json --at 0,8";
  const auto r = run_tool("streetlight-insert", photo + " --class Truck --out " + c.dir + "/out" + c.base);
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream lf(c.dir + "/out/label.txt");
  std::string line;
  ASSERT_TRUE(std::getline(lf, line));
  EXPECT_EQ(line.rfind("Truck ", 0), 0u) << line;
  std::ifstream jf(c.dir + "/out/result.json");
  EXPECT_EQ(nlohmann::json::parse(jf)["class"], "Truck");
  expect_clean_error(run_tool("streetlight-insert", photo + " --class Bus --out " + c.dir + "/bad" + c.base),
                     c.dir + "/bad", "'Bus' is not a KITTI class");
  expect_clean_error(run_tool("streetlight-insert", photo + " --class Car --class Van --out " + c.dir + "/bad" + c.base),
                     c.dir + "/bad", "--class was given 2 times for 1 objects");
  std::ofstream(c.dir + "/list.json") << R"([{"image": "photo.png", "intrinsics": "intrinsics.json"}])";
  // Two objects: the base flags' procedural car and one more.
  const std::string batch = "--batch " + c.dir + "/list.json --objects-per-image 2 --object procedural:car";
  const auto b = run_tool("streetlight-insert", batch + " --class Van --class Tram --out " + c.dir + "/aug" + c.base);
  ASSERT_EQ(b.code, 0) << b.out;
  std::ifstream bl(c.dir + "/aug/label_2/000000.txt");
  int lines = 0;
  while (std::getline(bl, line)) {
    ++lines;
    EXPECT_TRUE(line.rfind("Van ", 0) == 0 || line.rfind("Tram ", 0) == 0) << line;
  }
  EXPECT_GE(lines, 1);
  expect_clean_error(run_tool("streetlight-insert", batch + " --class Van --class Tram --class Car --out " + c.dir +
                                                        "/bad" + c.base),
                     c.dir + "/bad", "--class was given 3 times for 2 objects");
}

// A folder of phone photos, no KITTI layout: each photo's intrinsics from its EXIF focal length,
// written into the output's calib/ as a KITTI P2 (fx in the first row).
TEST(InsertTool, BatchTakesAFolderOfPhonePhotos) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP();
  const InsertCase c = setup("insert_batch_phone");
  const sl::Tensor up = sl::data::read_image(c.dir + "/photo.png", {.transfer = sl::data::Transfer::Linear});
  const std::string photos = c.dir + "/phone";
  fs::create_directories(photos);
  sl::test::write_exif_photo(photos + "/IMG_0001.JPG", up, 1, 26);
  sl::test::write_exif_photo(photos + "/IMG_0002.jpg", up, 1, 52);
  std::ofstream(photos + "/notes.txt") << "not a photo";
  const std::string out = c.dir + "/aug";
  const auto r = run_tool("streetlight-insert", "--batch " + photos + " --out " + out + c.base);
  ASSERT_EQ(r.code, 0) << r.out;
  const double diagonal_px = std::sqrt(64.0 * 64.0 + 32.0 * 32.0);
  for (const auto& [id, f35] : {std::pair<std::string, double>{"IMG_0001", 26.0}, {"IMG_0002", 52.0}}) {
    SCOPED_TRACE(id);
    EXPECT_TRUE(fs::exists(fs::path(out) / "image_2" / (id + ".png")));
    EXPECT_TRUE(fs::exists(fs::path(out) / "label_2" / (id + ".txt")));
    std::ifstream cf(out + "/calib/" + id + ".txt");
    std::string line;
    double fx = 0;
    while (std::getline(cf, line))
      if (line.rfind("P2:", 0) == 0) fx = std::stod(line.substr(3));
    EXPECT_NEAR(fx, f35 * diagonal_px / 43.266615305567875, 1e-3);
  }
  const auto empty = run_tool("streetlight-insert", "--batch " + c.dir + "/aug/label_2 --out " + c.dir + "/aug2" + c.base);
  expect_clean_error(empty, c.dir + "/aug2", "nor PNG or JPEG photos");
}

}  // namespace

namespace {

// Sec 4.1 through the tool: two photos with poses are fused into one lighting estimate.
TEST(InsertTool, MultiViewFusesTwoPosedPhotos) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP() << "streetlight-insert not built";
  const InsertCase c = setup("insert_multiview");
  const std::string out = c.dir + "/out";
  const std::string photo = " --image " + c.dir + "/photo.png --intrinsics " + c.dir + "/intrinsics.json";
  const auto r = run_tool("streetlight-insert", photo + " --pose 0,1.65,0,0" + photo + " --pose 2,1.65,-3,30" +
                                                    " --at 0,8 --out " + out + c.base);
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream jf(out + "/result.json");
  const auto j = nlohmann::json::parse(jf);
  EXPECT_EQ(j["views"].get<int>(), 2);
  const glm::dvec3 sun(j["sun"]["direction_world"][0], j["sun"]["direction_world"][1], j["sun"]["direction_world"][2]);
  EXPECT_NEAR(glm::length(sun), 1.0, 1e-6);
  EXPECT_TRUE(fs::exists(fs::path(out) / "composite.png"));
}

TEST(InsertTool, MultiViewWithoutAPosePerImageIsAnError) {
  if (!sl::test::tool_built("streetlight-insert")) GTEST_SKIP();
  const InsertCase c = setup("insert_multiview_bad");
  const std::string out = c.dir + "/out";
  const std::string photo = " --image " + c.dir + "/photo.png --intrinsics " + c.dir + "/intrinsics.json";
  expect_clean_error(run_tool("streetlight-insert", photo + photo + " --pose 0,1.65,0,0 --at 0,8 --out " + out + c.base),
                     out, "--pose");
}

}  // namespace

}  // namespace sl::test
