// The train executable's input errors (docs/DESIGN.md, "Executables"): an unknown config key names the
// nearest valid key, a missing stage checkpoint is named, and both exit 2 with one line.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace sl::test {

namespace {

namespace fs = std::filesystem;

struct TrainRun {
  int code = -1;
  std::string err;
};

TrainRun run_train(const std::string& config_text, const std::string& extra = "") {
  const fs::path exe = fs::path(STREETLIGHT_BINARY_DIR) / "tools" / "streetlight-train";
  if (!fs::exists(exe)) return {};
  // One folder per process and test: ctest runs the tests of this file in parallel processes.
  const fs::path dir = fs::path(STREETLIGHT_BINARY_DIR) / "test_tmp" / "train" /
                       ("executable_" + std::to_string(::getpid()) + "_" +
                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
  fs::create_directories(dir);
  std::ofstream(dir / "config.json") << config_text;
  const std::string cmd = exe.string() + " --config " + (dir / "config.json").string() + " --out " +
                          (dir / "out").string() + " " + extra + " 2> " + (dir / "err.txt").string();
  const int status = std::system(cmd.c_str());
  std::stringstream ss;
  ss << std::ifstream(dir / "err.txt").rdbuf();
  return {WEXITSTATUS(status), ss.str()};
}

TEST(TrainExecutable, UnknownConfigKeyNamesTheNearestValidKey) {
  const TrainRun r = run_train(R"({"stage": "sky_autoencoder", "train": {"stepz": 3}})");
  if (r.code < 0) GTEST_SKIP() << "streetlight-train is not built";
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("train.stepz"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("train.steps"), std::string::npos) << r.err;
}

TEST(TrainExecutable, LightingStageWithoutItsSkyCheckpointIsNamed) {
  const TrainRun r = run_train(R"({"stage": "lighting", "data": {"dataset": "nowhere"}})");
  if (r.code < 0) GTEST_SKIP() << "streetlight-train is not built";
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("init.sky_checkpoint"), std::string::npos) << r.err;
}

TEST(TrainExecutable, WrongValueTypeAndBadStageAreErrors) {
  TrainRun r = run_train(R"({"stage": "sky_autoencoder"})", "--set train.steps=abc");
  if (r.code < 0) GTEST_SKIP() << "streetlight-train is not built";
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("train.steps"), std::string::npos) << r.err;
  r = run_train(R"({"stage": "skyy"})");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("stage"), std::string::npos) << r.err;
  r = run_train(R"({"stage": "sky_autoencoder"})", "--set optim.ema_decay=1");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("optim.ema_decay"), std::string::npos) << r.err;
  r = run_train(R"({"stage": "sky_autoencoder"})", "--set optim.schedule_steps=-5");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("optim.schedule_steps"), std::string::npos) << r.err;
}

}  // namespace

}  // namespace sl::test
