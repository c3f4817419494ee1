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
// - Guarantees: one tape node per call. Statistics are summed in double in a fixed order,
//   so results are bitwise identical for any thread count. eps keeps constant inputs finite.
#pragma once
#include <cstdint>

#include "autodiff/tensor.h"

namespace sl::nn {

Tensor batch_norm(const Tensor& x, const Tensor& running_mean, const Tensor& running_var, const Tensor& weight,
                  const Tensor& bias, bool training, double momentum = 0.1, double eps = 1e-5);
Tensor group_norm(const Tensor& x, int64_t groups, const Tensor& weight, const Tensor& bias, double eps = 1e-5);
Tensor instance_norm(const Tensor& x, const Tensor& weight, const Tensor& bias, double eps = 1e-5);

}  // namespace sl::nn
