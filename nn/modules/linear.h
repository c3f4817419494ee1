// The Linear module.
//
// Contract:
// - Linear(in, out, bias): parameters `weight` [out, in] and (when bias) `bias` [out], PyTorch
//   names and layout, initialised as torch.nn.Linear (U(±1/sqrt(in)) for both). forward maps
//   x [..., in] to [..., out]; a last dim other than `in` throws naming the layer's shape.
#pragma once
#include "nn/module.h"

namespace sl::nn {

class Linear : public Module {
 public:
  Linear(int64_t in_features, int64_t out_features, bool bias = true);
  Tensor forward(const Tensor& x) override;
  int64_t in_features() const { return in_; }
  int64_t out_features() const { return out_; }

 protected:
  void reset_parameters(uint64_t seed, const std::string& prefix) override;

 private:
  int64_t in_, out_;
  bool has_bias_;
};

}  // namespace sl::nn
