#include "tools/common/config.h"

#include <gtest/gtest.h>

#include <fstream>

#include "util/error.h"

namespace sl::cli {
namespace {

using json = nlohmann::json;

json defaults() {
  return json{{"seed", 0},
              {"model", {{"norm", "batch"}, {"base_channels", 16}, {"dropout", 0.0}}},
              {"train", {{"lr", 1e-3}, {"steps", 100}, {"amp", false}, {"milestones", json::array()}}}};
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(Config, DefaultsApplyAndSetOverridesByPath) {
  Config c(defaults());
  EXPECT_EQ(c.integer("model.base_channels"), 16);
  c.set("model.base_channels=32");
  c.set("model.norm=group");
  c.set("train.lr=5e-4");
  c.set("train.milestones=[10, 20]");
  EXPECT_EQ(c.integer("model.base_channels"), 32);
  EXPECT_EQ(c.string("model.norm"), "group");
  EXPECT_DOUBLE_EQ(c.number("train.lr"), 5e-4);
  EXPECT_EQ(c.numbers("train.milestones"), (std::vector<double>{10, 20}));
}

TEST(Config, IntegerIsAcceptedForAFloatButNotTheReverse) {
  Config c(defaults());
  c.set("train.lr=1");
  EXPECT_DOUBLE_EQ(c.number("train.lr"), 1.0);
  EXPECT_NE(error_of([&] { c.set("train.steps=1.5"); }).find("expects integer"), std::string::npos);
}

TEST(Config, UnknownKeyNamesTheNearestValidKey) {
  Config c(defaults());
  const std::string e = error_of([&] { c.merge(json{{"model", {{"base_channel", 8}}}}, "config file 'x.json'"); });
  EXPECT_NE(e.find("x.json"), std::string::npos) << e;
  EXPECT_NE(e.find("'model.base_channel'"), std::string::npos) << e;
  EXPECT_NE(e.find("did you mean 'model.base_channels'"), std::string::npos) << e;
  EXPECT_NE(error_of([&] { c.set("trian.lr=1"); }).find("did you mean 'train'"), std::string::npos);
}

TEST(Config, WrongTypeNamesKeyAndBothTypes) {
  Config c(defaults());
  const std::string e = error_of([&] { c.set("train.amp=3"); });
  EXPECT_NE(e.find("train.amp"), std::string::npos) << e;
  EXPECT_NE(e.find("boolean"), std::string::npos) << e;
  EXPECT_NE(e.find("integer"), std::string::npos) << e;
}

TEST(Config, BadFilesAreErrorsNamingTheFile) {
  Config c(defaults());
  EXPECT_NE(error_of([&] { c.merge_file("/nonexistent/cfg.json"); }).find("/nonexistent/cfg.json"), std::string::npos);
  const std::string path = ::testing::TempDir() + "/broken_config.json";
  std::ofstream(path) << "{\"seed\": 1,";
  const std::string e = error_of([&] { c.merge_file(path); });
  EXPECT_NE(e.find(path), std::string::npos) << e;
  EXPECT_NE(e.find("not valid JSON"), std::string::npos) << e;
}

}  // namespace
}  // namespace sl::cli
