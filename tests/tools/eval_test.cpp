// streetlight-eval on a tiny generated street dataset: every metric of issue 8 is reported, one
// table row per checkpoint, the error-against-time plot is written, and bad input is one line.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "../data/street_fixture.h"
#include "tool_fixture.h"

namespace fs = std::filesystem;

TEST(EvalTool, ReportsTheMetricsOfTables1And2WithARowPerCheckpoint) {
  if (!sl::test::tool_built("streetlight-eval")) GTEST_SKIP() << "streetlight-eval not built";
  const std::string dir = sl::test::tool_dir("eval_ok");
  const std::string data = sl::test::tiny_dataset("eval_tiny_dataset", 3);
  const std::string ckpt = sl::test::tiny_lighting_checkpoint(dir);
  const auto r = sl::test::run_tool("streetlight-eval", "--checkpoint " + ckpt + " --checkpoint " + ckpt +
                                                          " --name a --name b --data " + data +
                                                          " --split train --view-rows 8 --out " + dir + "/out");
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream jf(dir + "/out/results.json");
  const auto j = nlohmann::json::parse(jf);
  ASSERT_EQ(j["results"].size(), 2u);
  for (const char* k : {"sun_error_median_deg", "sun_error_mean_deg", "psnr", "si_psnr", "psnr_upper", "si_psnr_upper",
                        "inference_ms"})
    EXPECT_TRUE(j["results"][0].contains(k)) << k;
  EXPECT_GE(j["results"][0]["si_psnr"].get<double>(), j["results"][0]["psnr"].get<double>() - 1e-9);
  EXPECT_TRUE(fs::exists(dir + "/out/results.md"));
  EXPECT_TRUE(fs::exists(dir + "/out/error_time.png"));
  EXPECT_EQ(j["results"][0]["sun_error_median_deg"], j["results"][1]["sun_error_median_deg"]);  // deterministic
}

TEST(EvalTool, MissingDataIsACleanError) {
  if (!sl::test::tool_built("streetlight-eval")) GTEST_SKIP();
  const std::string dir = sl::test::tool_dir("eval_bad");
  const std::string ckpt = sl::test::tiny_lighting_checkpoint(dir);
  const auto r = sl::test::run_tool("streetlight-eval", "--checkpoint " + ckpt + " --data " + dir + "/nothing");
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(r.out.rfind("error: ", 0), 0u) << r.out;
}
