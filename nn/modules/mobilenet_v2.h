// MobileNetV2 (Sandler et al. 2018, width 1.0) in the layout of TensorFlow's ImageNet models, whose
// batch norms are folded into the convolutions: every convolution has a bias and there is no
// normalisation layer. It is the backbone that the ImageNet weights in ../shared/data/weights fit
// (nn/modules/mobilenet_v2_tflite.h loads them).
//
// Contract:
// - MobileNetV2(options): stem (3×3 conv, stride 2, 32 channels, ReLU6) → 17 inverted residual
//   blocks (expansion t, output c, repeats n, first stride s: (1,16,1,1) (6,24,2,2) (6,32,3,2)
//   (6,64,4,2) (6,96,3,1) (6,160,3,2) (6,320,1,1)); each block is a 1×1 expansion + ReLU6 (not when
//   t = 1), a 3×3 depthwise conv + ReLU6 (stride s on a group's first block), a linear 1×1
//   projection, and adds its input when the stride is 1 and the widths agree → head (1×1 conv to
//   1280, ReLU6) → with num_classes > 0 a global average pool and a 1×1 classifier.
// - Padding is TensorFlow's "SAME": for stride 2 on an even extent the one padded row and column go
//   after the image (bottom and right), so the ImageNet weights see what they were trained on.
// - forward_map(x [N, 3, H, W], scaled to [-1, 1]) -> the head's map [N, 1280, ceil(H/32),
//   ceil(W/32)]; forward(x) -> the pooled vector [N, 1280], or the logits [N, num_classes].
//   imagenet_input(image) maps an LDR image in [0, 1] to the network's input, (255·x − 128) / 128,
//   as the TFLite model's uint8 input is dequantised.
// - Parameter names: stem.{weight,bias}; blocks.B.expand.{weight,bias} (t > 1),
//   blocks.B.depthwise.{weight,bias} ([C, 1, 3, 3]), blocks.B.project.{weight,bias}; head.{weight,bias};
//   classifier.{weight,bias}. Default initialisation: the layers' own (PyTorch's defaults).
// - Throws sl::Error naming the module and the shape for an input that is not [N, 3, H, W] with
//   H, W >= 1.
#pragma once
#include <memory>
#include <vector>

#include "nn/module.h"
#include "nn/modules/conv.h"
#include "nn/modules/depthwise_conv.h"

namespace sl::nn {

struct MobileNetV2Options {
  int64_t num_classes = 0;  // 0: a feature extractor (no pool, no classifier); 1001 for the TFLite model
  uint64_t seed = 0;
};

// One inverted residual block.
class InvertedResidual : public Module {
 public:
  InvertedResidual(int64_t in, int64_t out, int64_t expansion, int64_t stride);
  Tensor forward(const Tensor& x) override;
  int64_t stride() const { return stride_; }
  bool has_expansion() const { return expand_ != nullptr; }
  Conv2d* expand() const { return expand_.get(); }
  DepthwiseConv2d& depthwise() const { return *depthwise_; }
  Conv2d& project() const { return *project_; }

 private:
  int64_t in_, out_, stride_;
  std::shared_ptr<Conv2d> expand_, project_;
  std::shared_ptr<DepthwiseConv2d> depthwise_;
};

class MobileNetV2 : public Module {
 public:
  explicit MobileNetV2(const MobileNetV2Options& options = {});
  Tensor forward(const Tensor& x) override;
  Tensor forward_map(const Tensor& x);
  static constexpr int64_t kFeatures = 1280;
  int64_t num_classes() const { return opt_.num_classes; }
  Conv2d& stem() const { return *stem_; }
  const std::vector<std::shared_ptr<InvertedResidual>>& blocks() const { return blocks_; }
  Conv2d& head() const { return *head_; }
  Conv2d* classifier() const { return classifier_.get(); }

 private:
  MobileNetV2Options opt_;
  std::shared_ptr<Conv2d> stem_, head_, classifier_;
  std::vector<std::shared_ptr<InvertedResidual>> blocks_;
};

// (255·x − 128) / 128 for an LDR image x in [0, 1] (differentiable; any shape).
Tensor imagenet_input(const Tensor& image);

// TensorFlow "SAME" padding of one extent: (before, after) for kernel k and stride s.
std::pair<int64_t, int64_t> same_padding(int64_t extent, int64_t kernel, int64_t stride);

}  // namespace sl::nn
