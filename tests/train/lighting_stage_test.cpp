// Stage 2 (Sec 3.4): the supervised lighting stage overfits a tiny batch, and each ablation
// variant of the predictor steps and validates.
#include "train/lighting_stage.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "data/image_io.h"
#include "data/panorama.h"
#include "data/sky_model.h"
#include "data/sun_extraction.h"
#include "nn/checkpoint.h"
#include "render/equirect.h"
#include "support/test_files.h"
#include "support/tiny_stage.h"
#include "train/image_statistics.h"
#include "train/sky_autoencoder.h"
#include "util/error.h"
#include "util/math.h"

namespace sl::test {
using train::LightingStage;
using train::Metrics;
using train::kStageLighting;

namespace {

// Trains a stage of config c for two steps and exports its predictor alone (as an exported model
// holds it) to `path`; `before_export` may read the trained stage first. Returns a copy of the
// predictor's tensors.
nn::StateDict export_trained_predictor(const nlohmann::json& c, const std::string& path,
                                       const std::function<void(LightingStage&)>& before_export = {}) {
  LightingStage stage(c, memory_source(2), memory_source(1));
  stage.initialise();
  overfit(stage, 2);
  if (before_export) before_export(stage);
  nn::Module holder("Exported");
  holder.register_module("predictor", std::shared_ptr<nn::Module>(&stage.predictor(), [](nn::Module*) {}));
  nn::save_checkpoint(path, holder, nullptr, nn::CheckpointInfo{.stage = kStageLighting});
  nn::StateDict state;
  for (const auto& [name, t] : stage.predictor().state_dict()) state[name] = t.clone();
  return state;
}

// Config c started from the exported model at `exported`, which holds no teacher: no stage-1
// checkpoint, and so none of the teacher's pseudo-labels.
nlohmann::json from_exported(const nlohmann::json& c, const std::string& exported) {
  nlohmann::json g = c;
  g["init"]["checkpoint"] = exported;
  g["init"]["sky_checkpoint"] = "";
  g["loss"]["sky_intensity"] = 0.0;
  g["loss"]["sky_latent"] = 0.0;
  return g;
}

// The sun head's logits and the sky latent for `image`, in eval mode (the stage is left training).
struct SkyAnswers {
  std::vector<double> logits, code;
};
SkyAnswers sky_answers(LightingStage& stage, const Tensor& image) {
  stage.predictor().set_training(false);
  const NoGradGuard no_grad;
  const train::SkyPrediction p = stage.predictor().predict_sky(image);
  SkyAnswers a{p.sun_logits.to_vector(), p.code.latent.to_vector()};
  stage.predictor().set_training(true);
  return a;
}

// A model grown from another starts from the same answers.
void expect_same_answers(const SkyAnswers& a, const SkyAnswers& before) {
  ASSERT_EQ(a.logits.size(), before.logits.size());
  for (size_t i = 0; i < a.logits.size(); ++i) EXPECT_NEAR(a.logits[i], before.logits[i], 1e-5) << i;
  ASSERT_EQ(a.code.size(), before.code.size());
  for (size_t i = 0; i < a.code.size(); ++i) EXPECT_NEAR(a.code[i], before.code[i], 1e-5) << i;
}

// A first layer widened from `old`: its columns, then zeros for the new inputs.
void expect_widened(const std::string& name, const Tensor& t, const Tensor& old) {
  ASSERT_EQ(t.dim(), 2) << name;
  ASSERT_EQ(t.size(0), old.size(0)) << name;
  ASSERT_GT(t.size(1), old.size(1)) << name;
  const std::vector<double> w = t.to_vector(), o = old.to_vector();
  for (int64_t r = 0; r < t.size(0); ++r)
    for (int64_t k = 0; k < t.size(1); ++k)
      ASSERT_EQ(w[r * t.size(1) + k], k < old.size(1) ? o[r * old.size(1) + k] : 0.0) << name << " " << r << ", " << k;
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

// train.freeze: a frozen backbone keeps every weight and batch-norm statistic bit for bit
// through training steps, while the sky head moves; an unknown part is refused by name.
TEST(LightingStage, FrozenPartsKeepTheirWeightsAndStatistics) {
  const std::string dir = temp_dir("lighting_freeze");
  nlohmann::json c = tiny_config(kStageLighting);
  c["init"]["sky_checkpoint"] = save_sky_checkpoint(c, dir);
  c["train"]["freeze"] = {"backbone"};
  LightingStage stage(c, memory_source(2), memory_source(1));
  stage.initialise();
  const auto copy = [](const nn::NamedTensors& ts) {
    std::vector<std::pair<std::string, std::vector<double>>> out;
    for (const auto& [n, t] : ts) out.emplace_back(n, t.to_vector());
    return out;
  };
  const auto backbone_params = copy(stage.predictor().backbone().named_parameters());
  const auto backbone_stats = copy(stage.predictor().backbone().named_buffers());
  const auto head_before = copy(stage.predictor().child("sky_head")->named_parameters());
  ASSERT_FALSE(backbone_stats.empty());  // the batch norms' running statistics
  for (int64_t s = 0; s < 3; ++s) stage.step(s);
  stage.validate();
  EXPECT_EQ(copy(stage.predictor().backbone().named_parameters()), backbone_params);
  EXPECT_EQ(copy(stage.predictor().backbone().named_buffers()), backbone_stats);
  EXPECT_NE(copy(stage.predictor().child("sky_head")->named_parameters()), head_before);
  for (const auto& [n, t] : stage.predictor().backbone().named_parameters()) EXPECT_FALSE(t.requires_grad()) << n;

  c["train"]["freeze"] = {"backbone", "trunk"};
  try {
    LightingStage bad(c, memory_source(2), memory_source(1));
    FAIL() << "an unknown part was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("'trunk'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("sky_head"), std::string::npos) << e.what();
  }
}

// init.checkpoint may be an exported model (the predictor alone, as models/streetlight.safetensors
// ships): the teacher then comes from init.sky_checkpoint. Its pseudo-labels are used only when its
// decoder is the predictor's frozen one, bit for bit; with sky_intensity = sky_latent = 0 any
// stage-1 checkpoint will do, and steps run without the teacher.
TEST(LightingStage, StartsFromAnExportedPredictorWithATeacherThatMatchesItsDecoder) {
  const std::string dir = temp_dir("lighting_exported");
  nlohmann::json c = tiny_config(kStageLighting);
  const std::string sky = save_sky_checkpoint(c, dir);
  c["init"]["sky_checkpoint"] = sky;
  const std::string exported = dir + "/exported.safetensors";
  std::vector<double> trained_head;
  {
    LightingStage stage(c, memory_source(2), memory_source(1));
    stage.initialise();
    overfit(stage, 2);
    nn::Module holder("Exported");
    holder.register_module("predictor", std::shared_ptr<nn::Module>(&stage.predictor(), [](nn::Module*) {}));
    nn::save_checkpoint(exported, holder, nullptr, nn::CheckpointInfo{.stage = kStageLighting});
    trained_head = stage.predictor().child("sky_head")->named_parameters().front().second.to_vector();
  }
  // A stage-1 checkpoint whose decoder differs from the predictor's in one weight.
  const std::string other = dir + "/other_sky.safetensors";
  {
    train::SkyAutoencoder ae(train::sky_options(c));
    nn::load_checkpoint(sky, ae, nullptr);
    nn::StateDict sd = ae.decoder()->state_dict();
    Tensor w = sd.begin()->second.clone();
    w.data<float>()[0] += 0.25f;
    sd[sd.begin()->first] = w;
    ae.decoder()->load_state_dict(sd);
    nn::save_checkpoint(other, ae, nullptr, nn::CheckpointInfo{.stage = train::kStageSky});
  }
  c["init"]["checkpoint"] = exported;
  {
    LightingStage stage(c, memory_source(2), memory_source(1));
    stage.initialise();
    EXPECT_EQ(stage.predictor().child("sky_head")->named_parameters().front().second.to_vector(), trained_head);
    EXPECT_TRUE(std::isfinite(stage.step(0).at("loss")));
  }
  const auto refused = [&](const nlohmann::json& config, const std::string& what) {
    LightingStage stage(config, memory_source(2), memory_source(1));
    try {
      stage.initialise();
      ADD_FAILURE() << "accepted: " << what;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  };
  nlohmann::json no_teacher = c;
  no_teacher["init"]["sky_checkpoint"] = "";
  refused(no_teacher, "holds no teacher");
  nlohmann::json mismatched = c;
  mismatched["init"]["sky_checkpoint"] = other;
  refused(mismatched, "is not the predictor's frozen sky decoder");
  mismatched["loss"]["sky_intensity"] = 0.0;
  mismatched["loss"]["sky_latent"] = 0.0;
  no_teacher["loss"]["sky_intensity"] = 0.0;
  no_teacher["loss"]["sky_latent"] = 0.0;
  for (const nlohmann::json& config : {mismatched, no_teacher}) {
    LightingStage stage(config, memory_source(2), memory_source(1));
    stage.initialise();
    const Metrics m = stage.step(0);
    EXPECT_TRUE(std::isfinite(m.at("loss")));
    EXPECT_EQ(m.count("sky_latent"), 0u);  // the teacher did not run
  }
}

// Issue 53: a sun head (model.sun_grid) trained by loss.sun_distribution can start from a model
// exported before it existed: every other tensor is the file's, the new head keeps its
// initialisation, and a step trains it (its weights move; the loss terms, the front/back one
// with them, are finite). Validation
// scores the distribution's mode.
TEST(LightingStage, ASunHeadStartsFromAModelWithoutOne) {
  const std::string dir = temp_dir("lighting_sun_head");
  nlohmann::json c = tiny_config(kStageLighting);
  c["init"]["sky_checkpoint"] = save_sky_checkpoint(c, dir);
  const std::string exported = dir + "/exported.safetensors";
  const nn::StateDict before = export_trained_predictor(c, exported);
  nlohmann::json g = from_exported(c, exported);
  g["loss"]["sun_distribution"] = 1.0;
  g["model"]["sun_grid"] = {{"elevation_bins", 4}, {"azimuth_bins", 16}};
  g["loss"]["sun_half"] = 0.5;
  LightingStage stage(g, memory_source(2), memory_source(1));
  stage.initialise();
  std::vector<double> head;
  for (const auto& [name, t] : stage.predictor().state_dict()) {
    if (name.rfind("sun_head.", 0) == 0) {
      if (head.empty()) head = t.to_vector();
      continue;
    }
    ASSERT_TRUE(before.count(name)) << name;
    EXPECT_EQ(t.to_vector(), before.at(name).to_vector()) << name;
  }
  ASSERT_FALSE(head.empty()) << "no sun head";
  const Metrics m = stage.step(0);
  ASSERT_TRUE(m.count("sun_distribution"));
  EXPECT_TRUE(std::isfinite(m.at("sun_distribution")));
  EXPECT_GT(m.at("sun_distribution"), 0.0);
  EXPECT_TRUE(m.count("sun_in_view_share"));
  ASSERT_TRUE(m.count("sun_half"));  // the front/back term, weighed
  EXPECT_TRUE(std::isfinite(m.at("sun_half")));
  EXPECT_GT(m.at("sun_half"), 0.0);
  EXPECT_NE(stage.predictor().child("sun_head")->named_parameters().front().second.to_vector(), head);
  const Metrics v = stage.validate();
  EXPECT_TRUE(std::isfinite(v.at("val_sun_error_median_deg")));
  // The loss needs the grid, and says so naming the key.
  nlohmann::json bad = train::default_train_config();
  bad["stage"] = kStageLighting;
  bad["data"]["dataset"] = "streets";
  bad["init"]["checkpoint"] = exported;
  bad["loss"]["sun_distribution"] = 1.0;
  try {
    train::check_train_config(bad);
    ADD_FAILURE() << "accepted loss.sun_distribution without model.sun_grid";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("model.sun_grid"), std::string::npos) << e.what();
  }
}

// Issue 53: a sun head from before model.sun_image_statistics is widened when a stage with the
// statistics starts from it: its first layer keeps the loaded columns and gets zero columns for
// the 102 statistics, so the sun's logits start where the loaded model's are; a step then trains
// the new columns.
// A model without the heads' grid (model.head_grid_channels) gains one: every head that reads
// the features keeps its weights for the pooled vector and gets zero columns for the grid, so the
// model starts from the loaded one's answers, and the grid then trains.
TEST(LightingStage, HeadsGainTheFeatureGridFromAModelWithout) {
  const std::string dir = temp_dir("lighting_head_grid");
  nlohmann::json c = tiny_config(kStageLighting);
  c["init"]["sky_checkpoint"] = save_sky_checkpoint(c, dir);
  c["loss"]["sun_distribution"] = 1.0;
  c["model"]["sun_grid"] = {{"elevation_bins", 4}, {"azimuth_bins", 16}};
  const std::string exported = dir + "/exported.safetensors";
  const Tensor image = Tensor::uniform({2, 3, c["model"]["image_height"].get<int64_t>(),
                                        c["model"]["image_width"].get<int64_t>()}, 0.0, 1.0, 7);
  SkyAnswers answers_before;
  const nn::StateDict before = export_trained_predictor(
      c, exported, [&](LightingStage& stage) { answers_before = sky_answers(stage, image); });
  nlohmann::json g = from_exported(c, exported);
  g["model"]["head_grid_channels"] = 2;
  LightingStage stage(g, memory_source(2), memory_source(1));
  stage.initialise();
  int widened = 0;
  for (const auto& [name, t] : stage.predictor().state_dict()) {
    if (name.rfind("head_grid.", 0) == 0) continue;  // new: its own initialisation
    ASSERT_TRUE(before.count(name)) << name;
    const Tensor& old = before.at(name);
    if (t.shape() == old.shape()) {
      EXPECT_EQ(t.to_vector(), old.to_vector()) << name;
      continue;
    }
    ++widened;
    expect_widened(name, t, old);
  }
  EXPECT_EQ(widened, 3);  // the sky head, the sun head and the volume MLP
  expect_same_answers(sky_answers(stage, image), answers_before);
  EXPECT_TRUE(std::isfinite(stage.step(0).at("loss")));
  const Tensor w = stage.predictor().state_dict().at("sun_head.net.0.weight");
  const int64_t old_cols = before.at("sun_head.net.0.weight").size(1);
  const std::vector<double> v = w.to_vector();
  double moved = 0;
  for (size_t i = 0; i < v.size(); ++i)
    if (static_cast<int64_t>(i) % w.size(1) >= old_cols) moved += std::fabs(v[i]);
  EXPECT_GT(moved, 0.0) << "the grid's columns did not train";
}

TEST(LightingStage, AResNet18BackboneDeepensToAResNet34WithTheSameAnswers) {
  const std::string dir = temp_dir("lighting_deepen");
  nlohmann::json c = tiny_config(kStageLighting);
  c["init"]["sky_checkpoint"] = save_sky_checkpoint(c, dir);
  c["loss"]["sun_distribution"] = 1.0;
  c["model"]["sun_grid"] = {{"elevation_bins", 4}, {"azimuth_bins", 16}};
  ASSERT_EQ(c["model"]["backbone_depth"].get<int>(), 18);
  const std::string exported = dir + "/exported.safetensors";
  const Tensor image = Tensor::uniform({2, 3, c["model"]["image_height"].get<int64_t>(),
                                        c["model"]["image_width"].get<int64_t>()}, 0.0, 1.0, 7);
  SkyAnswers answers_before;
  const nn::StateDict before = export_trained_predictor(
      c, exported, [&](LightingStage& stage) { answers_before = sky_answers(stage, image); });
  nlohmann::json g = from_exported(c, exported);
  g["model"]["backbone_depth"] = 34;
  LightingStage stage(g, memory_source(2), memory_source(1));
  stage.initialise();
  std::set<std::string> added;  // the new blocks, "backbone.layerK.J"
  for (const auto& [name, t] : stage.predictor().state_dict()) {
    if (before.count(name)) {
      EXPECT_EQ(t.to_vector(), before.at(name).to_vector()) << name;
      continue;
    }
    // Only ResNet-34's extra blocks are new; each ends in a batch norm that starts at zero.
    ASSERT_EQ(name.rfind("backbone.layer", 0), 0u) << name;
    added.insert(name.substr(0, name.find('.', name.find('.', std::string("backbone.").size()) + 1)));
    if (name.ends_with(".bn2.weight") || name.ends_with(".bn2.bias")) {
      for (double v : t.to_vector()) ASSERT_EQ(v, 0.0) << name;
    }
  }
  // ResNet-34 has [3, 4, 6, 3] blocks where ResNet-18 has [2, 2, 2, 2].
  EXPECT_EQ(added, (std::set<std::string>{"backbone.layer1.2", "backbone.layer2.2", "backbone.layer2.3",
                                          "backbone.layer3.2", "backbone.layer3.3", "backbone.layer3.4",
                                          "backbone.layer3.5", "backbone.layer4.2"}));
  expect_same_answers(sky_answers(stage, image), answers_before);
  EXPECT_TRUE(std::isfinite(stage.step(0).at("loss")));
  // The zero scales take gradients: the new blocks train.
  double moved = 0;
  for (double v : stage.predictor().state_dict().at("backbone.layer3.5.bn2.weight").to_vector()) moved += std::fabs(v);
  EXPECT_GT(moved, 0.0) << "the new blocks did not train";
}

TEST(LightingStage, ANarrowBackboneWidensAndDeepensWithTheSameAnswers) {
  const std::string dir = temp_dir("lighting_widen");
  nlohmann::json c = tiny_config(kStageLighting);
  c["init"]["sky_checkpoint"] = save_sky_checkpoint(c, dir);
  c["loss"]["sun_distribution"] = 1.0;
  c["model"]["sun_grid"] = {{"elevation_bins", 4}, {"azimuth_bins", 16}};
  const int64_t width = c["model"]["backbone_width"].get<int64_t>();
  const std::string exported = dir + "/exported.safetensors";
  const Tensor image = Tensor::uniform({2, 3, c["model"]["image_height"].get<int64_t>(),
                                        c["model"]["image_width"].get<int64_t>()}, 0.0, 1.0, 7);
  SkyAnswers answers_before;
  const nn::StateDict before = export_trained_predictor(
      c, exported, [&](LightingStage& stage) { answers_before = sky_answers(stage, image); });
  nlohmann::json g = from_exported(c, exported);
  g["model"]["backbone_width"] = 2 * width;
  g["model"]["backbone_depth"] = 34;
  LightingStage stage(g, memory_source(2), memory_source(1));
  stage.initialise();
  int widened = 0;
  for (const auto& [name, t] : stage.predictor().state_dict()) {
    if (!before.count(name)) continue;  // ResNet-34's extra blocks (the test above)
    const Tensor& old = before.at(name);
    if (t.shape() == old.shape()) {
      EXPECT_EQ(t.to_vector(), old.to_vector()) << name;
      continue;
    }
    // The old tensor sits in the leading corner: its channels keep their indices.
    ++widened;
    ASSERT_EQ(t.dim(), old.dim()) << name;
    const int64_t inner = t.numel() / (t.size(0) * (t.dim() > 1 ? t.size(1) : 1));
    const std::vector<double> w = t.to_vector(), o = old.to_vector();
    const int64_t cols = t.dim() > 1 ? t.size(1) : 1, old_cols = old.dim() > 1 ? old.size(1) : 1;
    for (int64_t r = 0; r < old.size(0); ++r)
      for (int64_t k = 0; k < old_cols; ++k)
        for (int64_t i = 0; i < inner; ++i)
          ASSERT_EQ(w[(r * cols + k) * inner + i], o[(r * old_cols + k) * inner + i]) << name << " " << r << ", " << k;
  }
  EXPECT_GT(widened, 50);  // the backbone's convs and batch norms, and the heads' first layers
  expect_same_answers(sky_answers(stage, image), answers_before);
  // The new stream channels start at zero scale and train: the weights from them into the old
  // channels move in the first step, and with them the scales in the second.
  for (int64_t step = 0; step < 3; ++step) EXPECT_TRUE(std::isfinite(stage.step(step).at("loss")));
  const std::vector<double> gamma = stage.predictor().state_dict().at("backbone.layer2.1.bn2.weight").to_vector();
  double moved = 0;
  for (size_t i = 2 * width; i < gamma.size(); ++i) moved += std::fabs(gamma[i]);
  EXPECT_GT(moved, 0.0) << "the new channels did not train";
  // A wider backbone cannot go between the columns of the heads' later inputs.
  nlohmann::json bad = g;
  bad["model"]["head_grid_channels"] = 2;
  LightingStage refused(bad, memory_source(2), memory_source(1));
  try {
    refused.initialise();
    FAIL() << "a wider backbone with a new head grid was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("model.backbone_width"), std::string::npos) << e.what();
  }
}

TEST(LightingStage, ASunHeadGainsImageStatisticsFromAModelWithout) {
  const std::string dir = temp_dir("lighting_sun_statistics");
  nlohmann::json c = tiny_config(kStageLighting);
  c["init"]["sky_checkpoint"] = save_sky_checkpoint(c, dir);
  c["loss"]["sun_distribution"] = 1.0;
  c["model"]["sun_grid"] = {{"elevation_bins", 4}, {"azimuth_bins", 16}};
  const std::string exported = dir + "/exported.safetensors";
  const Tensor image = Tensor::uniform({2, 3, c["model"]["image_height"].get<int64_t>(),
                                        c["model"]["image_width"].get<int64_t>()}, 0.0, 1.0, 7);
  std::vector<double> logits_before;
  const nn::StateDict before = export_trained_predictor(c, exported, [&](LightingStage& stage) {
    stage.predictor().set_training(false);
    const NoGradGuard no_grad;
    logits_before = stage.predictor().predict_sky(image).sun_logits.to_vector();
  });
  nlohmann::json g = from_exported(c, exported);
  g["model"]["sun_image_statistics"] = true;
  LightingStage stage(g, memory_source(2), memory_source(1));
  stage.initialise();
  for (const auto& [name, t] : stage.predictor().state_dict()) {
    ASSERT_TRUE(before.count(name)) << name;
    if (name != "sun_head.net.0.weight") {
      EXPECT_EQ(t.to_vector(), before.at(name).to_vector()) << name;
      continue;
    }
    const Tensor& old = before.at(name);
    ASSERT_EQ(t.size(1), old.size(1) + train::kImageStatistics);
    expect_widened(name, t, old);
  }
  {
    stage.predictor().set_training(false);
    const NoGradGuard no_grad;
    const std::vector<double> logits = stage.predictor().predict_sky(image).sun_logits.to_vector();
    ASSERT_EQ(logits.size(), logits_before.size());
    for (size_t i = 0; i < logits.size(); ++i) EXPECT_NEAR(logits[i], logits_before[i], 1e-5) << i;
    stage.predictor().set_training(true);
  }
  const Metrics m = stage.step(0);
  EXPECT_TRUE(std::isfinite(m.at("sun_distribution")));
  const std::vector<double> w = stage.predictor().state_dict().at("sun_head.net.0.weight").to_vector();
  const int64_t cols = before.at("sun_head.net.0.weight").size(1) + train::kImageStatistics;
  double moved = 0;
  for (size_t i = 0; i < w.size(); ++i)
    if (static_cast<int64_t>(i % cols) >= cols - train::kImageStatistics) moved += std::fabs(w[i]);
  EXPECT_GT(moved, 0.0) << "the statistics' columns did not train";
  // The statistics need the sun head, and say so naming the key.
  nlohmann::json bad = c;
  bad["model"]["sun_grid"] = {{"elevation_bins", 0}, {"azimuth_bins", 0}};
  bad["loss"]["sun_distribution"] = 0.0;
  bad["model"]["sun_image_statistics"] = true;
  try {
    LightingStage refused(bad, memory_source(2), memory_source(1));
    ADD_FAILURE() << "accepted model.sun_image_statistics without model.sun_grid";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("model.sun_image_statistics"), std::string::npos) << e.what();
  }
}

// Issue 53: a sun head gains its own backbone (model.sun_backbone, an ImageNet MobileNetV2) from a
// model without one: the loaded tensors are unchanged, the sun head's first layer gets zero columns
// for the new map, so the logits start where the loaded model's are; init.sun_backbone_weights
// puts the ImageNet weights in the new backbone, and a step trains the new columns.
TEST(LightingStage, ASunHeadGainsItsOwnImageNetBackboneFromAModelWithout) {
  const std::string dir = temp_dir("lighting_sun_backbone");
  nlohmann::json c = tiny_config(kStageLighting);
  c["init"]["sky_checkpoint"] = save_sky_checkpoint(c, dir);
  c["loss"]["sun_distribution"] = 1.0;
  c["model"]["sun_grid"] = {{"elevation_bins", 4}, {"azimuth_bins", 16}};
  const std::string exported = dir + "/exported.safetensors";
  const Tensor image = Tensor::uniform({2, 3, c["model"]["image_height"].get<int64_t>(),
                                        c["model"]["image_width"].get<int64_t>()}, 0.0, 1.0, 7);
  std::vector<double> logits_before;
  const nn::StateDict before = export_trained_predictor(c, exported, [&](LightingStage& stage) {
    stage.predictor().set_training(false);
    const NoGradGuard no_grad;
    logits_before = stage.predictor().predict_sky(image).sun_logits.to_vector();
  });
  nlohmann::json g = from_exported(c, exported);
  g["model"]["sun_backbone"] = "mobilenet_v2";
  g["model"]["sun_backbone_channels"] = 2;
  const std::string weights = shared_data("weights/mobilenet_v2_1.0_224_quant.tflite");
  const bool imagenet = std::filesystem::is_regular_file(weights);
  if (imagenet) g["init"]["sun_backbone_weights"] = weights;
  LightingStage stage(g, memory_source(2), memory_source(1));
  stage.initialise();
  const auto hw = train::backbone_grid_size(c["model"]["image_height"].get<int64_t>(), c["model"]["image_width"].get<int64_t>());
  for (const auto& [name, t] : stage.predictor().state_dict()) {
    if (name.rfind("sun_backbone", 0) == 0) continue;  // new
    ASSERT_TRUE(before.count(name)) << name;
    if (name != "sun_head.net.0.weight") {
      EXPECT_EQ(t.to_vector(), before.at(name).to_vector()) << name;
      continue;
    }
    ASSERT_EQ(t.size(1), before.at(name).size(1) + 2 * hw[0] * hw[1]);
    expect_widened(name, t, before.at(name));
  }
  if (imagenet) {  // the stem holds the file's weights, not the seeded initialisation
    const nn::MobileNetV2 fresh;
    EXPECT_NE(stage.predictor().sun_backbone()->stem().parameter("weight").to_vector(),
              fresh.stem().parameter("weight").to_vector());
  }
  {
    stage.predictor().set_training(false);
    const NoGradGuard no_grad;
    const std::vector<double> logits = stage.predictor().predict_sky(image).sun_logits.to_vector();
    ASSERT_EQ(logits.size(), logits_before.size());
    for (size_t i = 0; i < logits.size(); ++i) EXPECT_NEAR(logits[i], logits_before[i], 1e-5) << i;
    stage.predictor().set_training(true);
  }
  const Metrics m = stage.step(0);
  EXPECT_TRUE(std::isfinite(m.at("sun_distribution")));
  const Tensor w = stage.predictor().state_dict().at("sun_head.net.0.weight");
  const int64_t old_cols = before.at("sun_head.net.0.weight").size(1);
  const std::vector<double> v = w.to_vector();
  double moved = 0;
  for (size_t i = 0; i < v.size(); ++i)
    if (static_cast<int64_t>(i) % w.size(1) >= old_cols) moved += std::fabs(v[i]);
  EXPECT_GT(moved, 0.0) << "the new backbone's columns did not train";
  // The backbone needs the sun head, and its weights need the backbone: each refusal names its key.
  nlohmann::json bad = c;
  bad["model"]["sun_grid"] = {{"elevation_bins", 0}, {"azimuth_bins", 0}};
  bad["loss"]["sun_distribution"] = 0.0;
  bad["model"]["sun_backbone"] = "mobilenet_v2";
  try {
    LightingStage refused(bad, memory_source(2), memory_source(1));
    ADD_FAILURE() << "accepted model.sun_backbone without model.sun_grid";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("model.sun_backbone"), std::string::npos) << e.what();
  }
  nlohmann::json unknown = g;
  unknown["model"]["sun_backbone"] = "resnet50";
  EXPECT_THROW(LightingStage(unknown, memory_source(2), memory_source(1)), Error);
  nlohmann::json orphan = from_exported(c, exported);
  orphan["init"]["sun_backbone_weights"] = weights;
  LightingStage without(orphan, memory_source(2), memory_source(1));
  try {
    without.initialise();
    ADD_FAILURE() << "accepted init.sun_backbone_weights without model.sun_backbone";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("init.sun_backbone_weights"), std::string::npos) << e.what();
  }
}

// init.reinitialise: the named parts start from the predictor's own initialisation for the
// config's seed, every other tensor (the frozen sky decoder among them) from the checkpoint; a
// part that does not exist, or the sky decoder, is refused naming the parts.
TEST(LightingStage, ReinitialisedPartsStartAfreshAndTheRestFromTheCheckpoint) {
  const std::string dir = temp_dir("lighting_reinitialise");
  nlohmann::json c = tiny_config(kStageLighting);
  c["init"]["sky_checkpoint"] = save_sky_checkpoint(c, dir);
  const std::string exported = dir + "/exported.safetensors";
  const nn::StateDict trained = export_trained_predictor(c, exported);
  nlohmann::json g = from_exported(c, exported);
  g["init"]["reinitialise"] = {"backbone", "sky_head"};
  LightingStage stage(g, memory_source(2), memory_source(1));
  stage.initialise();
  const train::LightingPredictor fresh(stage.predictor().options());
  const nn::StateDict initial = fresh.state_dict();
  int afresh = 0, loaded = 0;
  for (const auto& [name, t] : stage.predictor().state_dict()) {
    const bool again = name.rfind("backbone.", 0) == 0 || name.rfind("sky_head.", 0) == 0;
    EXPECT_EQ(t.to_vector(), (again ? initial : trained).at(name).to_vector()) << name;
    (again ? afresh : loaded) += 1;
    if (again && name.find("weight") != std::string::npos) {
      EXPECT_NE(t.to_vector(), trained.at(name).to_vector()) << name;
    }
  }
  EXPECT_GT(afresh, 0);
  EXPECT_GT(loaded, 0);
  EXPECT_TRUE(std::isfinite(stage.step(0).at("loss")));
  for (const char* bad : {"sky_decoder", "backbnoe"}) {
    nlohmann::json b = g;
    b["init"]["reinitialise"] = {bad};
    LightingStage refused(b, memory_source(2), memory_source(1));
    try {
      refused.initialise();
      ADD_FAILURE() << "accepted init.reinitialise " << bad;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("init.reinitialise"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("backbone"), std::string::npos) << e.what();
    }
  }
  nlohmann::json none = train::default_train_config();
  none["stage"] = kStageLighting;
  none["data"]["dataset"] = "streets";
  none["init"]["sky_checkpoint"] = "sky.safetensors";
  none["init"]["reinitialise"] = {"backbone"};
  try {
    train::check_train_config(none);
    ADD_FAILURE() << "accepted init.reinitialise without init.checkpoint";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("init.checkpoint"), std::string::npos) << e.what();
  }
}

// Two labelled LDR panoramas (one sun at a pixel, one "none") written as PNG files with their
// labels, read by ldr_panorama_source: mixed into training, they give finite steps; in
// validation, their suns are scored apart as val_ldr_*.
TEST(LightingStage, LdrPanoramasTrainAndValidateApart) {
  const std::string dir = temp_dir("lighting_ldr");
  data::SkyParams sp;
  sp.sun_elevation_rad = 20.0 * kPi / 180.0;
  sp.sun_azimuth_rad = 0.4;
  const Tensor hdr = data::PreethamSky(sp).render(64, 128);
  const Tensor ldr = data::to_ldr(hdr, render::exposure_for_ldr_median(hdr, 0.4));
  const data::SunEstimate sun = data::extract_sun(hdr);
  const auto uv = render::equirect::direction_to_uv(sun.direction.x, sun.direction.y, sun.direction.z, 2048, 1024);
  data::ImageWriteOptions wo;
  wo.transfer = data::Transfer::Linear;  // codes = LDR·255, read back as codes / 255
  data::write_image(dir + "/a.png", ldr, wo);
  data::write_image(dir + "/b.png", ldr, wo);
  {
    std::ofstream csv(dir + "/sun_labels.csv");
    csv << "file,sun,u,v,confidence,scene,note\n";
    csv << "a.png,visible," << uv.u << "," << uv.v << ",high,street,\n";
    csv << "b.png,none,,,high,street,\n";
  }
  nlohmann::json c = tiny_config(kStageLighting);
  c["init"]["sky_checkpoint"] = save_sky_checkpoint(c, dir);
  c["loss"]["sun_energy"] = 1.0;
  // A span no untrained sun reaches, so every sunny LDR crop in a batch adds to the range term.
  c["loss"]["ldr_sun_energy"] = 1.0;
  c["loss"]["ldr_sun_energy_range"] = {1e4, 1e5};
  data::PanoramaSampleOptions o;
  o.crop.width = 64;
  o.crop.height = 32;
  o.pano_width = 64;
  o.pano_height = 32;
  const std::vector<std::string> paths = {dir + "/a.png", dir + "/b.png"};
  const train::SampleSource train_ldr = train::ldr_panorama_source(paths, dir + "/sun_labels.csv", o, 1, 2, true, 128);
  const data::StreetSample a = train_ldr.load(0, 0), b = train_ldr.load(1, 0);
  EXPECT_TRUE(a.sun_known);
  EXPECT_FALSE(b.sun_known);
  EXPECT_EQ(a.id.rfind("ldr:a.png#", 0), 0u) << a.id;
  o.flip = false;
  o.exposure_stops = o.white_balance_stops = 0.0;
  LightingStage stage(c, train::mixed_source(memory_source(2), train_ldr, 0.5),
                      train::concat_sources(memory_source(1),
                                            train::ldr_panorama_source(paths, dir + "/sun_labels.csv", o, 2, 4, false, 128)));
  stage.initialise();
  double energy = 0.0, ldr_energy = 0.0;
  for (int64_t step = 0; step < 3; ++step) {
    const Metrics m = stage.step(step);
    for (const auto& [k, v] : m) EXPECT_TRUE(std::isfinite(v)) << k << " at step " << step;
    energy += m.at("sun_energy");
    ldr_energy += m.at("ldr_sun_energy");
  }
  EXPECT_GT(energy, 0.0);      // loss.sun_energy: the streets' HDR skies label the sun's energy
  EXPECT_GT(ldr_energy, 0.0);  // loss.ldr_sun_energy: the sunny LDR panorama 'a' has only a span
  const Metrics v = stage.validate();
  ASSERT_TRUE(v.count("val_ldr_sun_error_median_deg"));
  EXPECT_TRUE(std::isfinite(v.at("val_ldr_sun_error_median_deg")));
  // The error in parts per group (train/sun_error_parts.h): a share in [0, 1] and a finite bias.
  for (const char* g : {"ldr", "street"}) {
    const std::string pre = std::string("val_") + g + "_sun_";
    ASSERT_TRUE(v.count(pre + "wrong_half_share")) << g;
    EXPECT_GE(v.at(pre + "wrong_half_share"), 0.0);
    EXPECT_LE(v.at(pre + "wrong_half_share"), 1.0);
    EXPECT_TRUE(std::isfinite(v.at(pre + "elevation_bias_deg"))) << g;
  }
  EXPECT_TRUE(std::isfinite(v.at("val_loss")));
  // A panorama without a label row is refused, naming it and the labels file.
  {
    std::ofstream csv(dir + "/only_a.csv");
    csv << "file,sun,u,v,confidence,scene,note\na.png,none,,,high,street,\n";
  }
  try {
    train::ldr_panorama_source(paths, dir + "/only_a.csv", o, 1, 2, true, 128);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("b.png"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("only_a.csv"), std::string::npos) << e.what();
  }
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
