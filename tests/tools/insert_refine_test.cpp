// streetlight-insert --refine N (paper Fig. 7, train/lighting_refinement.h) end to end on a tiny
// photo with random-weight checkpoints: N = 0 changes nothing, N > 0 reports the loss and the sun
// before and after, the discriminator is found in the checkpoint or given apart, and every bad
// --refine input is one line "error: ...", exit 2, with no output folder left behind.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>

#include <nlohmann/json.hpp>

#include "support/tool_fixture.h"
#include "train/inference.h"

namespace sl::test {

namespace fs = std::filesystem;

namespace {

struct RefineCase {
  std::string dir, lighting, adversarial, args;
};

RefineCase setup(const std::string& name) {
  RefineCase c;
  c.dir = tool_dir(name);
  c.lighting = tiny_lighting_checkpoint(c.dir);
  c.adversarial = tiny_adversarial_checkpoint(c.dir);
  tiny_photo(c.dir);
  c.args = " --image " + c.dir + "/photo.png --intrinsics " + c.dir + "/intrinsics.json --at 0,8" +
           " --object procedural:car --aa 1 --light-samples 4 --shadow-rays 8 --shadow-width 16 --shadow-height 8 --exr";
  return c;
}

std::string bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

nlohmann::json result(const std::string& out) {
  std::ifstream f(out + "/result.json");
  return nlohmann::json::parse(f);
}

void expect_sun_consistent(const nlohmann::json& sun) {
  const glm::dvec3 d(sun["direction_world"][0], sun["direction_world"][1], sun["direction_world"][2]);
  EXPECT_NEAR(glm::length(d), 1.0, 1e-6);
  EXPECT_NEAR(sun["azimuth_deg"].get<double>(), train::azimuth_deg_of(d), 1e-9);
  EXPECT_NEAR(sun["elevation_deg"].get<double>(), train::elevation_deg_of(d), 1e-9);
  for (int c = 0; c < 3; ++c) {
    EXPECT_TRUE(std::isfinite(sun["intensity_rgb"][c].get<double>()));
    EXPECT_GT(sun["intensity_rgb"][c].get<double>(), 0.0);
  }
}

TEST(InsertRefine, ZeroStepsAreBitwiseTheRunWithoutRefine) {
  if (!tool_built("streetlight-insert")) GTEST_SKIP() << "streetlight-insert not built";
  const RefineCase c = setup("refine_zero");
  const std::string plain = c.dir + "/plain", zero = c.dir + "/zero";
  const auto a = run_tool("streetlight-insert", "--checkpoint " + c.adversarial + " --out " + plain + c.args);
  const auto b = run_tool("streetlight-insert", "--checkpoint " + c.adversarial + " --refine 0 --out " + zero + c.args);
  ASSERT_EQ(a.code, 0) << a.out;
  ASSERT_EQ(b.code, 0) << b.out;
  for (const char* f : {"composite.png", "composite.exr", "shadow_map.png", "sky.exr", "label.txt"})
    EXPECT_EQ(bytes(plain + "/" + f), bytes(zero + "/" + f)) << f;
  nlohmann::json ja = result(plain), jb = result(zero);
  ja.erase("timing_ms");
  jb.erase("timing_ms");
  EXPECT_EQ(ja, jb);
  EXPECT_FALSE(jb.contains("refinement"));
}

TEST(InsertRefine, ReportsTheLossAndTheSunBeforeAndAfter) {
  if (!tool_built("streetlight-insert")) GTEST_SKIP();
  const RefineCase c = setup("refine_report");
  const std::string out = c.dir + "/out";
  const auto r = run_tool("streetlight-insert", "--checkpoint " + c.adversarial +
                                                    " --refine 3 --refine-lr 0.2 --refine-volume --out " + out + c.args);
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("refine: 3 steps"), std::string::npos) << r.out;
  const nlohmann::json j = result(out);
  ASSERT_TRUE(j.contains("refinement")) << j.dump(2);
  const nlohmann::json& f = j["refinement"];
  EXPECT_EQ(f["steps"], 3);
  EXPECT_EQ(f["discriminator"], c.adversarial);
  EXPECT_EQ(f["loss_per_step"].size(), 3u);
  EXPECT_EQ(f["parameters"].size(), 4u);
  EXPECT_EQ(f["samples"]["aa"], 1);  // the default refinement budget 1,4,16
  EXPECT_TRUE(std::isfinite(f["loss_before"].get<double>()));
  EXPECT_TRUE(std::isfinite(f["loss_after"].get<double>()));
  for (const auto& v : f["loss_per_step"]) EXPECT_TRUE(v.is_number() && std::isfinite(v.get<double>())) << v;
  expect_sun_consistent(f["sun_before"]);
  expect_sun_consistent(f["sun_after"]);
  // The composite uses the refined lighting: the top-level sun is the one after refinement, and
  // three steps of 0.2 moved it.
  EXPECT_EQ(j["sun"]["direction_world"], f["sun_after"]["direction_world"]);
  EXPECT_EQ(j["sun"]["intensity_rgb"], f["sun_after"]["intensity_rgb"]);
  EXPECT_NE(f["sun_before"]["direction_world"], f["sun_after"]["direction_world"]);
  EXPECT_TRUE(j["timing_ms"].contains("refinement"));
}

TEST(InsertRefine, TakesTheDiscriminatorFromASeparateFile) {
  if (!tool_built("streetlight-insert")) GTEST_SKIP();
  const RefineCase c = setup("refine_separate");
  const std::string out = c.dir + "/out";
  const auto r = run_tool("streetlight-insert", "--checkpoint " + c.lighting + " --refine 1 --discriminator " +
                                                    c.adversarial + " --out " + out + c.args);
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(result(out)["refinement"]["discriminator"], c.adversarial);
}

TEST(InsertRefine, BadRefineInputIsACleanError) {
  if (!tool_built("streetlight-insert")) GTEST_SKIP();
  const RefineCase c = setup("refine_errors");
  const std::string out = c.dir + "/out";
  expect_clean_error(run_tool("streetlight-insert", "--checkpoint " + c.adversarial + " --refine -1 --out " + out + c.args),
                     out, "--refine -1");
  expect_clean_error(run_tool("streetlight-insert", "--checkpoint " + c.adversarial + " --refine abc --out " + out + c.args),
                     out, "--refine");
  expect_clean_error(run_tool("streetlight-insert", "--checkpoint " + c.adversarial + " --refine 2 --refine-lr -1 --out " +
                                                        out + c.args),
                     out, "--refine-lr");
  expect_clean_error(run_tool("streetlight-insert", "--checkpoint " + c.adversarial + " --refine 2 --refine-samples 1,0,4 --out " +
                                                        out + c.args),
                     out, "--refine-samples");
  // No discriminator in the lighting checkpoint and none given: the error names the file.
  expect_clean_error(run_tool("streetlight-insert", "--checkpoint " + c.lighting + " --refine 3 --out " + out + c.args),
                     out, c.lighting);
  expect_clean_error(run_tool("streetlight-insert", "--checkpoint " + c.lighting + " --refine 3 --discriminator " + c.dir +
                                                        "/missing.safetensors --out " + out + c.args),
                     out, "missing.safetensors");
  expect_clean_error(run_tool("streetlight-insert", "--checkpoint " + c.lighting + " --refine 3 --discriminator " +
                                                        c.lighting + " --out " + out + c.args),
                     out, c.lighting);
  expect_clean_error(run_tool("streetlight-insert", "--checkpoint " + c.adversarial + " --refine 2 --batch " + c.dir +
                                                        " --out " + out),
                     out, "--batch");
}

}  // namespace

}  // namespace sl::test
