// A reader for TensorFlow Lite model files (.tflite), written by hand: no flatbuffers library.
//
// A .tflite file is a FlatBuffer whose root table is `Model` of TFLite's schema.fbs. This reader
// walks the FlatBuffer binary format itself (little-endian; a table starts with an i32 soffset to
// its vtable; the vtable holds u16 vtable size, u16 table size and one u16 offset per field, 0 for
// an absent field; references to tables, vectors and strings are u32 offsets from the reference's
// own position; a vector is a u32 length and its elements) and keeps what a loader of a
// convolutional network needs: subgraph 0's tensors (shape, type, quantisation, constant data),
// its operators in execution order (builtin code, inputs, outputs, and the convolution, pooling
// and activation options), and its input and output tensor indices.
//
//   const tflite::Model m = tflite::read("mobilenet_v2_1.0_224_quant.tflite");
//   for (const tflite::OperatorInfo& op : m.operators)
//     if (op.builtin_code == tflite::kConv2D) {
//       const tflite::TensorInfo& w = m.tensors[op.inputs[1]];        // [O, H, W, I]
//       std::vector<float> weights = tflite::dequantize(w, "mobilenet");  // (q − zero_point) · scale
//     }
//
// Contract:
// - parse() requires the 4-byte file identifier "TFL3" at bytes 4-8: a FlatBuffer without it (or
//   of another schema) is refused. read() reads the whole file, then parses it.
// - Every offset, vtable and vtable entry, vector length and string is checked against the bytes
//   before it is read, in 64-bit arithmetic (no overflow); field positions need no alignment. The
//   walk follows the schema's fixed nesting (Model → SubGraph → Tensor → QuantizationParameters;
//   Model → SubGraph → Operator → options), so there is no recursion to exhaust.
// - Validated: the root and every table reached; opcode indices < the number of operator codes;
//   tensor indices of operators and of the subgraph in [0, tensors) (operator inputs may be −1,
//   "optional input absent"); buffer indices < the number of buffers; tensor types 0-18 (FLOAT32
//   .. BFLOAT16); a constant tensor (one whose buffer holds bytes) has dimensions ≥ 0 and exactly
//   product(shape) × element size bytes (STRING, RESOURCE and VARIANT excepted; INT4 packs two per
//   byte); a quantisation's zero points are absent or as many as its scales, and more than one
//   scale means one per entry of shape[quantized_dimension]; padding is SAME or VALID.
// - Buffers of large models (Buffer.offset > 1, Buffer.size) are read from that absolute file
//   offset, which must lie inside the bytes given.
// - Only subgraph 0 is read (a model needs ≥ 1 subgraph); other subgraphs are not checked.
// - Options: an operator's options are decoded by the union's type tag. Conv2DOptions,
//   DepthwiseConv2DOptions and Pool2DOptions fill padding, strides, dilations, depth multiplier,
//   filter size and activation; FullyConnected-, Concatenation-, Add-, Sub-, Mul-, Div- and
//   L2NormOptions fill the activation. A field absent from a present options table takes the
//   schema's default (0, dilations 1); with no options table the OperatorInfo defaults stay.
// - Memory: the returned Model (strings, vectors and the structs themselves) may hold at most
//   kMaxModelBytesPerFileByte × size + 1 MiB bytes; a file that shares one table or buffer among
//   many references so as to exceed it is refused. Work is linear in that bound.
// - Every violation throws ONE sl::Error, one line, beginning "tflite '<file_for_errors>': " and
//   naming what is wrong: "tflite 'x.tflite': tensor 12 'conv1/weights' points at buffer 99 of 80".
// - dequantize() returns (q − zero_point) · scale for UINT8, INT8, INT16, INT32 and INT64 constant
//   tensors, per channel along quantized_dimension when there is one scale per channel (a missing
//   zero point is 0); FLOAT32 as stored, FLOAT16 widened exactly. It throws naming the tensor for
//   an activation (no data), another type, or an integer tensor without scales.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace sl::nn::tflite {

// schema.fbs TensorType (values 0-18; the reader refuses others).
enum class TensorType : int {
  Float32 = 0, Float16 = 1, Int32 = 2, UInt8 = 3, Int64 = 4, String = 5, Bool = 6, Int16 = 7,
  Complex64 = 8, Int8 = 9, Float64 = 10, Complex128 = 11, UInt64 = 12, Resource = 13, Variant = 14,
  UInt32 = 15, UInt16 = 16, Int4 = 17, BFloat16 = 18,
};
const char* type_name(TensorType t);  // "UINT8", ...

// schema.fbs BuiltinOperator values of the ops a convolutional network uses.
enum BuiltinCode : int {
  kAdd = 0, kAveragePool2D = 1, kConcatenation = 2, kConv2D = 3, kDepthwiseConv2D = 4, kDequantize = 6,
  kFullyConnected = 9, kLogistic = 14, kMaxPool2D = 17, kMul = 18, kRelu = 19, kRelu6 = 21, kReshape = 22,
  kSoftmax = 25, kPad = 34, kMean = 40, kSub = 41, kSqueeze = 43, kQuantize = 114, kHardSwish = 117,
};
// "CONV_2D", ... for the codes above (and a few more), "CUSTOM" for 32, otherwise "UNKNOWN".
const char* builtin_name(int code);

struct Quantization {
  std::vector<float> scale;  // empty: not quantised (min/max-only parameters are not kept)
  std::vector<int64_t> zero_point;
  int32_t quantized_dimension = 0;
};

struct TensorInfo {
  std::string name;
  std::vector<int32_t> shape;
  TensorType type = TensorType::Float32;
  uint32_t buffer = 0;  // index into the model's buffers (0: the empty sentinel)
  Quantization quant;
  std::vector<uint8_t> data;  // raw little-endian bytes; empty for activations
};

enum class Padding { Same, Valid };
enum class Activation { None, Relu, ReluN1To1, Relu6, Tanh, Other };

struct OperatorInfo {
  int builtin_code = -1;    // max(deprecated_builtin_code, builtin_code) of its OperatorCode
  std::string custom_code;  // for CUSTOM ops
  int version = 1;          // the OperatorCode's version
  std::vector<int32_t> inputs, outputs;  // tensor indices; an input of −1 is an absent optional input
  int options_type = 0;     // the BuiltinOptions union tag (0: none)
  Padding padding = Padding::Same;
  Activation activation = Activation::None;
  int stride_h = 1, stride_w = 1, dilation_h = 1, dilation_w = 1, depth_multiplier = 1, filter_h = 0, filter_w = 0;
};

struct Model {
  uint32_t version = 0;  // schema version (3)
  std::string description;
  std::vector<TensorInfo> tensors;        // subgraph 0
  std::vector<OperatorInfo> operators;    // subgraph 0, in execution order
  std::vector<int32_t> inputs, outputs;   // subgraph 0's input and output tensor indices
  size_t subgraph_count = 0;
};

inline constexpr uint64_t kMaxModelBytesPerFileByte = 32;

Model parse(const uint8_t* bytes, size_t size, const std::string& file_for_errors);
Model read(const std::string& path);

std::vector<float> dequantize(const TensorInfo& t, const std::string& file_for_errors);

}  // namespace sl::nn::tflite
