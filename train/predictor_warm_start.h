// Warm start: a lighting predictor loaded from a checkpoint of an earlier architecture.
//
// Contract:
// - warm_start_predictor(path, predictor, teacher) loads `predictor` from the stage-2 checkpoint or
//   exported model at `path` (names "predictor.*"), and `teacher` from its "teacher.*" tensors when
//   the file has them and `teacher` is not null. Returns whether the file held a teacher.
// - The file's model may lack parts that `predictor`'s options add; each starts so that the loaded
//   model's answers are unchanged (tested in tests/train/lighting_stage_test.cpp):
//   - the sun head (model.sun_grid): it keeps its own initialisation;
//   - the sun head's image statistics (model.sun_image_statistics) and the heads' feature grid
//     (model.head_grid_channels) and the sun head's own backbone (model.sun_backbone): the heads'
//     first layers gain zero columns (a new backbone keeps its initialisation);
//   - a ResNet-34 backbone from a ResNet-18 (model.backbone_depth): the extra blocks end in a batch
//     norm at zero, so each passes its input on unchanged;
//   - a wider backbone (model.backbone_width): the old channels keep their indices and values, no
//     new channel reaches an old one, and the heads get zero columns for the new features (not
//     with model.head_grid_channels or model.sun_image_statistics: refused);
//   - the volume branch (model.volume_branch), from a model trained without it: the volume MLP and
//     3D UNet keep their initialisation.
// - Throws sl::Error naming the file and tensor for any other mismatch of names or shapes.
#pragma once
#include <memory>
#include <string>

#include "train/lighting_predictor.h"
#include "train/sky_autoencoder.h"

namespace sl::train {

bool warm_start_predictor(const std::string& path, const std::shared_ptr<LightingPredictor>& predictor,
                          const std::shared_ptr<SkyAutoencoder>& teacher);

}  // namespace sl::train
