// The smallest lighting-predictor model the train, adversarial and tool tests share: an 8×32
// sky dome, a 32×64 input, a width-4 backbone and an 8×8×4 VSG volume, so a step takes
// milliseconds. Applies these sizes to a config from train::default_train_config().
#pragma once
#include <nlohmann/json.hpp>

namespace sl::test {

inline void apply_tiny_model(nlohmann::json& c) {
  c["model"]["sky"] = {{"height", 8}, {"width", 32}, {"code_dim", 12}, {"base_channels", 4}, {"hidden", 16},
                       {"sun_lobe_texels", 1.0}};
  c["model"]["image_height"] = 32;
  c["model"]["image_width"] = 64;
  c["model"]["backbone_width"] = 4;
  c["model"]["head_hidden"] = 16;
  c["model"]["volume"]["dims"] = {8, 8, 4};
  c["model"]["volume"]["coarse_scale"] = 4;
  c["model"]["volume"]["coarse_channels"] = 2;
  c["model"]["volume"]["unet_channels"] = 4;
  c["model"]["volume"]["unet_depth"] = 1;
  c["model"]["volume"]["samples"] = 8;
}

}  // namespace sl::test
