// Folding an eval-mode batch norm into the convolution before it. See batch_norm_folding.h.
#include "nn/modules/batch_norm_folding.h"

#include <cmath>
#include <vector>

#include "autodiff/tape.h"

namespace sl::nn {

void fold_batch_norm(ConvNd& conv, BatchNormNd& bn) {
  SL_CHECK(bn.features() == conv.out_channels(), "fold_batch_norm: ", bn.type_name(), "(", bn.features(),
           ") does not follow a conv with ", conv.out_channels(), " output channels");
  SL_CHECK(bn.tracks_running_stats(), "fold_batch_norm: ", bn.type_name(), " has no running statistics to fold");
  SL_CHECK(!bn.folded(), "fold_batch_norm: ", bn.type_name(), " is already folded");
  const NoGradGuard no_grad;
  const int64_t out = conv.out_channels();
  const std::vector<double> mean = bn.buffer("running_mean").to_vector(), var = bn.buffer("running_var").to_vector();
  const std::vector<double> gamma = bn.affine() ? bn.parameter("weight").to_vector() : std::vector<double>(out, 1.0);
  const std::vector<double> beta = bn.affine() ? bn.parameter("bias").to_vector() : std::vector<double>(out, 0.0);
  std::vector<double> scale(out), shift(out);
  for (int64_t o = 0; o < out; ++o) {
    scale[o] = gamma[o] / std::sqrt(var[o] + bn.eps());
    shift[o] = beta[o] - mean[o] * scale[o];
  }
  conv.scale_outputs(scale, shift);
  bn.set_folded();
}

}  // namespace sl::nn
