// The training stages (Sec 3.4): a 20-step overfit per stage on a tiny batch, bit-identical
// resume, signal handling and the non-finite guard.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "autodiff/ops.h"
#include "nn/checkpoint.h"
#include "support/street_fixture.h"
#include "support/tiny_model.h"
#include "train/lighting_stage.h"
#include "train/sky_stage.h"
#include "train/train_config.h"
#include "train/trainer.h"

using sl::render::InsertionOptions;
using sl::render::SampleSpacing;

namespace sl::test {
using train::LightingStage;
using train::Metrics;
using train::NonFiniteError;
using train::RunOptions;
using train::RunResult;
using train::SampleSource;
using train::SkyAutoencoder;
using train::SkyStage;
using train::Stage;
using train::default_train_config;
using train::kStageLighting;
using train::kStageSky;
using train::request_stop;
using train::run_training;
using train::sky_options;
using train::training_insertion_options;
using train::volume_query_options;

namespace {

namespace fs = std::filesystem;

std::string temp_dir(const std::string& name) {
  const fs::path p = fs::path(STREETLIGHT_BINARY_DIR) / "test_tmp" / "train" / name;
  fs::remove_all(p);
  fs::create_directories(p);
  return p.string();
}

nlohmann::json tiny_config(const std::string& stage) {
  nlohmann::json c = default_train_config();
  c["stage"] = stage;
  sl::test::apply_tiny_model(c);
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

SampleSource memory_source(int n) {
  return SampleSource{static_cast<size_t>(n), [](size_t i, uint64_t) { return test::tiny_street_sample(i + 1); }};
}

// Steps the same batch (step index 0) `steps` times at a constant lr; returns first and last loss.
std::pair<double, double> overfit(Stage& stage, int steps) {
  double first = 0, last = 0;
  for (int s = 0; s < steps; ++s) {
    stage.set_lr(3e-3);
    last = stage.step(0).at("loss");
    if (s == 0) first = last;
  }
  return {first, last};
}

TEST(SkyStage, TwentyStepsOverfitATinyBatch) {
  nlohmann::json c = tiny_config(kStageSky);
  SkyStage stage(c);
  const auto [first, last] = overfit(stage, 20);
  EXPECT_LT(last, 0.7 * first) << first << " -> " << last;
}

std::string save_sky_checkpoint(const nlohmann::json& c, const std::string& dir) {
  SkyAutoencoder ae(sky_options(c));
  const std::string path = dir + "/sky.safetensors";
  nn::save_checkpoint(path, ae, nullptr, nn::CheckpointInfo{.stage = kStageSky});
  return path;
}

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

std::vector<double> run_losses(Stage& stage, const nlohmann::json& c, const std::string& out, const std::string& resume,
                               int64_t stop_at) {
  std::vector<double> losses;
  RunOptions o;
  o.out_dir = out;
  o.resume = resume;
  o.on_step = [&](int64_t done, int64_t, const Metrics& m) {
    losses.push_back(m.at("loss"));
    if (done == stop_at) request_stop();
  };
  const RunResult r = run_training(stage, c, o);
  EXPECT_EQ(r.interrupted, stop_at > 0);
  return losses;
}

TEST(Trainer, SkyResumeIsBitIdentical) {
  const nlohmann::json c = tiny_config(kStageSky);
  const std::string a = temp_dir("resume_sky_a"), b = temp_dir("resume_sky_b");
  SkyStage full(c);
  const std::vector<double> all = run_losses(full, c, a, "", 0);
  ASSERT_EQ(all.size(), 6u);
  SkyStage first(c);
  const std::vector<double> head = run_losses(first, c, b, "", 2);  // SIGINT-style stop after step 2
  ASSERT_EQ(head.size(), 2u);
  SkyStage second(c);
  const std::vector<double> tail = run_losses(second, c, b, b + "/last.safetensors", 0);
  ASSERT_EQ(tail.size(), 4u);
  for (size_t i = 0; i < 2; ++i) EXPECT_EQ(head[i], all[i]) << i;
  for (size_t i = 0; i < 4; ++i) EXPECT_EQ(tail[i], all[i + 2]) << "step " << i + 3;
  EXPECT_TRUE(fs::exists(a + "/best.safetensors"));
  EXPECT_TRUE(fs::exists(a + "/metrics.jsonl"));
}

TEST(Trainer, LightingResumeIsBitIdentical) {
  const std::string dir = temp_dir("resume_light");
  nlohmann::json c = tiny_config(kStageLighting);
  c["init"]["sky_checkpoint"] = save_sky_checkpoint(c, dir);
  c["train"]["steps"] = 4;
  c["train"]["batch_size"] = 1;
  LightingStage full(c, memory_source(3), memory_source(1));
  const std::vector<double> all = run_losses(full, c, dir + "/a", "", 0);
  LightingStage first(c, memory_source(3), memory_source(1));
  run_losses(first, c, dir + "/b", "", 2);
  LightingStage second(c, memory_source(3), memory_source(1));
  const std::vector<double> tail = run_losses(second, c, dir + "/b", dir + "/b/last.safetensors", 0);
  ASSERT_EQ(tail.size(), 2u);
  EXPECT_EQ(tail[0], all[2]);
  EXPECT_EQ(tail[1], all[3]);
}

TEST(Trainer, NonFiniteLossNamesTheLossAndStepAndKeepsTheCheckpoint) {
  nlohmann::json c = tiny_config(kStageSky);
  c["loss"]["ae_hdr"] = std::numeric_limits<double>::infinity();  // forces an infinite total
  const std::string out = temp_dir("nonfinite");
  SkyStage stage(c);
  RunOptions o;
  o.out_dir = out;
  try {
    run_training(stage, c, o);
    FAIL() << "expected NonFiniteError";
  } catch (const NonFiniteError& e) {
    EXPECT_NE(std::string(e.what()).find("'loss'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("step 0"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(out + "/last.safetensors"));
}

TEST(Trainer, ResumeRejectsACheckpointOfAnotherStage) {
  const std::string dir = temp_dir("wrong_stage");
  nlohmann::json c = tiny_config(kStageLighting);
  const std::string sky = save_sky_checkpoint(c, dir);
  c["init"]["sky_checkpoint"] = sky;
  LightingStage stage(c, memory_source(1), memory_source(1));
  RunOptions o;
  o.out_dir = dir;
  o.resume = sky;
  EXPECT_THROW(run_training(stage, c, o), Error);
}

}  // namespace
}  // namespace sl::test

namespace sl::test {
namespace {

// Stage 3 renders with the estimator family inference uses (cosine + sky MIS, the sun
// included) and with Eq. 1 from model.volume; configs written before these keys existed keep
// what they trained with (cosine samples, metric spacing).
TEST(TrainConfig, TrainingInsertionUsesSkySamplingAndTheModelsEq1Options) {
  nlohmann::json c = default_train_config();
  const InsertionOptions o = training_insertion_options(c, 7);
  EXPECT_TRUE(o.importance_sampling);
  EXPECT_EQ(o.seed, 7u);
  EXPECT_EQ(o.query.samples, c.at("model").at("volume").at("samples").get<int>());
  EXPECT_EQ(o.query.spacing, SampleSpacing::kGrid);
  EXPECT_EQ(o.shadow_rays, c.at("insertion").at("shadow_rays").get<int>());
  c["insertion"].erase("importance_sampling");
  c["model"]["volume"].erase("spacing");
  c["model"]["volume"]["trilinear"] = true;
  const InsertionOptions old = training_insertion_options(c, 7);
  EXPECT_FALSE(old.importance_sampling);
  EXPECT_EQ(old.query.spacing, SampleSpacing::kMetric);
  EXPECT_TRUE(old.query.trilinear);
  c["model"]["volume"]["spacing"] = "log";
  try {
    (void)volume_query_options(c);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("model.volume.spacing"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace sl::test
