// MLP: a stack of Linear layers with an activation (and optional norm) between them.
//
// Contract:
// - widths = {in, hidden..., out} (at least 2 entries, all > 0). Layer i maps widths[i] to
//   widths[i+1]; every layer but the last is followed by [norm] and the activation; the last is
//   followed by output_activation (default identity).
// - Children live in one Sequential named "net", numbered in order, so parameters read
//   net.0.weight, net.0.bias, net.2.weight, ... (PyTorch's nn.Sequential naming).
// - activation / output_activation: any name make_activation accepts; norm: "none", "layer"
//   (LayerNorm) or "batch" (BatchNorm1d over the last dim, leading dims flattened).
// - forward maps x [..., in] to [..., out]. Parameters are initialised from `seed` (init.h).
// - Throws sl::Error naming the bad option.
#pragma once
#include <memory>
#include <string>
#include <vector>

#include "nn/module.h"

namespace sl::nn {

struct MlpOptions {
  std::vector<int64_t> widths{};
  std::string activation = "relu";
  std::string norm = "none";
  std::string output_activation = "identity";
  bool bias = true;
  uint64_t seed = 0;
};

class MLP : public Module {
 public:
  explicit MLP(MlpOptions options);
  Tensor forward(const Tensor& x) override;
  const MlpOptions& options() const { return opt_; }

 private:
  MlpOptions opt_;
  std::shared_ptr<Module> net_;
};

}  // namespace sl::nn
