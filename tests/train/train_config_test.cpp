// Stage 3's insertion options from a train config, and configs written before their keys existed.
#include "train/train_config.h"

#include <gtest/gtest.h>

#include "render/object_insertion.h"
#include "render/radiance_query.h"
#include "util/error.h"

using sl::render::InsertionOptions;
using sl::render::SampleSpacing;

namespace sl::test {
using train::default_train_config;
using train::training_insertion_options;
using train::volume_query_options;

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

// The released model of 2026-11-22 was trained before model.head_grid_channels existed: its stored
// config must still build the pooled-only predictor it holds weights for.
TEST(TrainConfig, ConfigsWithoutTheGridHeadKeyBuildThePooledHead) {
  nlohmann::json c = default_train_config();
  c["model"]["head_grid_channels"] = 16;
  EXPECT_EQ(train::predictor_options(c).head_grid_channels, 16);
  c["model"].erase("head_grid_channels");
  EXPECT_EQ(train::predictor_options(c).head_grid_channels, 0);
}

}  // namespace
}  // namespace sl::test

namespace sl::test {
namespace {

// check_train_config's message for c, or "" when it accepts c.
std::string refusal(const nlohmann::json& c) {
  try {
    train::check_train_config(c);
  } catch (const Error& e) {
    return std::string(e.what());
  }
  return std::string();
}

// The LDR panorama keys (configs/README.md, "Mixing"): the shares leave room for the streets, and
// a share without its folder is refused naming the key.
TEST(TrainConfig, LdrPanoramaSharesAreCheckedNamingTheirKeys) {
  nlohmann::json c = default_train_config();
  c["stage"] = "lighting";
  c["init"]["sky_checkpoint"] = "sky.safetensors";
  c["data"]["dataset"] = "streets";
  EXPECT_EQ(refusal(c), "");
  c["data"]["ldr_fraction"] = 0.3;
  EXPECT_NE(refusal(c).find("data.ldr_dir"), std::string::npos) << refusal(c);
  c["data"]["ldr_dir"] = "pano_ldr";
  EXPECT_EQ(refusal(c), "");
  c["data"]["hdri_dir"] = "hdri";
  c["data"]["real_fraction"] = 0.7;
  EXPECT_NE(refusal(c).find("data.ldr_fraction"), std::string::npos) << refusal(c);
  c["data"]["real_fraction"] = 0.2;
  c["data"]["ldr_val_crops"] = -1;
  EXPECT_NE(refusal(c).find("data.ldr_val_crops"), std::string::npos) << refusal(c);
  c["data"]["ldr_val_crops"] = 8;
  EXPECT_EQ(refusal(c), "");
  for (const nlohmann::json& bad : {nlohmann::json({10.0, 1.0}), nlohmann::json({-1.0, 1.0}), nlohmann::json({1.0}),
                                    nlohmann::json("1-10")}) {
    c["loss"]["ldr_sun_energy_range"] = bad;
    EXPECT_NE(refusal(c).find("loss.ldr_sun_energy_range"), std::string::npos) << bad.dump() << ": " << refusal(c);
  }
  c["loss"]["ldr_sun_energy_range"] = {1.0, 10.0};
  EXPECT_EQ(refusal(c), "");
  for (double bad : {-0.1, 1.5}) {  // data.ldr_place_balance is an exponent in [0, 1]
    c["data"]["ldr_place_balance"] = bad;
    EXPECT_NE(refusal(c).find("data.ldr_place_balance must lie in [0, 1]"), std::string::npos) << refusal(c);
  }
}

// train.freeze is a list of names, for the lighting stages only; a lighting stage may start from
// a lighting checkpoint (an exported model) instead of a stage-1 one.
TEST(TrainConfig, FreezeListAndTheLightingStagesStartingPoints) {
  nlohmann::json c = default_train_config();
  c["stage"] = "lighting";
  c["data"]["dataset"] = "streets";
  EXPECT_NE(refusal(c).find("init.sky_checkpoint"), std::string::npos) << refusal(c);
  c["init"]["checkpoint"] = "models/streetlight.safetensors";
  EXPECT_EQ(refusal(c), "");
  c["train"]["freeze"] = {"backbone", "volume_unet"};
  EXPECT_EQ(refusal(c), "");
  c["train"]["freeze"] = "backbone";
  EXPECT_NE(refusal(c).find("train.freeze"), std::string::npos) << refusal(c);
  c["train"]["freeze"] = {"backbone", 3};
  EXPECT_NE(refusal(c).find("train.freeze"), std::string::npos) << refusal(c);
  nlohmann::json sky = default_train_config();
  sky["stage"] = "sky_autoencoder";
  sky["train"]["freeze"] = {"encoder"};
  EXPECT_NE(refusal(sky).find("train.freeze"), std::string::npos) << refusal(sky);
}

}  // namespace
}  // namespace sl::test
