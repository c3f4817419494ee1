// Activation modules: thin Module wrappers over the autodiff unary ops, so that blocks can
// hold them in a Sequential and configs can name them.
//
// Contract:
// - Each forward accepts any floating tensor and returns a tensor of the same shape; the
//   numerical conventions (kinks, overflow safety) are those of autodiff/unary.h.
// - make_activation(name) accepts "relu", "leaky_relu" (slope 0.01, or "leaky_relu:0.2"),
//   "elu", "sigmoid", "tanh", "softplus", "identity" / "none"; any other name throws sl::Error
//   listing the valid names.
// - Activations have no parameters or buffers.
#pragma once
#include <memory>
#include <string>

#include "nn/functional/normalization.h"
#include "nn/module.h"

namespace sl::nn {

class ReLU : public Module {
 public:
  ReLU() : Module("ReLU") {}
  Tensor forward(const Tensor& x) override;
};

class LeakyReLU : public Module {
 public:
  explicit LeakyReLU(double negative_slope = 0.01) : Module("LeakyReLU"), negative_slope_(negative_slope) {}
  Tensor forward(const Tensor& x) override;
  double negative_slope() const { return negative_slope_; }

 private:
  double negative_slope_;
};

class ELU : public Module {
 public:
  explicit ELU(double alpha = 1.0) : Module("ELU"), alpha_(alpha) {}
  Tensor forward(const Tensor& x) override;

 private:
  double alpha_;
};

class Sigmoid : public Module {
 public:
  Sigmoid() : Module("Sigmoid") {}
  Tensor forward(const Tensor& x) override;
};

class Tanh : public Module {
 public:
  Tanh() : Module("Tanh") {}
  Tensor forward(const Tensor& x) override;
};

class Softplus : public Module {
 public:
  Softplus() : Module("Softplus") {}
  Tensor forward(const Tensor& x) override;
};

class Identity : public Module {
 public:
  Identity() : Module("Identity") {}
  Tensor forward(const Tensor& x) override { return x; }
};

std::shared_ptr<Module> make_activation(const std::string& name);

// `m` as an activation a normalisation can fuse (ReLU; LeakyReLU with slope >= 0), else Kind::None.
NormActivation fusable_activation(const Module& m);

}  // namespace sl::nn
