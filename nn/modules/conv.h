// Convolution modules: Conv2d and Conv3d over nn/functional/conv.h.
//
// Contract:
// - Conv2d(in, out, kernel, options) holds `weight` [out, in, k, k] and (when options.bias)
//   `bias` [out]; Conv3d likewise with [out, in, k, k, k]. Names, layout and default init
//   (U(±1/sqrt(fan_in)) for weight and bias) are torch.nn.Conv2d/Conv3d's. Square / cubic
//   kernels and the same stride, padding and dilation on every spatial axis; no groups.
// - forward(x [N, in, ...spatial]) -> [N, out, ...spatial'] as conv2d/conv3d; a wrong rank or
//   channel count throws naming the layer and the input shape.
// - Options are designated-initialiser friendly: Conv2d(3, 64, 7, {.stride = 2, .padding = 3,
//   .bias = false}).
#pragma once
#include <vector>

#include "nn/module.h"

namespace sl::nn {

struct ConvOptions {
  int64_t stride = 1;
  int64_t padding = 0;
  int64_t dilation = 1;
  bool bias = true;
};

// Shared by Conv2d and Conv3d: `spatial_dims` is 2 or 3.
class ConvNd : public Module {
 public:
  Tensor forward(const Tensor& x) override;
  int64_t in_channels() const { return in_; }
  int64_t out_channels() const { return out_; }
  const ConvOptions& options() const { return opt_; }
  // For inference (nn/modules/batch_norm_folding.h): output channel o becomes
  // scale[o]·conv(x)[o] + shift[o], i.e. weight[o] *= scale[o] and bias[o] = bias[o]·scale[o] +
  // shift[o] (a zero bias is registered first when there is none), each computed in float64 and
  // rounded once. Throws for vectors whose length is not the output channel count.
  void scale_outputs(const std::vector<double>& scale, const std::vector<double>& shift);

 protected:
  ConvNd(const char* type_name, int spatial_dims, int64_t in, int64_t out, int64_t kernel, ConvOptions options);
  void reset_parameters(uint64_t seed, const std::string& prefix) override;

 private:
  int dims_;
  int64_t in_, out_, kernel_;
  ConvOptions opt_;
};

class Conv2d : public ConvNd {
 public:
  Conv2d(int64_t in, int64_t out, int64_t kernel, ConvOptions options = {})
      : ConvNd("Conv2d", 2, in, out, kernel, options) {}
};

class Conv3d : public ConvNd {
 public:
  Conv3d(int64_t in, int64_t out, int64_t kernel, ConvOptions options = {})
      : ConvNd("Conv3d", 3, in, out, kernel, options) {}
};

// Conv2d or Conv3d by spatial_dims (2 or 3), for blocks that serve both.
std::shared_ptr<ConvNd> make_conv(int spatial_dims, int64_t in, int64_t out, int64_t kernel, ConvOptions options = {});

}  // namespace sl::nn
