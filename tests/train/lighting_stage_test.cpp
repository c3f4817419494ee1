// Stage 2 (Sec 3.4): the supervised lighting stage overfits a tiny batch, keeps frozen parts
// frozen, mixes labelled LDR panoramas in, and each ablation variant of the predictor steps and
// validates. Starting from another model's checkpoint: predictor_warm_start_test.cpp.
#include "train/lighting_stage.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include "data/image_io.h"
#include "data/panorama.h"
#include "data/sky_model.h"
#include "data/sun_extraction.h"
#include "render/equirect.h"
#include "support/test_files.h"
#include "support/tiny_stage.h"
#include "util/error.h"
#include "util/math.h"

namespace sl::test {
using train::LightingStage;
using train::Metrics;
using train::kStageLighting;

namespace {

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

// loss.domain_adversarial (issue 53): a classifier on the pooled features tells the real crops (ids
// "hdri:" and "ldr:") from the generated streets behind a gradient reversal. It trains (its weights
// move; its loss and accuracy are reported and finite); at reversal 0 the predictor steps bit for bit
// as without the term, so the term reaches the predictor only through the reversal, and at
// reversal 1 it does reach it; validation leaves it out. Without real crops it is refused, naming
// the key.
TEST(LightingStage, ADomainClassifierTrainsBehindTheGradientReversal) {
  const std::string dir = temp_dir("lighting_domain");
  nlohmann::json c = tiny_config(kStageLighting);
  c["init"]["sky_checkpoint"] = save_sky_checkpoint(c, dir);
  c["optim"]["clip_grad_norm"] = 1e9;  // the classifier's gradient would otherwise change the clipping
  c["data"]["real_fraction"] = 0.5;    // what the check asks for; the source below is the mix
  const train::SampleSource half_real{4, [](size_t i, uint64_t) {
                                        data::StreetSample s = tiny_street_sample(i + 1);
                                        if (i % 2 == 1) s.id = (i == 1 ? "hdri:" : "ldr:") + s.id;
                                        return s;
                                      }};
  auto trained = [&](double weight, double reversal, Metrics* last, nn::StateDict* head) {
    nlohmann::json g = c;
    g["loss"]["domain_adversarial"] = weight;
    g["loss"]["domain_reversal"] = reversal;
    g["loss"]["domain_lr_scale"] = 10.0;  // the classifier at its own rate; the predictor's is unchanged
    LightingStage stage(g, half_real, memory_source(1));
    stage.initialise();
    const double val_before = stage.validate().at("val_loss");
    if (head && stage.model().child("domain_head")) {
      *head = stage.model().child("domain_head")->state_dict();
      for (auto& [n, t] : *head) t = t.clone();
    }
    Metrics m;
    for (int64_t s = 0; s < 3; ++s) m = stage.step(s);
    if (last) *last = m;
    std::vector<std::pair<std::string, std::vector<double>>> out;
    for (const auto& [n, t] : stage.predictor().state_dict()) out.emplace_back(n, t.to_vector());
    if (head && stage.model().child("domain_head")) {
      for (const auto& [n, t] : stage.model().child("domain_head")->state_dict()) {
        EXPECT_NE(t.to_vector(), head->at(n).to_vector()) << "the classifier's " << n << " did not train";
      }
    }
    return std::make_pair(out, val_before);
  };
  const auto [plain, plain_val] = trained(0.0, 1.0, nullptr, nullptr);
  Metrics m;
  nn::StateDict head;
  const auto [off, off_val] = trained(1.0, 0.0, &m, &head);
  ASSERT_FALSE(head.empty()) << "no domain_head";
  EXPECT_EQ(off, plain) << "at reversal 0 the domain term must not reach the predictor";
  EXPECT_EQ(off_val, plain_val) << "validation must leave the domain term out";
  ASSERT_TRUE(m.count("domain_adversarial") && m.count("domain_accuracy"));
  EXPECT_TRUE(std::isfinite(m.at("domain_adversarial")));
  EXPECT_GT(m.at("domain_adversarial"), 0.0);
  EXPECT_GE(m.at("domain_accuracy"), 0.0);
  EXPECT_LE(m.at("domain_accuracy"), 1.0);
  const auto [on, on_val] = trained(1.0, 1.0, nullptr, &head);
  EXPECT_NE(on, plain) << "at reversal 1 the domain term must reach the predictor";
  auto refusal = [](const nlohmann::json& config) {
    try {
      train::check_train_config(config);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  nlohmann::json bad = train::default_train_config();
  bad["stage"] = kStageLighting;
  bad["data"]["dataset"] = "streets";
  bad["init"]["sky_checkpoint"] = c["init"]["sky_checkpoint"];
  EXPECT_EQ(refusal(bad), "accepted");
  bad["loss"]["domain_adversarial"] = 1.0;  // data.real_fraction and data.ldr_fraction are 0
  EXPECT_NE(refusal(bad).find("loss.domain_adversarial > 0 needs real crops"), std::string::npos) << refusal(bad);
  bad["stage"] = train::kStageAdversarial;
  bad["init"]["checkpoint"] = "lighting.safetensors";  // checked for being named only
  EXPECT_NE(refusal(bad).find("loss.domain_adversarial is a term of stage 2"), std::string::npos) << refusal(bad);
  bad["stage"] = kStageLighting;
  bad["init"]["checkpoint"] = "";
  bad["loss"]["domain_adversarial"] = -1.0;
  EXPECT_NE(refusal(bad).find("loss.domain_adversarial must be finite"), std::string::npos) << refusal(bad);
  bad["loss"]["domain_adversarial"] = 0.0;
  bad["loss"]["domain_reversal"] = -1.0;
  EXPECT_NE(refusal(bad).find("loss.domain_reversal"), std::string::npos) << refusal(bad);
  bad["loss"]["domain_reversal"] = 1.0;
  bad["loss"]["domain_lr_scale"] = 0.0;
  EXPECT_NE(refusal(bad).find("loss.domain_lr_scale"), std::string::npos) << refusal(bad);
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
