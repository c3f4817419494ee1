// DepthwiseConv2d: one k×k filter per channel (PyTorch's nn.Conv2d(C, C, k, groups=C)), over
// nn/functional/depthwise_conv.h; the spatial half of a MobileNetV2 inverted residual block.
//
// Contract:
// - DepthwiseConv2d(channels, kernel, stride, padding, bias, seed) holds `weight` [C, 1, k, k]
//   and (when bias) `bias` [C], initialised from `seed` as torch.nn.Conv2d with groups = C:
//   U(±1/sqrt(fan_in)) for both, fan_in = k·k (nn/init.h, default_layer_init).
// - forward(x [N, C, H, W]) -> [N, C, Ho, Wo] as depthwise_conv2d with the same stride and padding
//   on both axes; a wrong rank or channel count throws naming the layer and the input shape.
#pragma once
#include <cstdint>

#include "nn/module.h"

namespace sl::nn {

class DepthwiseConv2d : public Module {
 public:
  DepthwiseConv2d(int64_t channels, int64_t kernel, int64_t stride = 1, int64_t padding = 0, bool bias = true,
                  uint64_t seed = 0);
  Tensor forward(const Tensor& x) override;
  int64_t channels() const { return channels_; }
  int64_t kernel() const { return kernel_; }
  int64_t stride() const { return stride_; }
  int64_t padding() const { return padding_; }

 protected:
  void reset_parameters(uint64_t seed, const std::string& prefix) override;

 private:
  int64_t channels_, kernel_, stride_, padding_;
  bool bias_;
};

}  // namespace sl::nn
