// The tiny stage configuration the stage and trainer tests share: the tiny model of
// tiny_model.h, in-memory street samples (street_fixture.h), six steps of batch 2, and helpers
// to overfit one batch, save a sky-stage checkpoint and get a clean folder under
// <build>/test_tmp/train/.
#pragma once
#include <filesystem>
#include <string>
#include <utility>

#include <nlohmann/json.hpp>

#include "nn/checkpoint.h"
#include "support/street_fixture.h"
#include "support/tiny_model.h"
#include "train/sample_source.h"
#include "train/sky_autoencoder.h"
#include "train/train_config.h"
#include "train/trainer.h"

namespace sl::test {

inline std::string temp_dir(const std::string& name) {
  namespace fs = std::filesystem;
  const fs::path p = fs::path(STREETLIGHT_BINARY_DIR) / "test_tmp" / "train" / name;
  fs::remove_all(p);
  fs::create_directories(p);
  return p.string();
}

inline nlohmann::json tiny_config(const std::string& stage) {
  nlohmann::json c = train::default_train_config();
  c["stage"] = stage;
  apply_tiny_model(c);
  c["model"]["volume"]["samples"] = 16;
  c["data"]["val_size"] = 2;
  c["data"]["pano_rays"] = 64;
  c["data"]["view_rays"] = 64;
  c["data"]["val_view_height"] = 8;
  c["data"]["dataset"] = "in-memory";
  c["train"] = {{"steps", 6}, {"batch_size", 2}, {"log_every", 1}, {"val_every", 3}, {"checkpoint_every", 3},
                {"image_every", 100}};
  c["optim"]["lr"] = 3e-3;
  c["optim"]["warmup_steps"] = 0;
  return c;
}

inline train::SampleSource memory_source(int n) {
  return train::SampleSource{static_cast<size_t>(n), [](size_t i, uint64_t) { return tiny_street_sample(i + 1); }};
}

// Steps the same batch (step index 0) `steps` times at a constant lr; returns first and last loss.
inline std::pair<double, double> overfit(train::Stage& stage, int steps) {
  double first = 0, last = 0;
  for (int s = 0; s < steps; ++s) {
    stage.set_lr(3e-3);
    last = stage.step(0).at("loss");
    if (s == 0) first = last;
  }
  return {first, last};
}

inline std::string save_sky_checkpoint(const nlohmann::json& c, const std::string& dir) {
  train::SkyAutoencoder ae(train::sky_options(c));
  const std::string path = dir + "/sky.safetensors";
  nn::save_checkpoint(path, ae, nullptr, nn::CheckpointInfo{.stage = train::kStageSky});
  return path;
}

}  // namespace sl::test
