// The training configuration: ONE defaults object listing every valid key of every stage
// (documented key by key in configs/README.md), and its conversion to model options.
//
// Contract:
// - default_train_config() returns the JSON defaults (the CPU-scale defaults of docs/DESIGN.md, "Scale"). The
//   train executable validates user configs against it with tools/common/config.h (unknown
//   keys name the nearest valid key; wrong types name both types).
// - check_train_config() checks what types cannot: the stage name, positive sizes, the
//   checkpoint a stage starts from. Throws sl::Error naming the key path and the value.
// - sky_options() / predictor_options() read the model sections into option structs.
#pragma once
#include <nlohmann/json.hpp>

#include "render/object_insertion.h"
#include "render/radiance_query.h"
#include "render/vsg_volume.h"
#include "train/lighting_predictor.h"
#include "train/sky_autoencoder.h"

namespace sl::train {

inline constexpr const char* kStageSky = "sky_autoencoder";
inline constexpr const char* kStageLighting = "lighting";
inline constexpr const char* kStageAdversarial = "adversarial";

nlohmann::json default_train_config();
void check_train_config(const nlohmann::json& config);

SkyAutoencoderOptions sky_options(const nlohmann::json& config);
LightingPredictorOptions predictor_options(const nlohmann::json& config);
// The VSG grid centred on a camera at height `camera_height_m` above the canonical origin.
render::VsgGrid vsg_grid(const nlohmann::json& config, double camera_height_m);
// Eq. 1's query options from model.volume: samples (K), spacing ("metric" | "grid"), trilinear.
render::RadianceQueryOptions volume_query_options(const nlohmann::json& config);
// The insertion renderer's options in stage 3 (the `insertion` section): sample counts, I_a,
// and importance_sampling (cosine + sky MIS for light and shadow rays, as at inference; false:
// the paper's cosine samples), with Eq. 1 from model.volume. seed draws every sample.
render::InsertionOptions training_insertion_options(const nlohmann::json& config, uint64_t seed);

}  // namespace sl::train
