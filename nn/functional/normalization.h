// Batch, group and instance normalisation over [N, C, ...] tensors of any spatial rank.
//
// Contract:
//   batch_norm: y = (x - mean) / sqrt(var + eps) · weight[c] + bias[c], with per-channel
//     statistics over (N, spatial). training = true uses the batch's mean and biased variance
//     and updates running_mean / running_var IN PLACE (outside the tape):
//       running = (1 - momentum)·running + momentum·batch_stat, with the UNBIASED variance
//     (n / (n - 1), as PyTorch). training = false normalises with the running statistics.
//     running_mean / running_var are [C] and may be undefined only when training (then
//     nothing is updated). Training needs more than one value per channel (as PyTorch).
//   group_norm(x, groups, weight, bias, eps): statistics per (n, group of C/groups channels).
//   instance_norm(x, weight, bias, eps): statistics per (n, c); never keeps running stats.
//   weight and bias are [C] and may be undefined (then 1 and 0).
// - Requires: F32 or F64; x of rank >= 2 (>= 3 for instance_norm); C divisible by groups.
//   Throws sl::Error naming the op and the shapes otherwise.
//   act (all three): an activation applied to the normalised output inside the same op,
//     act(y) with ReLU max(y, 0) or LeakyReLU (y > 0 ? y : slope·y, slope >= 0). The result
//     and every gradient are bitwise those of relu(norm(x)) / leaky_relu(norm(x), slope) as
//     two ops (tested); fusing saves the activation's forward pass, its output buffer and its
//     tape node (the backward takes the activation's gradient in one pass, then the norm's).
// - Guarantees: one tape node per call. Statistics are summed in double in a fixed order,
//   so results are bitwise identical for any thread count. eps keeps constant inputs finite.
#pragma once
#include <cstdint>

#include "autodiff/tensor.h"

namespace sl::nn {

// An activation fused into a normalisation (see act above).
struct NormActivation {
  enum class Kind { None, ReLU, LeakyReLU };
  Kind kind = Kind::None;
  double slope = 0.0;  // LeakyReLU's negative slope, >= 0
};

Tensor batch_norm(const Tensor& x, const Tensor& running_mean, const Tensor& running_var, const Tensor& weight,
                  const Tensor& bias, bool training, double momentum = 0.1, double eps = 1e-5,
                  NormActivation act = {});
Tensor group_norm(const Tensor& x, int64_t groups, const Tensor& weight, const Tensor& bias, double eps = 1e-5,
                  NormActivation act = {});
Tensor instance_norm(const Tensor& x, const Tensor& weight, const Tensor& bias, double eps = 1e-5,
                     NormActivation act = {});

}  // namespace sl::nn
