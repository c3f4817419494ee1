// The training loop: bit-identical resume after a SIGINT-style stop, the non-finite guard, and a
// checkpoint of another stage refused on resume.
#include "train/trainer.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "nn/safetensors.h"
#include "support/tiny_stage.h"
#include "train/lighting_stage.h"
#include "train/sky_stage.h"
#include "util/error.h"

namespace sl::test {
using train::LightingStage;
using train::Metrics;
using train::NonFiniteError;
using train::check_finite_gradients;
using train::clip_finite_gradients;
using train::RunOptions;
using train::RunResult;
using train::SkyStage;
using train::Stage;
using train::kStageLighting;
using train::kStageSky;
using train::request_stop;
using train::run_training;

namespace {

namespace fs = std::filesystem;

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

// A run cut after head.size() steps and resumed (tail) computed, loss for loss, what the
// uninterrupted run computed (all).
void expect_same_losses_as_one_run(const std::vector<double>& head, const std::vector<double>& tail,
                                   const std::vector<double>& all) {
  ASSERT_EQ(head.size() + tail.size(), all.size());
  for (size_t i = 0; i < head.size(); ++i) EXPECT_EQ(head[i], all[i]) << "step " << i + 1;
  for (size_t i = 0; i < tail.size(); ++i) EXPECT_EQ(tail[i], all[head.size() + i]) << "step " << head.size() + i + 1;
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
  expect_same_losses_as_one_run(head, tail, all);
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

// Validation reads the model and changes nothing it trains: a lighting run validated after every
// step ends with the weights of one validated once, at its end. So a stage whose last checkpoint
// is what the next step uses may validate as rarely as its monitoring needs (scripts/train_release.sh).
TEST(Trainer, ValidationLeavesTheTrainedWeightsUnchanged) {
  const std::string dir = temp_dir("val_every_light");
  nlohmann::json c = tiny_config(kStageLighting);
  c["init"]["sky_checkpoint"] = save_sky_checkpoint(c, dir);
  c["train"]["steps"] = 4;
  c["train"]["batch_size"] = 1;
  nlohmann::json often = c, once = c;
  often["train"]["val_every"] = 1;
  once["train"]["val_every"] = 4;
  LightingStage a(often, memory_source(3), memory_source(2));
  const std::vector<double> la = run_losses(a, often, dir + "/often", "", 0);
  LightingStage b(once, memory_source(3), memory_source(2));
  const std::vector<double> lb = run_losses(b, once, dir + "/once", "", 0);
  EXPECT_EQ(la, lb);
  // Parameters and buffers (the batch-norm statistics) alike.
  for (const bool buffers : {false, true}) {
    const auto ta = buffers ? a.model().named_buffers() : a.model().named_parameters();
    const auto tb = buffers ? b.model().named_buffers() : b.model().named_parameters();
    ASSERT_EQ(ta.size(), tb.size());
    EXPECT_GT(ta.size(), 0u);
    for (size_t i = 0; i < ta.size(); ++i) {
      ASSERT_EQ(ta[i].first, tb[i].first);
      EXPECT_EQ(ta[i].second.to_vector(), tb[i].second.to_vector()) << ta[i].first;
    }
  }
}

// optim.schedule_steps: a run that stops at train.steps = 2 under a 6-step schedule, then resumes
// with train.steps = 6, computes what one 6-step run computes; the schedule, not where the run
// stops, sets the rate.
TEST(Trainer, AStopInsideALongerScheduleResumesBitIdentically) {
  const nlohmann::json c = tiny_config(kStageSky);
  ASSERT_EQ(c["train"]["steps"], 6);
  const std::string a = temp_dir("schedule_sky_a"), b = temp_dir("schedule_sky_b");
  SkyStage full(c);
  const std::vector<double> all = run_losses(full, c, a, "", 0);
  nlohmann::json head_config = c;
  head_config["train"]["steps"] = 2;
  head_config["optim"]["schedule_steps"] = 6;
  SkyStage first(head_config);
  const std::vector<double> head = run_losses(first, head_config, b, "", 0);
  ASSERT_EQ(head.size(), 2u);
  SkyStage second(c);
  const std::vector<double> tail = run_losses(second, c, b, b + "/last.safetensors", 0);
  ASSERT_EQ(tail.size(), 4u);
  expect_same_losses_as_one_run(head, tail, all);
  // Without schedule_steps the 2-step run anneals to min_lr by its end and the runs part.
  nlohmann::json short_config = c;
  short_config["train"]["steps"] = 2;
  SkyStage alone(short_config);
  const std::string d = temp_dir("schedule_sky_d");
  run_losses(alone, short_config, d, "", 0);
  SkyStage after(c);
  const std::vector<double> other = run_losses(after, c, d, d + "/last.safetensors", 0);
  ASSERT_EQ(other.size(), 4u);
  EXPECT_NE(other[0], all[2]);
}

// optim.ema_decay: a resumed run ends with the same weights and averages, and best.safetensors
// (written at the one validation, the last step) holds the averages as its model and the raw
// weights as "optim.average.*": last.safetensors the other way round.
TEST(Trainer, WeightAverageResumesBitIdenticallyAndBestHoldsTheAverage) {
  nlohmann::json c = tiny_config(kStageSky);
  c["optim"]["ema_decay"] = 0.5;
  c["train"]["val_every"] = c["train"]["steps"];
  const std::string a = temp_dir("ema_sky_a"), b = temp_dir("ema_sky_b");
  SkyStage full(c);
  run_losses(full, c, a, "", 0);
  SkyStage first(c);
  run_losses(first, c, b, "", 2);
  SkyStage second(c);
  run_losses(second, c, b, b + "/last.safetensors", 0);
  const nn::SafetensorsFile la = nn::read_safetensors(a + "/last.safetensors");
  const nn::SafetensorsFile lb = nn::read_safetensors(b + "/last.safetensors");
  const nn::SafetensorsFile best = nn::read_safetensors(a + "/best.safetensors");
  size_t averaged = 0, differ = 0;
  for (const auto& [name, p] : full.model().named_parameters()) {
    const std::string avg = "optim.average." + name;
    ASSERT_TRUE(la.tensors.count(avg)) << avg;
    EXPECT_EQ(la.tensors.at(name).to_vector(), lb.tensors.at(name).to_vector()) << name;
    EXPECT_EQ(la.tensors.at(avg).to_vector(), lb.tensors.at(avg).to_vector()) << avg;
    EXPECT_EQ(best.tensors.at(name).to_vector(), la.tensors.at(avg).to_vector()) << name;
    EXPECT_EQ(best.tensors.at(avg).to_vector(), la.tensors.at(name).to_vector()) << avg;
    ++averaged;
    differ += la.tensors.at(name).to_vector() != la.tensors.at(avg).to_vector();
  }
  EXPECT_GT(averaged, 0u);
  EXPECT_GT(differ, 0u);  // the average is not the last weights
}

// The gradient check reads every element (a NaN or Inf anywhere, in float and double) and names
// the first parameter that holds one; so does the clipping that the stages call in its place, which
// otherwise clips as nn::clip_grad_norm does.
TEST(Trainer, NonFiniteGradientAnywhereNamesItsParameter) {
  const auto with_grad = [](DType dtype, int64_t bad_at, double bad) {
    Tensor p = Tensor::zeros({1001}, dtype).set_requires_grad(true);
    std::vector<double> g(1001, 0.5);
    if (bad_at >= 0) g[static_cast<size_t>(bad_at)] = bad;
    p.set_grad(Tensor::from_vector(g, {1001}, dtype));
    return p;
  };
  for (const DType dtype : {DType::F32, DType::F64}) {
    EXPECT_NO_THROW(check_finite_gradients({{"fine", with_grad(dtype, -1, 0)}}, 3));
    for (const int64_t at : {int64_t{0}, int64_t{517}, int64_t{1000}})
      for (const double bad : {std::numeric_limits<double>::quiet_NaN(), -std::numeric_limits<double>::infinity()}) {
        try {
          check_finite_gradients({{"fine", with_grad(dtype, -1, 0)}, {"head.w", with_grad(dtype, at, bad)}}, 3);
          ADD_FAILURE() << "missed " << bad << " at " << at;
        } catch (const NonFiniteError& e) {
          EXPECT_NE(std::string(e.what()).find("'head.w'"), std::string::npos) << e.what();
          EXPECT_NE(std::string(e.what()).find("step 3"), std::string::npos) << e.what();
        }
        try {
          clip_finite_gradients({{"fine", with_grad(dtype, -1, 0)}, {"head.w", with_grad(dtype, at, bad)}}, 1.0, 4);
          ADD_FAILURE() << "clipping missed " << bad << " at " << at;
        } catch (const NonFiniteError& e) {
          EXPECT_NE(std::string(e.what()).find("'head.w'"), std::string::npos) << e.what();
          EXPECT_NE(std::string(e.what()).find("step 4"), std::string::npos) << e.what();
        }
      }
    // Finite gradients: the same norm and the same clipped gradients as nn::clip_grad_norm.
    const nn::NamedTensors a{{"fine", with_grad(dtype, -1, 0)}, {"head.w", with_grad(dtype, 517, -3.0)}};
    const nn::NamedTensors b{{"fine", with_grad(dtype, -1, 0)}, {"head.w", with_grad(dtype, 517, -3.0)}};
    EXPECT_EQ(clip_finite_gradients(a, 1.0, 5), nn::clip_grad_norm(b, 1.0));
    for (size_t i = 0; i < a.size(); ++i) {
      EXPECT_EQ(a[i].second.grad().to_vector(), b[i].second.grad().to_vector()) << a[i].first;
      EXPECT_LT(a[i].second.grad().to_vector()[0], 0.5) << "not clipped";
    }
  }
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
