// make_stage: the config's "stage" key picks the stage (trainer.h).
#include "train/sky_stage.h"
#include "train/train_config.h"
#include "train/trainer.h"

namespace sl::train {

std::unique_ptr<Stage> make_lighting_stage(const nlohmann::json& config);  // lighting_stage.cpp

std::unique_ptr<Stage> make_stage(const nlohmann::json& config) {
  check_train_config(config);
  const std::string stage = config.at("stage").get<std::string>();
  if (stage == kStageSky) return std::make_unique<SkyStage>(config);
  return make_lighting_stage(config);
}

}  // namespace sl::train
