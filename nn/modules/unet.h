// UNet2D and UNet3D: encoder-decoder with skip connections, for images and volumes.
//
// Contract:
// - Levels 0..depth: level i has c_i = base_channels·2^i channels and is a ConvBlock (two
//   3×3(×3) convs, each followed by norm and activation). Between encoder levels a 2× max pool
//   halves every spatial extent. The decoder climbs back: at each level an Upsample (2×,
//   nearest or linear) followed by a 3×3 conv maps c_{i+1} to c_i, the encoder's level-i output
//   is concatenated on channels (when skip), and a ConvBlock maps back to c_i. A final 1×1
//   conv ("head") gives out_channels.
// - Names: enc.<i>.conv1.weight, enc.<i>.norm1.*, dec.<j>.up.1.weight, dec.<j>.block.conv1.*,
//   head.weight, with dec.0 the deepest decoder level.
// - norm: "batch", "group" (groups as make_norm), "instance" or "none"; convs have a bias only
//   when norm is "none" (a bias before a norm is redundant). activation: any make_activation
//   name. Every spatial extent of the input must be divisible by 2^depth (checked, with the
//   shape in the message). forward maps [N, in, *S] to [N, out, *S].
// - Parameters are initialised from options.seed (children's defaults: PyTorch's conv init).
#pragma once
#include <memory>
#include <string>
#include <vector>

#include "nn/module.h"

namespace sl::nn {

struct UNetOptions {
  int64_t in_channels = 1;
  int64_t out_channels = 1;
  int64_t base_channels = 16;
  int depth = 3;
  std::string norm = "batch";
  int64_t groups = 8;
  std::string activation = "relu";
  bool skip = true;
  std::string upsample = "nearest";  // or "linear"
  uint64_t seed = 0;
};

// conv → norm → act → conv → norm → act (children conv1, norm1, act1, conv2, norm2, act2).
class ConvBlock : public Module {
 public:
  ConvBlock(int spatial_dims, int64_t in, int64_t out, const std::string& norm, int64_t groups,
            const std::string& activation);
  Tensor forward(const Tensor& x) override;

 private:
  std::vector<std::shared_ptr<Module>> seq_;
};

class UNet : public Module {
 public:
  UNet(int spatial_dims, UNetOptions options);
  Tensor forward(const Tensor& x) override;
  const UNetOptions& options() const { return opt_; }

 private:
  int dims_;
  UNetOptions opt_;
  std::shared_ptr<ModuleList> enc_, dec_;
  std::shared_ptr<Module> pool_, head_;
};

class UNet2D : public UNet {
 public:
  explicit UNet2D(UNetOptions options) : UNet(2, std::move(options)) {}
};

class UNet3D : public UNet {
 public:
  explicit UNet3D(UNetOptions options) : UNet(3, std::move(options)) {}
};

}  // namespace sl::nn
