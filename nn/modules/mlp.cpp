#include "nn/modules/mlp.h"

#include "autodiff/shape_ops.h"

#include "nn/modules/activations.h"
#include "nn/modules/layer_norm.h"
#include "nn/modules/linear.h"
#include "nn/modules/norm.h"

namespace sl::nn {

namespace {
// BatchNorm1d over the last dim of [..., F]: leading dims are flattened into the batch, so the
// parameters and buffers keep BatchNorm1d's names.
class FeatureBatchNorm : public BatchNorm1d {
 public:
  explicit FeatureBatchNorm(int64_t features) : BatchNorm1d(features) {}
  Tensor forward(const Tensor& x) override {
    if (x.dim() == 2) return BatchNorm1d::forward(x);
    SL_CHECK(x.dim() >= 1, "MLP batch norm: input ", x.describe(), " has no feature dim");
    Shape shape = x.shape();
    return reshape(BatchNorm1d::forward(reshape(x, {-1, shape.back()})), shape);
  }
  // The same flattening around the fused norm + activation.
  Tensor forward_absorbing(const Tensor& x, const Module& next) override {
    if (x.dim() == 2) return BatchNorm1d::forward_absorbing(x, next);
    SL_CHECK(x.dim() >= 1, "MLP batch norm: input ", x.describe(), " has no feature dim");
    Shape shape = x.shape();
    const Tensor y = BatchNorm1d::forward_absorbing(reshape(x, {-1, shape.back()}), next);
    return y.defined() ? reshape(y, shape) : Tensor();
  }
};
}  // namespace

MLP::MLP(MlpOptions options) : Module("MLP"), opt_(std::move(options)) {
  const auto& w = opt_.widths;
  SL_CHECK(w.size() >= 2, "MLP: widths needs at least {in, out}, got ", w.size(), " entries");
  for (int64_t v : w) SL_CHECK(v > 0, "MLP: widths must be positive, got ", shape_str(w));
  SL_CHECK(opt_.norm == "none" || opt_.norm == "layer" || opt_.norm == "batch", "MLP: unknown norm '", opt_.norm,
           "' (valid: none, layer, batch)");
  auto net = std::make_shared<Sequential>();
  for (size_t i = 0; i + 1 < w.size(); ++i) {
    net->push_back(std::make_shared<Linear>(w[i], w[i + 1], opt_.bias));
    const bool last = i + 2 == w.size();
    if (!last && opt_.norm == "layer") net->push_back(std::make_shared<LayerNorm>(w[i + 1]));
    if (!last && opt_.norm == "batch") net->push_back(std::make_shared<FeatureBatchNorm>(w[i + 1]));
    const std::string& act = last ? opt_.output_activation : opt_.activation;
    if (!(last && (act == "identity" || act == "none"))) net->push_back(make_activation(act));
  }
  net_ = register_module("net", net);
  init_parameters(opt_.seed);
}

Tensor MLP::forward(const Tensor& x) { return net_->forward(x); }

}  // namespace sl::nn
