#include "nn/modules/activations.h"

#include <cstdlib>

#include "autodiff/unary.h"

namespace sl::nn {

Tensor ReLU::forward(const Tensor& x) { return relu(x); }
Tensor LeakyReLU::forward(const Tensor& x) { return leaky_relu(x, negative_slope_); }
Tensor ELU::forward(const Tensor& x) { return elu(x, alpha_); }
Tensor Sigmoid::forward(const Tensor& x) { return sigmoid(x); }
Tensor Tanh::forward(const Tensor& x) { return tanh(x); }
Tensor Softplus::forward(const Tensor& x) { return softplus(x); }

std::shared_ptr<Module> make_activation(const std::string& name) {
  // "leaky_relu:0.2" carries the slope, so a config can name it in one string.
  const size_t colon = name.find(':');
  const std::string base = name.substr(0, colon);
  double arg = 0.0;
  const bool has_arg = colon != std::string::npos;
  if (has_arg) {
    const std::string text = name.substr(colon + 1);
    char* end = nullptr;
    arg = std::strtod(text.c_str(), &end);
    SL_CHECK(!text.empty() && end && *end == '\0', "make_activation: bad parameter in '", name, "'");
  }
  if (base == "relu") return std::make_shared<ReLU>();
  if (base == "leaky_relu") return std::make_shared<LeakyReLU>(has_arg ? arg : 0.01);
  if (base == "elu") return std::make_shared<ELU>(has_arg ? arg : 1.0);
  if (base == "sigmoid") return std::make_shared<Sigmoid>();
  if (base == "tanh") return std::make_shared<Tanh>();
  if (base == "softplus") return std::make_shared<Softplus>();
  if (base == "identity" || base == "none") return std::make_shared<Identity>();
  fail("make_activation: unknown activation '", name,
       "' (valid: relu, leaky_relu[:slope], elu[:alpha], sigmoid, tanh, softplus, identity, none)");
}

NormActivation fusable_activation(const Module& m) {
  if (dynamic_cast<const ReLU*>(&m)) return {NormActivation::Kind::ReLU, 0.0};
  if (const auto* l = dynamic_cast<const LeakyReLU*>(&m); l && l->negative_slope() >= 0)
    return {NormActivation::Kind::LeakyReLU, l->negative_slope()};
  return {};
}

}  // namespace sl::nn
