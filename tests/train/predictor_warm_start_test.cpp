// Starting stage 2 from a checkpoint that is not the model being trained (train/predictor_warm_start.h,
// init.checkpoint, init.reinitialise): an exported predictor with a teacher of its own; a model that
// grows (a sun head, the heads' feature grid, a deeper or wider backbone, image statistics or an
// ImageNet backbone for the sun head, the volume branch) keeps every loaded tensor and starts from
// the loaded model's answers, and what is new trains; parts named for reinitialisation start afresh.
#include "train/predictor_warm_start.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <functional>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "nn/checkpoint.h"
#include "nn/modules/mobilenet_v2.h"
#include "support/test_files.h"
#include "support/tiny_stage.h"
#include "train/image_statistics.h"
#include "train/lighting_stage.h"
#include "train/sky_autoencoder.h"
#include "util/error.h"

namespace sl::test {
using train::LightingStage;
using train::Metrics;
using train::kStageLighting;

namespace {

// The sun head's logits (empty without one) and the sky latent for `image`, in eval mode (the stage
// is left training).
struct SkyAnswers {
  std::vector<double> logits, code;
};
SkyAnswers sky_answers(LightingStage& stage, const Tensor& image) {
  stage.predictor().set_training(false);
  const NoGradGuard no_grad;
  const train::SkyPrediction p = stage.predictor().predict_sky(image);
  SkyAnswers a{p.sun_logits.defined() ? p.sun_logits.to_vector() : std::vector<double>{}, p.code.latent.to_vector()};
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

// Σ |w| over the columns of a 2-D weight from `first_new` on: > 0 once the new inputs trained.
double new_columns_mass(const Tensor& w, int64_t first_new) {
  const std::vector<double> v = w.to_vector();
  double mass = 0.0;
  for (size_t i = 0; i < v.size(); ++i)
    if (static_cast<int64_t>(i) % w.size(1) >= first_new) mass += std::fabs(v[i]);
  return mass;
}

// The message of the sl::Error that `f` throws; a failure when it throws none.
std::string refusal(const std::function<void()>& f, const std::string& what) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  ADD_FAILURE() << "accepted: " << what;
  return {};
}

// Every test starts the same way: a tiny lighting config (with a sun head unless told otherwise),
// its predictor trained two steps and exported alone to `exported`, as models/streetlight.safetensors
// ships; `before` holds a copy of its tensors and `answers` its sky answers for `image`.
class PredictorWarmStart : public ::testing::Test {
 protected:
  void export_model(const std::string& name, bool sun_head = true, bool volume = true) {
    dir = temp_dir(name);
    c = tiny_config(kStageLighting);
    c["model"]["volume_branch"] = volume;
    sky = save_sky_checkpoint(c, dir);
    c["init"]["sky_checkpoint"] = sky;
    if (sun_head) {
      c["loss"]["sun_distribution"] = 1.0;
      c["model"]["sun_grid"] = {{"elevation_bins", 4}, {"azimuth_bins", 16}};
    }
    exported = dir + "/exported.safetensors";
    image = Tensor::uniform({2, 3, c["model"]["image_height"].get<int64_t>(), c["model"]["image_width"].get<int64_t>()},
                            0.0, 1.0, 7);
    LightingStage stage(c, memory_source(2), memory_source(1));
    stage.initialise();
    overfit(stage, 2);
    answers = sky_answers(stage, image);
    nn::Module holder("Exported");
    holder.register_module("predictor", std::shared_ptr<nn::Module>(&stage.predictor(), [](nn::Module*) {}));
    nn::save_checkpoint(exported, holder, nullptr, nn::CheckpointInfo{.stage = kStageLighting});
    before.clear();
    for (const auto& [n, t] : stage.predictor().state_dict()) before[n] = t.clone();
  }

  // The config started from the exported model, which holds no teacher: no stage-1 checkpoint, and
  // so none of the teacher's pseudo-labels.
  nlohmann::json from_exported() const {
    nlohmann::json g = c;
    g["init"]["checkpoint"] = exported;
    g["init"]["sky_checkpoint"] = "";
    g["loss"]["sky_intensity"] = 0.0;
    g["loss"]["sky_latent"] = 0.0;
    return g;
  }

  // A grown model starts from the exported one's answers, and one step trains the columns its sun
  // head's first layer gained (for `what`).
  void expect_same_answers_then_new_columns_train(LightingStage& stage, const std::string& what) {
    expect_same_answers(sky_answers(stage, image), answers);
    EXPECT_TRUE(std::isfinite(stage.step(0).at("loss")));
    EXPECT_GT(new_columns_mass(stage.predictor().state_dict().at("sun_head.net.0.weight"),
                               before.at("sun_head.net.0.weight").size(1)),
              0.0)
        << what << " did not train";
  }

  // The config with the sun head (model.sun_grid and its loss) taken away.
  nlohmann::json without_sun_head() const {
    nlohmann::json g = c;
    g["model"]["sun_grid"] = {{"elevation_bins", 0}, {"azimuth_bins", 0}};
    g["loss"]["sun_distribution"] = 0.0;
    return g;
  }

  std::string dir, sky, exported;
  nlohmann::json c;
  Tensor image;
  nn::StateDict before;
  SkyAnswers answers;
};

// init.checkpoint may be an exported model (the predictor alone, as models/streetlight.safetensors
// ships): the teacher then comes from init.sky_checkpoint. Its pseudo-labels are used only when its
// decoder is the predictor's frozen one, bit for bit; with sky_intensity = sky_latent = 0 any
// stage-1 checkpoint will do, and steps run without the teacher.
TEST_F(PredictorWarmStart, AnExportedPredictorTakesATeacherOnlyWhenItMatchesItsDecoder) {
  export_model("warm_exported", false);
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
  nlohmann::json g = c;
  g["init"]["checkpoint"] = exported;
  {
    LightingStage stage(g, memory_source(2), memory_source(1));
    stage.initialise();
    for (const auto& [name, t] : stage.predictor().state_dict()) EXPECT_EQ(t.to_vector(), before.at(name).to_vector()) << name;
    EXPECT_TRUE(std::isfinite(stage.step(0).at("loss")));
  }
  const auto refused = [&](const nlohmann::json& config, const std::string& what) {
    LightingStage stage(config, memory_source(2), memory_source(1));
    EXPECT_NE(refusal([&] { stage.initialise(); }, what).find(what), std::string::npos);
  };
  nlohmann::json no_teacher = g;
  no_teacher["init"]["sky_checkpoint"] = "";
  refused(no_teacher, "holds no teacher");
  nlohmann::json mismatched = g;
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
// initialisation, and a step trains it (its weights move; the loss terms, the front/back one with
// them, are finite). Validation scores the distribution's mode.
TEST_F(PredictorWarmStart, ASunHeadStartsFromAModelWithoutOne) {
  export_model("warm_sun_head", false);
  nlohmann::json g = from_exported();
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
  EXPECT_NE(refusal([&] { train::check_train_config(bad); }, "loss.sun_distribution without model.sun_grid").find("model.sun_grid"),
            std::string::npos);
}

// A model trained without the volume branch (model.volume_branch false: the backbone and the sky and
// sun heads, a cheap first part of a recipe) gains it: every loaded tensor is the file's, the volume
// MLP and 3D UNet are the new model's own initialisation, the sky's answers are unchanged, and a step
// trains the volume through the radiance rays.
TEST_F(PredictorWarmStart, AVolumeBranchStartsFromAModelWithoutOne) {
  export_model("warm_volume", true, false);
  for (const auto& [name, t] : before)
    ASSERT_TRUE(name.rfind("volume_", 0) != 0) << "the exported model has a volume part: " << name;
  nlohmann::json g = from_exported();
  g["model"]["volume_branch"] = true;
  LightingStage stage(g, memory_source(2), memory_source(1));
  stage.initialise();
  const nn::StateDict fresh = train::LightingPredictor(stage.predictor().options()).state_dict();
  std::map<std::string, std::vector<double>> volume;
  for (const auto& [name, t] : stage.predictor().state_dict()) {
    if (name.rfind("volume_", 0) == 0) {
      EXPECT_EQ(t.to_vector(), fresh.at(name).to_vector()) << name;
      volume[name] = t.to_vector();
      continue;
    }
    ASSERT_TRUE(before.count(name)) << name;
    EXPECT_EQ(t.to_vector(), before.at(name).to_vector()) << name;
  }
  ASSERT_FALSE(volume.empty()) << "no volume branch";
  expect_same_answers(sky_answers(stage, image), answers);
  const Metrics m = stage.step(0);
  ASSERT_TRUE(m.count("depth") && m.count("sky_separation")) << "the volume's losses did not run";
  EXPECT_TRUE(std::isfinite(m.at("loss")));
  int moved = 0;
  for (const auto& [name, t] : stage.predictor().state_dict())
    if (volume.count(name) && t.to_vector() != volume.at(name)) ++moved;
  EXPECT_GT(moved, 0) << "the volume branch did not train";
}

// A model without the heads' grid (model.head_grid_channels) gains one: every head that reads
// the features keeps its weights for the pooled vector and gets zero columns for the grid, so the
// model starts from the loaded one's answers, and the grid then trains.
TEST_F(PredictorWarmStart, HeadsGainTheFeatureGridFromAModelWithout) {
  export_model("warm_head_grid");
  nlohmann::json g = from_exported();
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
  expect_same_answers_then_new_columns_train(stage, "the grid's columns");
}

TEST_F(PredictorWarmStart, AResNet18BackboneDeepensToAResNet34WithTheSameAnswers) {
  export_model("warm_deepen");
  ASSERT_EQ(c["model"]["backbone_depth"].get<int>(), 18);
  nlohmann::json g = from_exported();
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
  expect_same_answers(sky_answers(stage, image), answers);
  EXPECT_TRUE(std::isfinite(stage.step(0).at("loss")));
  // The zero scales take gradients: the new blocks train.
  double moved = 0;
  for (double v : stage.predictor().state_dict().at("backbone.layer3.5.bn2.weight").to_vector()) moved += std::fabs(v);
  EXPECT_GT(moved, 0.0) << "the new blocks did not train";
}

TEST_F(PredictorWarmStart, ANarrowBackboneWidensAndDeepensWithTheSameAnswers) {
  export_model("warm_widen");
  const int64_t width = c["model"]["backbone_width"].get<int64_t>();
  nlohmann::json g = from_exported();
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
  expect_same_answers(sky_answers(stage, image), answers);
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
  EXPECT_NE(refusal([&] { refused.initialise(); }, "a wider backbone with a new head grid").find("model.backbone_width"),
            std::string::npos);
}

// Issue 53: a sun head from before model.sun_image_statistics is widened when a stage with the
// statistics starts from it: its first layer keeps the loaded columns and gets zero columns for
// the 102 statistics, so the sun's logits start where the loaded model's are; a step then trains
// the new columns.
TEST_F(PredictorWarmStart, ASunHeadGainsImageStatisticsFromAModelWithout) {
  export_model("warm_sun_statistics");
  nlohmann::json g = from_exported();
  g["model"]["sun_image_statistics"] = true;
  LightingStage stage(g, memory_source(2), memory_source(1));
  stage.initialise();
  for (const auto& [name, t] : stage.predictor().state_dict()) {
    ASSERT_TRUE(before.count(name)) << name;
    if (name != "sun_head.net.0.weight") {
      EXPECT_EQ(t.to_vector(), before.at(name).to_vector()) << name;
      continue;
    }
    ASSERT_EQ(t.size(1), before.at(name).size(1) + train::kImageStatistics);
    expect_widened(name, t, before.at(name));
  }
  expect_same_answers_then_new_columns_train(stage, "the statistics' columns");
  EXPECT_TRUE(std::isfinite(stage.step(1).at("sun_distribution")));
  // The statistics need the sun head, and say so naming the key.
  nlohmann::json bad = without_sun_head();
  bad["model"]["sun_image_statistics"] = true;
  EXPECT_NE(refusal([&] { LightingStage refused(bad, memory_source(2), memory_source(1)); },
                    "model.sun_image_statistics without model.sun_grid")
                .find("model.sun_image_statistics"),
            std::string::npos);
}

// Issue 53: a sun head gains its own backbone (model.sun_backbone, an ImageNet MobileNetV2) from a
// model without one: the loaded tensors are unchanged, the sun head's first layer gets zero columns
// for the new map, so the logits start where the loaded model's are; init.sun_backbone_weights
// puts the ImageNet weights in the new backbone, and a step trains the new columns.
TEST_F(PredictorWarmStart, ASunHeadGainsItsOwnImageNetBackboneFromAModelWithout) {
  export_model("warm_sun_backbone");
  nlohmann::json g = from_exported();
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
  expect_same_answers_then_new_columns_train(stage, "the new backbone's columns");
  EXPECT_TRUE(std::isfinite(stage.step(1).at("sun_distribution")));
  // The backbone needs the sun head, and its weights need the backbone: each refusal names its key.
  nlohmann::json bad = without_sun_head();
  bad["model"]["sun_backbone"] = "mobilenet_v2";
  EXPECT_NE(refusal([&] { LightingStage refused(bad, memory_source(2), memory_source(1)); },
                    "model.sun_backbone without model.sun_grid")
                .find("model.sun_backbone"),
            std::string::npos);
  nlohmann::json unknown = g;
  unknown["model"]["sun_backbone"] = "resnet50";
  EXPECT_THROW(LightingStage(unknown, memory_source(2), memory_source(1)), Error);
  nlohmann::json orphan = from_exported();
  orphan["init"]["sun_backbone_weights"] = weights;
  LightingStage without(orphan, memory_source(2), memory_source(1));
  EXPECT_NE(refusal([&] { without.initialise(); }, "init.sun_backbone_weights without model.sun_backbone")
                .find("init.sun_backbone_weights"),
            std::string::npos);
}

// init.reinitialise: the named parts start from the predictor's own initialisation for the
// config's seed, every other tensor (the frozen sky decoder among them) from the checkpoint; a
// part that does not exist, or the sky decoder, is refused naming the parts.
TEST_F(PredictorWarmStart, ReinitialisedPartsStartAfreshAndTheRestFromTheCheckpoint) {
  export_model("warm_reinitialise", false);
  nlohmann::json g = from_exported();
  g["init"]["reinitialise"] = {"backbone", "sky_head"};
  LightingStage stage(g, memory_source(2), memory_source(1));
  stage.initialise();
  const train::LightingPredictor fresh(stage.predictor().options());
  const nn::StateDict initial = fresh.state_dict();
  int afresh = 0, loaded = 0;
  for (const auto& [name, t] : stage.predictor().state_dict()) {
    const bool again = name.rfind("backbone.", 0) == 0 || name.rfind("sky_head.", 0) == 0;
    EXPECT_EQ(t.to_vector(), (again ? initial : before).at(name).to_vector()) << name;
    (again ? afresh : loaded) += 1;
    if (again && name.find("weight") != std::string::npos) {
      EXPECT_NE(t.to_vector(), before.at(name).to_vector()) << name;
    }
  }
  EXPECT_GT(afresh, 0);
  EXPECT_GT(loaded, 0);
  EXPECT_TRUE(std::isfinite(stage.step(0).at("loss")));
  for (const char* bad : {"sky_decoder", "backbnoe"}) {
    nlohmann::json b = g;
    b["init"]["reinitialise"] = {bad};
    LightingStage refused(b, memory_source(2), memory_source(1));
    const std::string e = refusal([&] { refused.initialise(); }, std::string("init.reinitialise ") + bad);
    EXPECT_NE(e.find("init.reinitialise"), std::string::npos) << e;
    EXPECT_NE(e.find("backbone"), std::string::npos) << e;
  }
  nlohmann::json none = train::default_train_config();
  none["stage"] = kStageLighting;
  none["data"]["dataset"] = "streets";
  none["init"]["sky_checkpoint"] = "sky.safetensors";
  none["init"]["reinitialise"] = {"backbone"};
  EXPECT_NE(refusal([&] { train::check_train_config(none); }, "init.reinitialise without init.checkpoint").find("init.checkpoint"),
            std::string::npos);
}

}  // namespace
}  // namespace sl::test
