// Stage 1 (Sec 3.4): the sky autoencoder stage overfits a tiny batch in 20 steps.
#include "train/sky_stage.h"

#include <gtest/gtest.h>

#include "support/tiny_stage.h"

namespace sl::test {
using train::SkyStage;
using train::kStageSky;

namespace {

TEST(SkyStage, TwentyStepsOverfitATinyBatch) {
  nlohmann::json c = tiny_config(kStageSky);
  SkyStage stage(c);
  const auto [first, last] = overfit(stage, 20);
  EXPECT_LT(last, 0.7 * first) << first << " -> " << last;
}

}  // namespace
}  // namespace sl::test
