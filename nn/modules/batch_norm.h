// BatchNorm1d/2d/3d over BatchNormNd, as torch.nn.BatchNorm*d.
//
// Contract:
// - BatchNormNd(features): parameters `weight` (ones) and `bias` (zeros) [C] when affine;
//   buffers `running_mean` (zeros), `running_var` (ones) [C] and `num_batches_tracked` (I64
//   scalar) when track_running_stats — PyTorch's names, so checkpoints map one to one.
//   Training normalises with batch statistics and updates the running ones in place
//   (momentum as PyTorch) and counts batches; eval uses the running statistics. Without
//   running statistics both modes use batch statistics.
// - forward_activated / forward_absorbing fuse a following ReLU or LeakyReLU into the op. Expected input ranks: 1d [N, C] or
//   [N, C, L]; 2d [N, C, H, W]; 3d [N, C, D, H, W]; other ranks or channel counts throw.
#pragma once
#include <string>

#include "nn/functional/normalization.h"
#include "nn/module.h"

namespace sl::nn {

class BatchNormNd : public Module {
 public:
  Tensor forward(const Tensor& x) override;
  // act(forward(x)) as one op (nn/functional/normalization.h).
  Tensor forward_activated(const Tensor& x, NormActivation act);
  Tensor forward_absorbing(const Tensor& x, const Module& next) override;
  int64_t features() const { return features_; }
  double eps() const { return eps_; }
  bool affine() const { return affine_; }
  bool tracks_running_stats() const { return track_; }
  // Folded into the conv before it (nn/modules/batch_norm_folding.h): forward is then the
  // identity (with its fused activation, if any), and training mode throws.
  bool folded() const { return folded_; }
  void set_folded() { folded_ = true; }

 protected:
  BatchNormNd(const char* type_name, int spatial_dims, int64_t features, double eps, double momentum, bool affine,
              bool track_running_stats);
  void reset_parameters(uint64_t seed, const std::string& prefix) override;

 private:
  int dims_;
  int64_t features_;
  double eps_, momentum_;
  bool affine_, track_;
  bool folded_ = false;
};

class BatchNorm1d : public BatchNormNd {
 public:
  explicit BatchNorm1d(int64_t features, double eps = 1e-5, double momentum = 0.1, bool affine = true,
                       bool track_running_stats = true)
      : BatchNormNd("BatchNorm1d", 1, features, eps, momentum, affine, track_running_stats) {}
};
class BatchNorm2d : public BatchNormNd {
 public:
  explicit BatchNorm2d(int64_t features, double eps = 1e-5, double momentum = 0.1, bool affine = true,
                       bool track_running_stats = true)
      : BatchNormNd("BatchNorm2d", 2, features, eps, momentum, affine, track_running_stats) {}
};
class BatchNorm3d : public BatchNormNd {
 public:
  explicit BatchNorm3d(int64_t features, double eps = 1e-5, double momentum = 0.1, bool affine = true,
                       bool track_running_stats = true)
      : BatchNormNd("BatchNorm3d", 3, features, eps, momentum, affine, track_running_stats) {}
};

}  // namespace sl::nn
