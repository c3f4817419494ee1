// ImageNet weights for nn::MobileNetV2 from a TensorFlow Lite model file (nn/tflite.h), such as
// ../shared/data/weights/mobilenet_v2_1.0_224_quant.tflite (8-bit, batch norms folded).
//
// Contract: load_mobilenet_v2_tflite(net, path) walks the file's CONV_2D and DEPTHWISE_CONV_2D
// operators in graph order and pairs them with net's convolutions in forward order (stem; per
// block its expansion, depthwise and projection; head; the classifier when net has one, which must
// then have the file's class count; a net without one ignores the file's last convolution). Each
// pair must agree on the kind, the weight's shape (TFLite's [O, kh, kw, I] and depthwise [1, kh, kw,
// C] against ours [O, I, kh, kw] and [C, 1, kh, kw]), the stride and the fused activation (ReLU6 but
// after the projections and the classifier). The weights and biases are dequantised ((q − zero
// point) · scale, nn::tflite::dequantize), transposed and copied into net's parameters in place, in
// their dtype. Nothing is written unless every pair agrees: a mismatch throws sl::Error naming the
// file, the operator's index and what differs.
#pragma once
#include <string>

#include "nn/modules/mobilenet_v2.h"

namespace sl::nn {

void load_mobilenet_v2_tflite(MobileNetV2& net, const std::string& path);

}  // namespace sl::nn
