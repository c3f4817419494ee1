// Stage 2 (Sec 3.4): the supervised lighting stage overfits a tiny batch, and each ablation
// variant of the predictor steps and validates.
#include "train/lighting_stage.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "support/tiny_stage.h"

namespace sl::test {
using train::LightingStage;
using train::Metrics;
using train::kStageLighting;

namespace {

TEST(LightingStage, TwentyStepsOverfitATinyBatch) {
  const std::string dir = temp_dir("lighting_overfit");
  nlohmann::json c = tiny_config(kStageLighting);
  c["init"]["sky_checkpoint"] = save_sky_checkpoint(c, dir);
  LightingStage stage(c, memory_source(2), memory_source(1));
  stage.initialise();
  const auto [first, last] = overfit(stage, 20);
  EXPECT_LT(last, 0.8 * first) << first << " -> " << last;
}

TEST(LightingStage, AblationsRun) {
  const std::string dir = temp_dir("lighting_ablations");
  for (const auto& [branch, volume] : std::vector<std::pair<std::string, bool>>{
           {"direct", true}, {"constant", true}, {"sky_decoder", false}}) {
    nlohmann::json c = tiny_config(kStageLighting);
    c["init"]["sky_checkpoint"] = save_sky_checkpoint(c, dir);
    c["model"]["sky_branch"] = branch;
    c["model"]["volume_branch"] = volume;
    LightingStage stage(c, memory_source(2), memory_source(1));
    stage.initialise();
    const auto [first, last] = overfit(stage, 5);
    EXPECT_LT(last, first) << branch << " volume " << volume;
    const Metrics v = stage.validate();
    EXPECT_TRUE(std::isfinite(v.at("val_loss"))) << branch;
    EXPECT_TRUE(v.count("val_si_psnr")) << branch;
  }
}

}  // namespace
}  // namespace sl::test
