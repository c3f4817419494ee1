#include "nn/modules/resnet.h"

#include "autodiff/ops.h"
#include "nn/functional/pooling.h"
#include "nn/init.h"
#include "nn/layers.h"
#include "nn/modules/batch_norm_folding.h"

namespace sl::nn {

namespace {
// The ReLU that follows a BatchNorm, as a module so that the BatchNorm can absorb it.
const std::shared_ptr<Module>& relu_module() {
  static const std::shared_ptr<Module> m = std::make_shared<ReLU>();
  return m;
}
}  // namespace

BasicBlock::BasicBlock(int64_t in_channels, int64_t out_channels, int64_t stride) : Module("BasicBlock") {
  conv1_ = register_module("conv1", std::make_shared<Conv2d>(in_channels, out_channels, 3,
                                                              ConvOptions{.stride = stride, .padding = 1, .bias = false}));
  bn1_ = register_module("bn1", std::make_shared<BatchNorm2d>(out_channels));
  conv2_ = register_module("conv2", std::make_shared<Conv2d>(out_channels, out_channels, 3,
                                                              ConvOptions{.padding = 1, .bias = false}));
  bn2_ = register_module("bn2", std::make_shared<BatchNorm2d>(out_channels));
  if (stride != 1 || in_channels != out_channels) {
    auto ds = std::make_shared<Sequential>();
    ds->push_back(std::make_shared<Conv2d>(in_channels, out_channels, 1, ConvOptions{.stride = stride, .bias = false}));
    ds->push_back(std::make_shared<BatchNorm2d>(out_channels));
    downsample_ = register_module("downsample", ds);
  }
}

Tensor BasicBlock::forward(const Tensor& x) {
  Tensor y = forward_chain({bn1_, relu_module()}, conv1_->forward(x));  // relu(bn1(·)) as one op
  y = bn2_->forward(conv2_->forward(y));
  return relu(add(y, downsample_ ? downsample_->forward(x) : x));
}

namespace {
void fold_pair(const std::shared_ptr<Module>& conv, const std::shared_ptr<Module>& bn) {
  fold_batch_norm(dynamic_cast<ConvNd&>(*conv), dynamic_cast<BatchNormNd&>(*bn));
}
}  // namespace

void BasicBlock::fold_batch_norms() {
  fold_pair(conv1_, bn1_);
  fold_pair(conv2_, bn2_);
  if (downsample_) {
    const auto& ds = static_cast<Sequential&>(*downsample_);
    fold_pair(ds[0], ds[1]);
  }
}

void ResNet::fold_batch_norms() {
  fold_pair(stem_conv_, stem_bn_);
  for (auto& stage : stages_)
    for (const auto& [name, block] : stage->children()) static_cast<BasicBlock&>(*block).fold_batch_norms();
}

ResNet::ResNet(ResNetOptions options) : Module("ResNet"), opt_(options) {
  SL_CHECK(opt_.depth == 18 || opt_.depth == 34, "ResNet: depth must be 18 or 34, got ", opt_.depth);
  SL_CHECK(opt_.in_channels > 0 && opt_.base_width > 0 && opt_.num_classes >= 0, "ResNet: in_channels ",
           opt_.in_channels, " and base_width ", opt_.base_width, " must be > 0, num_classes ", opt_.num_classes,
           " >= 0");
  const int64_t w = opt_.base_width;
  stem_conv_ = register_module("conv1", std::make_shared<Conv2d>(opt_.in_channels, w, 7,
                                                                  ConvOptions{.stride = 2, .padding = 3, .bias = false}));
  stem_bn_ = register_module("bn1", std::make_shared<BatchNorm2d>(w));
  maxpool_ = register_module("maxpool", std::make_shared<MaxPool2d>(3, 2, 1));
  const std::vector<int> blocks = opt_.depth == 18 ? std::vector<int>{2, 2, 2, 2} : std::vector<int>{3, 4, 6, 3};
  int64_t in = w;
  for (int s = 0; s < 4; ++s) {
    const int64_t out = w << s;
    auto stage = std::make_shared<Sequential>();
    for (int b = 0; b < blocks[s]; ++b) {
      stage->push_back(std::make_shared<BasicBlock>(in, out, b == 0 && s > 0 ? 2 : 1));
      in = out;
    }
    stages_.push_back(register_module("layer" + std::to_string(s + 1), stage));
  }
  if (opt_.num_classes > 0) fc_ = register_module("fc", std::make_shared<Linear>(8 * w, opt_.num_classes));
  init_parameters(opt_.seed);
}

void ResNet::reset_parameters(uint64_t seed, const std::string& prefix) {
  // torchvision: Kaiming normal (fan_out, ReLU) for every conv; BN stays at weight 1, bias 0.
  for (auto& [name, m] : named_modules())
    if (dynamic_cast<Conv2d*>(m))
      kaiming_normal_init(m->parameter("weight"), seed, prefix + name + ".weight", 0.0, FanMode::FanOut);
}

ResNetOutput ResNet::forward_features(const Tensor& x) {
  SL_CHECK(x.dim() == 4 && x.size(1) == opt_.in_channels, "ResNet: expected input [N, ", opt_.in_channels,
           ", H, W], got ", x.describe());
  ResNetOutput out;
  Tensor y = maxpool_->forward(forward_chain({stem_bn_, relu_module()}, stem_conv_->forward(x)));
  for (auto& stage : stages_) {
    y = stage->forward(y);
    out.features.push_back(y);
  }
  out.pooled = global_avg_pool(y);
  return out;
}

Tensor ResNet::forward(const Tensor& x) {
  Tensor pooled = forward_features(x).pooled;
  return fc_ ? fc_->forward(pooled) : pooled;
}

}  // namespace sl::nn
