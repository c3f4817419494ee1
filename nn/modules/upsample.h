// Upsample, as torch.nn.Upsample with an integer scale.
//
// Contract: Upsample(scale, mode, align_corners): integer scale >= 1; mode "nearest" or "linear"
// (bilinear for [N, C, H, W], trilinear for [N, C, D, H, W], as torch's "bilinear" /
// "trilinear"); the spatial rank is taken from the input. Other ranks or modes throw. No
// parameters or buffers; the op and its backward are nn/functional/upsample.h.
#pragma once
#include <string>

#include "nn/module.h"

namespace sl::nn {

class Upsample : public Module {
 public:
  explicit Upsample(int64_t scale, std::string mode = "nearest", bool align_corners = false);
  Tensor forward(const Tensor& x) override;

 private:
  int64_t scale_;
  std::string mode_;
  bool align_corners_;
};

}  // namespace sl::nn
