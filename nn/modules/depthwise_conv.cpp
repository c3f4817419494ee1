#include "nn/modules/depthwise_conv.h"

#include "nn/functional/depthwise_conv.h"
#include "nn/init.h"

namespace sl::nn {

DepthwiseConv2d::DepthwiseConv2d(int64_t channels, int64_t kernel, int64_t stride, int64_t padding, bool bias,
                                 uint64_t seed)
    : Module("DepthwiseConv2d"), channels_(channels), kernel_(kernel), stride_(stride), padding_(padding), bias_(bias) {
  SL_CHECK(channels > 0 && kernel > 0, "DepthwiseConv2d: channels and kernel must be positive, got channels=",
           channels, " kernel=", kernel);
  SL_CHECK(stride > 0 && padding >= 0, "DepthwiseConv2d: stride ", stride, " must be >= 1 and padding ", padding,
           " >= 0");
  register_parameter("weight", Tensor::empty({channels, 1, kernel, kernel}));
  if (bias) register_parameter("bias", Tensor::empty({channels}));
  reset_parameters(seed, "");
}

void DepthwiseConv2d::reset_parameters(uint64_t seed, const std::string& prefix) {
  Tensor none;
  default_layer_init(parameter("weight"), bias_ ? parameter("bias") : none, seed, prefix);
}

Tensor DepthwiseConv2d::forward(const Tensor& x) {
  SL_CHECK(x.dim() == 4 && x.size(1) == channels_, type_name(), "(", channels_, ", k=", kernel_,
           "): expected input [N, ", channels_, ", H, W], got ", x.describe());
  const Tensor b = bias_ ? parameter("bias") : Tensor();
  return depthwise_conv2d(x, parameter("weight"), b, {stride_, stride_}, {padding_, padding_});
}

}  // namespace sl::nn
