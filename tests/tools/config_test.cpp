#include "tools/common/config.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <vector>

#include "util/error.h"

namespace sl::test {
using cli::Config;
using cli::ConfigFile;
using cli::read_config_chain;
using cli::key_paths;
using cli::nearest;

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

TEST(Config, ExtendsMergesTheBaseFileFirstRelativeToTheExtendingFile) {
  const std::string dir = ::testing::TempDir() + "/config_extends";
  std::filesystem::create_directories(dir + "/sub");
  std::ofstream(dir + "/base.json") << "{\"seed\": 7, \"model\": {\"base_channels\": 32, \"norm\": \"group\"}}";
  std::ofstream(dir + "/sub/middle.json") << "{\"extends\": \"../base.json\", \"model\": {\"base_channels\": 48}}";
  std::ofstream(dir + "/sub/top.json") << "{\"extends\": \"middle.json\", \"seed\": 9}";
  Config c(defaults());
  c.merge_file(dir + "/sub/top.json");
  EXPECT_EQ(c.integer("seed"), 9);                  // the extending file wins
  EXPECT_EQ(c.integer("model.base_channels"), 48);  // the middle file over the base
  EXPECT_EQ(c.string("model.norm"), "group");       // the base where nothing overrides it
  EXPECT_EQ(c.integer("train.steps"), 100);         // the defaults where no file sets it
  EXPECT_FALSE(c.tree().contains("extends"));       // not a key of the effective config
  // The chain itself, for a reader without a defaults tree: bases first, in merge order, each
  // file's own keys only.
  const std::vector<ConfigFile> chain = read_config_chain(dir + "/sub/top.json");
  ASSERT_EQ(chain.size(), 3u);
  EXPECT_EQ(std::filesystem::path(chain[0].path).filename(), "base.json");
  EXPECT_EQ(std::filesystem::path(chain[1].path).filename(), "middle.json");
  EXPECT_EQ(chain[2].path, dir + "/sub/top.json");
  EXPECT_EQ(chain[0].content.at("seed").get<int>(), 7);
  EXPECT_EQ(chain[1].content, nlohmann::json::parse(R"({"model": {"base_channels": 48}})"));
  EXPECT_EQ(chain[2].content, nlohmann::json::parse(R"({"seed": 9})"));
}

TEST(Config, ExtendsCyclesMissingBasesAndNonStringsAreErrorsNamingTheFile) {
  const std::string dir = ::testing::TempDir() + "/config_extends_bad";
  std::filesystem::create_directories(dir);
  std::ofstream(dir + "/a.json") << "{\"extends\": \"b.json\"}";
  std::ofstream(dir + "/b.json") << "{\"extends\": \"a.json\"}";
  std::ofstream(dir + "/self.json") << "{\"extends\": \"self.json\"}";
  std::ofstream(dir + "/missing.json") << "{\"extends\": \"nowhere.json\"}";
  std::ofstream(dir + "/number.json") << "{\"extends\": 3}";
  Config c(defaults());
  std::string e = error_of([&] { c.merge_file(dir + "/a.json"); });
  EXPECT_NE(e.find("cycle"), std::string::npos) << e;
  EXPECT_NE(e.find("b.json"), std::string::npos) << e;
  e = error_of([&] { c.merge_file(dir + "/self.json"); });
  EXPECT_NE(e.find("cycle"), std::string::npos) << e;
  e = error_of([&] { c.merge_file(dir + "/missing.json"); });
  EXPECT_NE(e.find("nowhere.json"), std::string::npos) << e;
  e = error_of([&] { c.merge_file(dir + "/number.json"); });
  EXPECT_NE(e.find("number.json"), std::string::npos) << e;
  EXPECT_NE(e.find("extends"), std::string::npos) << e;
  // After the errors, a good file still merges (no stale chain is left behind).
  std::ofstream(dir + "/good.json") << "{\"seed\": 5}";
  std::ofstream(dir + "/child.json") << "{\"extends\": \"good.json\"}";
  c.merge_file(dir + "/child.json");
  EXPECT_EQ(c.integer("seed"), 5);
}

TEST(Config, NumberPastDoubleIsACleanError) {
  // Found by the config fuzzer: nlohmann throws out_of_range (not parse_error) for 1e999.
  Config c(defaults());
  const std::string path = ::testing::TempDir() + "/overflow_config.json";
  std::ofstream(path) << "{\"train\": {\"lr\": 2222e2222222222}}";
  const std::string e = error_of([&] { c.merge_file(path); });
  EXPECT_NE(e.find(path), std::string::npos) << e;
  EXPECT_NE(e.find("not valid JSON"), std::string::npos) << e;
  const std::string s = error_of([&] { c.set("train.lr=1e999"); });  // kept as text, then refused as a string
  EXPECT_NE(s.find("train.lr"), std::string::npos) << s;
  EXPECT_NE(s.find("expects number, got string"), std::string::npos) << s;
}

// The suggestion rule of nearest(), computed in full for every candidate.
std::string nearest_in_full(const std::string& key, const std::vector<std::string>& candidates) {
  auto distance = [](const std::string& a, const std::string& b) {
    std::vector<size_t> prev(b.size() + 1), cur(b.size() + 1);
    for (size_t j = 0; j <= b.size(); ++j) prev[j] = j;
    for (size_t i = 1; i <= a.size(); ++i) {
      cur[0] = i;
      for (size_t j = 1; j <= b.size(); ++j)
        cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
      std::swap(prev, cur);
    }
    return prev[b.size()];
  };
  auto leaf = [](const std::string& k) { return k.substr(k.rfind('.') == std::string::npos ? 0 : k.rfind('.') + 1); };
  std::string best;
  size_t best_d = SIZE_MAX;
  for (const auto& c : candidates) {
    const size_t d = std::min(distance(key, c), distance(leaf(key), leaf(c)) + 1);
    if (d < best_d) best_d = d, best = c;
  }
  return best_d <= std::max<size_t>(3, key.size() / 3) ? best : "";
}

TEST(Config, NearestSkipsOnlyDistancesThatCannotWin) {
  const std::vector<std::string> keys = key_paths(defaults());
  std::vector<std::string> probes = {"", "x", "lr", "train.l", "model.base_channel", "trian.lr", "model.norm.extra",
                                     std::string(5000, 'a'), std::string(5000, 'a') + ".lr", "a.b.c.d.e.f.g.steps"};
  uint32_t state = 12345;  // deterministic edits of the real keys: drop, double or change one character
  for (const std::string& k : keys)
    for (int n = 0; n < 8; ++n) {
      state = state * 1664525u + 1013904223u;
      std::string p = k;
      const size_t at = (state >> 8) % p.size();
      if (n % 3 == 0) p.erase(at, 1);
      else if (n % 3 == 1) p.insert(at, 1, p[at]);
      else p[at] = static_cast<char>('a' + (state >> 20) % 26);
      probes.push_back(p);
    }
  for (const std::string& p : probes) EXPECT_EQ(nearest(p, keys), nearest_in_full(p, keys)) << p.substr(0, 40);
  EXPECT_EQ(nearest(std::string(100000, 'q'), keys), "");  // no key is within a third of its length
}

}  // namespace
}  // namespace sl::test
