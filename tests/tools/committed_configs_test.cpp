// Every training config committed under configs/ is one streetlight-train accepts: it merges over
// the defaults without an unknown key or a wrong type (tools/common/config.h), passes
// check_train_config, and builds its model options. A typo in a release config fails here, not
// hours into a run.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "tools/common/config.h"
#include "train/train_config.h"
#include "util/error.h"

namespace sl::test {
namespace {

namespace fs = std::filesystem;

// Whether a config file, or a base it extends, names a stage: a variant that lists only what
// differs from its base is a training config too.
bool names_a_stage(const fs::path& p) {
  const std::vector<cli::ConfigFile> chain = cli::read_config_chain(p.string());
  return std::any_of(chain.begin(), chain.end(),
                     [](const cli::ConfigFile& f) { return f.content.is_object() && f.content.contains("stage"); });
}

TEST(CommittedConfigs, EveryTrainingConfigValidatesAndBuildsItsModel) {
  const fs::path dir = fs::path(STREETLIGHT_SOURCE_DIR) / "configs";
  std::vector<fs::path> configs;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.path().extension() != ".json") continue;
    if (names_a_stage(e.path())) configs.push_back(e.path());  // datagen configs and splits have none
  }
  ASSERT_GE(configs.size(), 17u) << "the training configs of configs/README.md";
  // The variants that extend a base are among them.
  EXPECT_NE(std::find(configs.begin(), configs.end(), dir / "release_sun_grid_compact_mix50.json"), configs.end());
  for (const fs::path& p : configs) {
    SCOPED_TRACE(p.filename().string());
    try {
      cli::Config c(train::default_train_config());
      c.merge_file(p.string());
      train::check_train_config(c.tree());
      const std::string stage = c.tree().at("stage").get<std::string>();
      if (stage == train::kStageSky) {
        (void)train::sky_options(c.tree());
      } else {
        (void)train::predictor_options(c.tree());
      }
    } catch (const Error& e) {
      ADD_FAILURE() << e.what();
    }
  }
}

}  // namespace
}  // namespace sl::test
