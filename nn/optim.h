// Optimisers (SGD, Adam, AdamW) with PyTorch's update rules, and global gradient-norm clipping.
//
// Contract:
// - An optimiser is built over named parameters (Module::named_parameters()); the names key its
//   state for checkpoints. Parameters must be contiguous floating leaves. Its state is created
//   at construction (zeros, same dtype and shape as each parameter) so that a checkpoint can be
//   loaded before the first step.
// - step() updates, in place under NoGradGuard, every parameter that HAS a gradient; a
//   parameter without one (frozen, or not reached by backward) is skipped and its per-parameter
//   step count does not advance, as in PyTorch. Scalars are computed in double.
// - Update rules (g = gradient, t = that parameter's step count after incrementing):
//   SGD:   g += wd·p; buf = t == 1 ? g : momentum·buf + (1 − dampening)·g;
//          g = nesterov ? g + momentum·buf : buf (when momentum > 0); p −= lr·g.
//   Adam:  g += wd·p; m = β1·m + (1 − β1)·g; v = β2·v + (1 − β2)·g²;
//          p −= (lr / (1 − β1^t)) · m / (sqrt(v) / sqrt(1 − β2^t) + eps).
//   AdamW: p *= 1 − lr·wd first, then Adam with no wd in g (decoupled weight decay).
// - state_dict() names state tensors "<slot>.<parameter name>": "momentum_buffer.x" (SGD),
//   "exp_avg.x", "exp_avg_sq.x" (Adam/AdamW), and "step.x" (I64 scalar, every optimiser).
//   load_state_dict() checks all names, shapes and dtypes and throws ONE sl::Error listing
//   what is missing, unexpected or mismatched; it copies in place.
// - Weight averaging (off unless enable_average(decay), 0 < decay < 1): after each update of
//   a parameter, its exponential moving average a ← d·a + (1 − d)·p with
//   d = min(decay, (1 + t)/(10 + t)) (the short-run ramp of TensorFlow's ExponentialMovingAverage
//   num_updates), and a = p at t = 1. The averages are the state slot "average"
//   ("average.<param>"), so checkpoints carry them and a resumed run averages bit-identically;
//   enable it before loading a checkpoint. swap_average() swaps every parameter that has been
//   stepped with its average, in place (so modules see the averaged weights); a second call
//   swaps back. Parameters never stepped (frozen) keep their values.
// - Per-parameter rates: set_lr_scale(prefix, s) makes every parameter whose name starts with
//   prefix step at lr·s in place of lr (all its uses of lr, AdamW's decay among them); lr·1 is lr
//   bit for bit. The scale is not state: who builds the optimiser sets it, before or after loading
//   a checkpoint. A prefix that names no parameter, or a scale that is not finite and > 0, throws.
// - Bad hyperparameters (lr < 0, betas outside [0, 1), eps <= 0, momentum < 0, decay outside
//   (0, 1)) throw.
#pragma once
#include <string>
#include <vector>

#include "nn/module.h"

namespace sl::nn {

class Optimizer {
 public:
  virtual ~Optimizer() = default;
  void step();
  void zero_grad();
  double lr() const { return lr_; }
  void set_lr(double lr);
  void set_lr_scale(const std::string& prefix, double scale);
  const NamedTensors& params() const { return params_; }
  const std::string& type_name() const { return type_name_; }
  StateDict state_dict() const;
  void load_state_dict(const StateDict& state);
  void enable_average(double decay);
  bool averaging() const { return average_decay_ > 0; }
  void swap_average();

 protected:
  Optimizer(std::string type_name, NamedTensors params, double lr, std::vector<std::string> slots);
  // Updates parameter i (its gradient g, contiguous, same dtype) given its step count t >= 1.
  virtual void update(size_t i, const Tensor& g, int64_t t) = 0;
  Tensor& slot(size_t slot_index, size_t param_index) { return state_[slot_index][param_index]; }
  double lr_of(size_t param_index) const { return lr_ * lr_scale_[param_index]; }

 private:
  std::string type_name_;
  NamedTensors params_;
  double lr_;
  std::vector<double> lr_scale_;  // one per parameter, 1 unless set_lr_scale
  std::vector<std::string> slot_names_;
  std::vector<std::vector<Tensor>> state_;  // [slot][param]
  std::vector<Tensor> steps_;               // I64 scalars, one per parameter
  double average_decay_ = 0.0;              // > 0 when weight averaging is on
  size_t average_slot_ = 0;
  void update_average(size_t i, int64_t t);
};

struct SgdOptions {
  double lr = 1e-2;
  double momentum = 0.0;
  double dampening = 0.0;
  double weight_decay = 0.0;
  bool nesterov = false;
};

class SGD : public Optimizer {
 public:
  SGD(NamedTensors params, SgdOptions options);

 protected:
  void update(size_t i, const Tensor& g, int64_t t) override;

 private:
  SgdOptions opt_;
};

struct AdamOptions {
  double lr = 1e-3;
  double beta1 = 0.9;
  double beta2 = 0.999;
  double eps = 1e-8;
  double weight_decay = 0.0;  // L2 in Adam, decoupled in AdamW
};

class Adam : public Optimizer {
 public:
  Adam(NamedTensors params, AdamOptions options);

 protected:
  Adam(std::string type_name, NamedTensors params, AdamOptions options, bool decoupled);
  void update(size_t i, const Tensor& g, int64_t t) override;

 private:
  AdamOptions opt_;
  bool decoupled_;
};

class AdamW : public Adam {
 public:
  // PyTorch's AdamW default weight decay is 0.01; AdamOptions{} defaults to 0, so pass it.
  AdamW(NamedTensors params, AdamOptions options);
};

// Scales every gradient by max_norm / (norm + 1e-6) when the global L2 norm over all of them
// exceeds max_norm (as torch.nn.utils.clip_grad_norm_), and returns the norm before clipping.
// A NaN or Inf norm is returned as is and the gradients are left untouched, so the caller can
// report it and skip the step. Parameters without a gradient are ignored.
double clip_grad_norm(const std::vector<Tensor>& params, double max_norm);
double clip_grad_norm(const NamedTensors& params, double max_norm);

}  // namespace sl::nn
