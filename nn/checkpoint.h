// Training checkpoints: model parameters and buffers, optimiser state, step, stage and config
// in one safetensors file (nn/safetensors.h), readable by PyTorch's safetensors loader.
//
// Contract:
// - Tensor names: the model's state_dict() names unchanged (`backbone.layer1.0.conv1.weight`,
//   `...bn1.running_mean`), and the optimiser's state under "optim." (`optim.exp_avg.<param>`,
//   `optim.step.<param>`). Metadata: "format" = "pt", "streetlight_version" =
//   kCheckpointVersion, "stage", "step" (decimal), "config" (a JSON text), plus any `extra`
//   keys (which must not collide with these).
// - save_checkpoint writes atomically (temp file, fsync, rename).
// - load_checkpoint reads and validates the file (see read_safetensors), then checks every
//   expected name, shape and dtype (model, plus "optim.*" when an optimiser is given; "optim.*"
//   entries are ignored when none is) and throws ONE sl::Error naming the file and listing
//   what is missing, unexpected or mismatched. Nothing is modified unless everything matches.
//   Half-precision tensors in the file are widened, so an F16 export loads into an F32 model.
// - read_checkpoint_info reads only what the metadata says (still validating the file).
#pragma once
#include <cstdint>
#include <string>

#include "nn/module.h"
#include "nn/optim.h"
#include "nn/safetensors.h"

namespace sl::nn {

inline constexpr const char* kCheckpointVersion = "1";

struct CheckpointInfo {
  std::string stage{};
  int64_t step = 0;
  std::string config_json = "{}";
  Metadata extra{};
};

void save_checkpoint(const std::string& path, const Module& model, const Optimizer* optimizer,
                     const CheckpointInfo& info);
CheckpointInfo load_checkpoint(const std::string& path, Module& model, Optimizer* optimizer);
CheckpointInfo read_checkpoint_info(const std::string& path);

}  // namespace sl::nn
