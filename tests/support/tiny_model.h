// The smallest lighting-predictor model the train, adversarial and tool tests share: an 8×32
// sky dome, a 32×64 input, a width-4 backbone and an 8×8×4 VSG volume, so a step takes
// milliseconds. apply_tiny_model() applies these sizes to a config from
// train::default_train_config(); tiny_sky_options() and tiny_predictor_options() build the same
// models directly; grad_of() reads one parameter's gradient by its hierarchical name.
#pragma once
#include <gtest/gtest.h>

#include <string>

#include <nlohmann/json.hpp>

#include "autodiff/tensor.h"
#include "nn/module.h"
#include "train/lighting_predictor.h"
#include "train/sky_autoencoder.h"

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

inline train::SkyAutoencoderOptions tiny_sky_options() {
  return train::SkyAutoencoderOptions{
      .height = 8, .width = 32, .code_dim = 12, .base_channels = 4, .hidden = 16, .seed = 3};
}

// `branch` is the sky branch ("sky_decoder", "direct", "constant"); `volume` adds the VSG branch.
inline train::LightingPredictorOptions tiny_predictor_options(const std::string& branch, bool volume) {
  train::LightingPredictorOptions o;
  o.image_height = 32;
  o.image_width = 64;
  o.backbone_width = 4;
  o.head_hidden = 16;
  o.sky_branch = branch;
  o.volume_branch = volume;
  o.vsg_dims = {8, 8, 4};
  o.coarse_scale = 4;
  o.coarse_channels = 2;
  o.unet_channels = 4;
  o.unet_depth = 1;
  o.sky = tiny_sky_options();
  o.seed = 5;
  return o;
}

// The gradient of parameter `name` of `m` (zeros({1}) when it has none; a failure when no such
// parameter exists).
inline Tensor grad_of(const nn::Module& m, const std::string& name) {
  for (const auto& [n, t] : m.named_parameters())
    if (n == name) return t.grad().defined() ? t.grad() : Tensor::zeros({1});
  ADD_FAILURE() << "no parameter " << name;
  return Tensor::zeros({1});
}

}  // namespace sl::test
