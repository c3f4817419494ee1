// ResNet-18/34 backbones with torchvision's parameter names.
//
// Contract:
// - ResNet(options): conv1 (7×7, stride 2) → bn1 → relu → maxpool (3×3, stride 2) → layer1..4
//   (BasicBlocks; depth 18 = [2, 2, 2, 2], 34 = [3, 4, 6, 3]) with widths w, 2w, 4w, 8w for
//   base_width w (64 in torchvision) → global average pool (→ fc when num_classes > 0).
//   Names match torchvision exactly: conv1.weight, bn1.running_mean, layer1.0.conv1.weight,
//   layer2.0.downsample.0.weight, layer2.0.downsample.1.weight, fc.weight, ...
//   (with base_width 64, in_channels 3, a torchvision resnet18 state dict loads one to one).
// - forward_features(x [N, in_channels, H, W]) returns the four stage outputs (strides 4, 8,
//   16, 32 relative to the input) and the pooled vector [N, 8w]; forward(x) returns the pooled
//   vector, or the logits [N, num_classes] when there is an fc layer.
// - Initialisation (torchvision's): convs Kaiming normal (fan_out, ReLU gain), batch norms
//   weight 1 and bias 0, fc PyTorch's Linear default; seeded by name (nn/init.h).
// - Throws sl::Error for a depth other than 18/34, non-positive widths, or a wrong input.
#pragma once
#include <memory>
#include <vector>

#include "nn/module.h"

namespace sl::nn {

struct ResNetOptions {
  int depth = 18;
  int64_t in_channels = 3;
  int64_t base_width = 64;
  int64_t num_classes = 0;  // 0: no fc layer (a feature extractor)
  uint64_t seed = 0;
};

struct ResNetOutput {
  std::vector<Tensor> features;  // layer1..layer4 outputs
  Tensor pooled;                 // [N, 8·base_width]
};

// Two 3×3 conv-BN pairs with an identity (or 1×1 conv-BN "downsample") shortcut.
class BasicBlock : public Module {
 public:
  BasicBlock(int64_t in_channels, int64_t out_channels, int64_t stride);
  Tensor forward(const Tensor& x) override;
  void fold_batch_norms();  // see ResNet::fold_batch_norms

 private:
  std::shared_ptr<Module> conv1_, bn1_, conv2_, bn2_, downsample_;
};

class ResNet : public Module {
 public:
  explicit ResNet(ResNetOptions options);
  ResNetOutput forward_features(const Tensor& x);
  Tensor forward(const Tensor& x) override;
  int64_t feature_dim() const { return 8 * opt_.base_width; }
  // For inference: folds every batch norm into the conv before it (the stem, each block's two
  // pairs and each downsample; nn/modules/batch_norm_folding.h). The same function up to
  // rounding; irreversible (training mode then throws; the state dict gains conv biases).
  void fold_batch_norms();
  const ResNetOptions& options() const { return opt_; }

 protected:
  void reset_parameters(uint64_t seed, const std::string& prefix) override;

 private:
  ResNetOptions opt_;
  std::shared_ptr<Module> stem_conv_, stem_bn_, maxpool_, fc_;
  std::vector<std::shared_ptr<Module>> stages_;
};

}  // namespace sl::nn
