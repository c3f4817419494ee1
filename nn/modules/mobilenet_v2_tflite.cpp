// MobileNetV2's ImageNet weights from a TFLite file. See mobilenet_v2_tflite.h.
#include "nn/modules/mobilenet_v2_tflite.h"

#include <vector>

#include "autodiff/tape.h"
#include "nn/tflite.h"
#include "util/error.h"

namespace sl::nn {

namespace {

constexpr int kConv2d = 3, kDepthwise = 4;  // TFLite builtin operator codes

// One of our convolutions, as the file must describe it.
struct Slot {
  Module* layer;
  bool depthwise;
  int64_t stride;
  bool relu6;
  std::string name;
};

// The file's values of one tensor in our layout: OHWI -> OIHW, and [1, kh, kw, C] -> [C, 1, kh, kw].
std::vector<double> to_our_layout(const std::vector<float>& v, const std::vector<int32_t>& shape, bool depthwise) {
  const int64_t a = shape[0], kh = shape[1], kw = shape[2], b = shape[3];
  std::vector<double> out(v.size());
  if (depthwise) {  // a = 1, b = C
    for (int64_t y = 0; y < kh; ++y)
      for (int64_t x = 0; x < kw; ++x)
        for (int64_t c = 0; c < b; ++c) out[(c * kh + y) * kw + x] = v[(y * kw + x) * b + c];
    return out;
  }
  for (int64_t o = 0; o < a; ++o)  // a = O, b = I
    for (int64_t y = 0; y < kh; ++y)
      for (int64_t x = 0; x < kw; ++x)
        for (int64_t i = 0; i < b; ++i) out[((o * b + i) * kh + y) * kw + x] = v[((o * kh + y) * kw + x) * b + i];
  return out;
}

std::string shape_text(const std::vector<int32_t>& s) {
  std::string t = "[";
  for (size_t i = 0; i < s.size(); ++i) t += (i ? ", " : "") + std::to_string(s[i]);
  return t + "]";
}

}  // namespace

void load_mobilenet_v2_tflite(MobileNetV2& net, const std::string& path) {
  std::vector<Slot> slots{{&net.stem(), false, 2, true, "stem"}};
  for (size_t b = 0; b < net.blocks().size(); ++b) {
    const auto& block = *net.blocks()[b];
    const std::string prefix = "blocks." + std::to_string(b) + ".";
    if (block.has_expansion()) slots.push_back({block.expand(), false, 1, true, prefix + "expand"});
    slots.push_back({&block.depthwise(), true, block.stride(), true, prefix + "depthwise"});
    slots.push_back({&block.project(), false, 1, false, prefix + "project"});
  }
  slots.push_back({&net.head(), false, 1, true, "head"});
  if (net.classifier()) slots.push_back({net.classifier(), false, 1, false, "classifier"});

  const tflite::Model model = tflite::read(path);
  std::vector<size_t> convs;
  for (size_t k = 0; k < model.operators.size(); ++k) {
    const int code = model.operators[k].builtin_code;
    if (code == kConv2d || code == kDepthwise) convs.push_back(k);
  }
  const size_t expected = slots.size() + (net.classifier() ? 0 : 1);
  SL_CHECK(convs.size() == expected, "tflite '", path, "': ", convs.size(),
           " convolutions, a MobileNetV2 (width 1.0) has ", expected);

  // Check everything and convert, then write: a mismatch leaves net as it was.
  std::vector<std::pair<std::vector<double>, std::vector<double>>> values;
  for (size_t i = 0; i < slots.size(); ++i) {
    const Slot& s = slots[i];
    const tflite::OperatorInfo& op = model.operators[convs[i]];
    const std::string where = "tflite '" + path + "': operator " + std::to_string(convs[i]) + " (for " + s.name + ")";
    SL_CHECK((op.builtin_code == kDepthwise) == s.depthwise, where, " is ", tflite::builtin_name(op.builtin_code),
             ", expected ", s.depthwise ? "DEPTHWISE_CONV_2D" : "CONV_2D");
    SL_CHECK(op.inputs.size() >= 3 && op.inputs[1] >= 0 && op.inputs[2] >= 0, where, " has no weight or bias input");
    SL_CHECK(op.stride_h == s.stride && op.stride_w == s.stride, where, ": stride ", op.stride_h, "×", op.stride_w,
             ", expected ", s.stride);
    SL_CHECK(op.dilation_h == 1 && op.dilation_w == 1, where, ": dilation ", op.dilation_h, "×", op.dilation_w);
    SL_CHECK(!s.depthwise || op.depth_multiplier == 1, where, ": depth multiplier ", op.depth_multiplier);
    const auto want_act = s.relu6 ? tflite::Activation::Relu6 : tflite::Activation::None;
    SL_CHECK(op.activation == want_act, where, ": fused activation ", static_cast<int>(op.activation), ", expected ",
             s.relu6 ? "RELU6" : "none");
    const tflite::TensorInfo& w = model.tensors.at(static_cast<size_t>(op.inputs[1]));
    const tflite::TensorInfo& b = model.tensors.at(static_cast<size_t>(op.inputs[2]));
    const Tensor& ours = s.layer->parameter("weight");
    const int64_t out = ours.size(0), in = ours.size(1), k = ours.size(2);
    const std::vector<int32_t> want = s.depthwise ? std::vector<int32_t>{1, int32_t(k), int32_t(k), int32_t(out)}
                                                  : std::vector<int32_t>{int32_t(out), int32_t(k), int32_t(k), int32_t(in)};
    SL_CHECK(w.shape == want, where, ": weight '", w.name, "' is ", shape_text(w.shape), ", expected ", shape_text(want));
    SL_CHECK(b.shape == std::vector<int32_t>{int32_t(out)}, where, ": bias '", b.name, "' is ", shape_text(b.shape),
             ", expected [", out, "]");
    const std::vector<float> bias = tflite::dequantize(b, path);
    values.emplace_back(to_our_layout(tflite::dequantize(w, path), w.shape, s.depthwise),
                        std::vector<double>(bias.begin(), bias.end()));
  }
  const NoGradGuard no_grad;
  for (size_t i = 0; i < slots.size(); ++i) {
    Tensor& w = slots[i].layer->parameter("weight");
    Tensor& b = slots[i].layer->parameter("bias");
    w.copy_(Tensor::from_vector(values[i].first, w.shape(), w.dtype()));
    b.copy_(Tensor::from_vector(values[i].second, b.shape(), b.dtype()));
  }
}

}  // namespace sl::nn
