// Shared fixtures of the insert/eval tool tests: running an executable, tiny lighting and
// stage-3 checkpoints (random weights, tiny sizes) and a tiny synthetic photo with its intrinsics.
#pragma once
#include <sys/wait.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "data/image_io.h"
#include "nn/checkpoint.h"
#include "nn/modules/patch_discriminator.h"
#include "support/tiny_model.h"
#include "train/lighting_predictor.h"
#include "train/train_config.h"

namespace sl::test {

struct ToolRun {
  int code = -1;
  std::string out;
};

inline ToolRun run_tool(const std::string& name, const std::string& args) {
  const std::string cmd = "OMP_NUM_THREADS=1 " + std::string(STREETLIGHT_BINARY_DIR) + "/tools/" + name + " " + args + " 2>&1";
  ToolRun r;
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf;
  while (fgets(buf.data(), buf.size(), p)) r.out += buf.data();
  const int status = pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

// A bad-input run of a tool: exit 2, one line "error: ..." naming `needle`, and no output
// folder or temporary file left beside it (docs/DESIGN.md, "Errors").
inline void expect_clean_error(const ToolRun& r, const std::string& out_dir, const std::string& needle) {
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
  EXPECT_EQ(r.out.rfind("error: ", 0), 0u) << r.out;
  EXPECT_NE(r.out.find(needle), std::string::npos) << "expected '" << needle << "' in: " << r.out;
  EXPECT_FALSE(std::filesystem::exists(out_dir)) << "partial output left in " << out_dir;
  for (const auto& e : std::filesystem::directory_iterator(std::filesystem::path(out_dir).parent_path()))
    EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << e.path();
}

inline bool tool_built(const std::string& name) {
  return std::filesystem::exists(std::filesystem::path(STREETLIGHT_BINARY_DIR) / "tools" / name);
}

inline std::string tool_dir(const std::string& name) {
  const auto p = std::filesystem::path(STREETLIGHT_BINARY_DIR) / "test_tmp" / "tools" / name;
  std::filesystem::remove_all(p);
  std::filesystem::create_directories(p);
  return p.string();
}

inline nlohmann::json tiny_lighting_config() {
  nlohmann::json c = train::default_train_config();
  c["stage"] = "lighting";
  sl::test::apply_tiny_model(c);
  return c;
}

// A stage-2 checkpoint with random weights: enough to exercise the tools end to end.
inline std::string tiny_lighting_checkpoint(const std::string& dir) {
  const std::string path = dir + "/tiny_lighting.safetensors";
  const nlohmann::json c = tiny_lighting_config();
  nn::Module holder("LightingModel");
  holder.register_module("predictor", std::make_shared<train::LightingPredictor>(train::predictor_options(c)));
  nn::save_checkpoint(path, holder, nullptr, nn::CheckpointInfo{.stage = "lighting", .step = 1, .config_json = c.dump()});
  return path;
}

// A stage-3 checkpoint with random weights: the tiny predictor plus a tiny discriminator
// (discriminator.*, model.discriminator in its config), for streetlight-insert --refine.
inline std::string tiny_adversarial_checkpoint(const std::string& dir) {
  const std::string path = dir + "/tiny_adversarial.safetensors";
  nlohmann::json c = tiny_lighting_config();
  c["stage"] = "adversarial";
  c["model"]["discriminator"] = {{"base_channels", 4}, {"layers", 2}, {"norm", "instance"}};
  nn::Module holder("LightingModel");
  holder.register_module("predictor", std::make_shared<train::LightingPredictor>(train::predictor_options(c)));
  auto d = std::make_shared<nn::PatchDiscriminator>(
      nn::PatchDiscriminatorOptions{.base_channels = 4, .layers = 2, .norm = "instance"});
  d->init_parameters(17);
  holder.register_module("discriminator", d);
  nn::save_checkpoint(path, holder, nullptr, nn::CheckpointInfo{.stage = "adversarial", .step = 1, .config_json = c.dump()});
  return path;
}

// A 64×32 "street photo" (sky above, grey road below) and JSON intrinsics for it.
inline void tiny_photo(const std::string& dir, int width = 64, int height = 32) {
  Tensor img = Tensor::zeros({3, height, width});
  float* p = img.data<float>();
  for (int r = 0; r < height; ++r)
    for (int c = 0; c < width; ++c)
      for (int ch = 0; ch < 3; ++ch)
        p[(ch * height + r) * width + c] = r < height / 2 ? 0.5f + 0.15f * ch : 0.35f;
  data::ImageWriteOptions lin;
  lin.transfer = data::Transfer::Linear;
  data::write_image(dir + "/photo.png", img, lin);
  std::ofstream(dir + "/intrinsics.json") << nlohmann::json{{"fx", width * 0.6}, {"fy", width * 0.6},
                                                           {"cx", width / 2.0}, {"cy", height / 2.0}}.dump();
}

}  // namespace sl::test
