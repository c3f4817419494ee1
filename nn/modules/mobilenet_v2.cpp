// MobileNetV2 with TensorFlow's folded batch norms and "SAME" padding. See mobilenet_v2.h.
#include "nn/modules/mobilenet_v2.h"

#include <algorithm>

#include "autodiff/ops.h"
#include "nn/functional/conv.h"
#include "nn/functional/depthwise_conv.h"
#include "nn/functional/pooling.h"
#include "util/error.h"

namespace sl::nn {

namespace {

Tensor relu6(const Tensor& x) { return clamp(x, 0.0, 6.0); }

// The (expansion, width, repeats, first stride) of the seven groups of blocks (the paper's Table 2).
struct Group {
  int64_t t, c, n, s;
};
constexpr Group kGroups[] = {{1, 16, 1, 1}, {6, 24, 2, 2}, {6, 32, 3, 2}, {6, 64, 4, 2},
                             {6, 96, 3, 1}, {6, 160, 3, 2}, {6, 320, 1, 1}};
constexpr int64_t kStemWidth = 32;

// x padded for a k×k window at stride s as TensorFlow's "SAME" pads it; `symmetric` receives the
// padding when it is the same on both sides of both axes (then the convolution pads, no copy).
Tensor pad_same(const Tensor& x, int64_t k, int64_t s, int64_t& symmetric) {
  const auto [top, bottom] = same_padding(x.size(2), k, s);
  const auto [left, right] = same_padding(x.size(3), k, s);
  if (top == bottom && left == right && top == left) {
    symmetric = top;
    return x;
  }
  symmetric = 0;
  return pad(x, {{top, bottom}, {left, right}});
}

}  // namespace

std::pair<int64_t, int64_t> same_padding(int64_t extent, int64_t kernel, int64_t stride) {
  const int64_t out = (extent + stride - 1) / stride;
  const int64_t total = std::max<int64_t>((out - 1) * stride + kernel - extent, 0);
  return {total / 2, total - total / 2};
}

Tensor imagenet_input(const Tensor& image) { return add_scalar(mul_scalar(image, 255.0 / 128.0), -1.0); }

InvertedResidual::InvertedResidual(int64_t in, int64_t out, int64_t expansion, int64_t stride)
    : Module("InvertedResidual"), in_(in), out_(out), stride_(stride) {
  const int64_t hidden = in * expansion;
  if (expansion != 1) expand_ = register_module("expand", std::make_shared<Conv2d>(in, hidden, 1));
  depthwise_ = register_module("depthwise", std::make_shared<DepthwiseConv2d>(hidden, 3, stride, 0, true));
  project_ = register_module("project", std::make_shared<Conv2d>(hidden, out, 1));
}

Tensor InvertedResidual::forward(const Tensor& x) {
  Tensor h = expand_ ? relu6(expand_->forward(x)) : x;
  int64_t p = 0;
  const Tensor padded = pad_same(h, 3, stride_, p);
  h = relu6(depthwise_conv2d(padded, depthwise_->parameter("weight"), depthwise_->parameter("bias"),
                             {stride_, stride_}, {p, p}));
  h = project_->forward(h);
  return stride_ == 1 && in_ == out_ ? add(h, x) : h;
}

MobileNetV2::MobileNetV2(const MobileNetV2Options& options) : Module("MobileNetV2"), opt_(options) {
  SL_CHECK(options.num_classes >= 0, "MobileNetV2: num_classes must be >= 0, got ", options.num_classes);
  stem_ = register_module("stem", std::make_shared<Conv2d>(3, kStemWidth, 3, ConvOptions{.stride = 2}));
  auto list = register_module("blocks", std::make_shared<ModuleList>());
  int64_t in = kStemWidth;
  for (const Group& g : kGroups)
    for (int64_t i = 0; i < g.n; ++i) {
      blocks_.push_back(std::make_shared<InvertedResidual>(in, g.c, g.t, i == 0 ? g.s : 1));
      list->push_back(blocks_.back());
      in = g.c;
    }
  head_ = register_module("head", std::make_shared<Conv2d>(in, kFeatures, 1));
  if (options.num_classes > 0)
    classifier_ = register_module("classifier", std::make_shared<Conv2d>(kFeatures, options.num_classes, 1));
  init_parameters(options.seed);
}

Tensor MobileNetV2::forward_map(const Tensor& x) {
  SL_CHECK(x.dim() == 4 && x.size(1) == 3 && x.size(2) >= 1 && x.size(3) >= 1,
           "MobileNetV2: expected an image [N, 3, H, W], got ", x.describe());
  int64_t p = 0;
  const Tensor padded = pad_same(x, 3, 2, p);
  Tensor h = relu6(conv2d(padded, stem_->parameter("weight"), stem_->parameter("bias"), {2, 2}, {p, p}));
  for (const auto& block : blocks_) h = block->forward(h);
  return relu6(head_->forward(h));
}

Tensor MobileNetV2::forward(const Tensor& x) {
  const Tensor pooled = global_avg_pool(forward_map(x));  // [N, 1280]
  if (!classifier_) return pooled;
  const int64_t n = pooled.size(0);
  return reshape(classifier_->forward(reshape(pooled, {n, kFeatures, 1, 1})), {n, opt_.num_classes});
}

}  // namespace sl::nn
