// The TFLite reader (nn/tflite): the ImageNet MobileNetV2 of ../shared/data/weights, a tiny
// hand-built FlatBuffer for fields and schema defaults, and hostile inputs (truncations, byte
// flips, offsets and lengths pointing outside, shared objects, wrong identifiers).
#include "nn/tflite.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>

#include "support/tflite_builder.h"
#include "util/error.h"
#include "util/random.h"

namespace sl::test {

namespace tfl = sl::nn::tflite;

namespace {

namespace fs = std::filesystem;

const char* const kTiny = "tiny.tflite";

tfl::Model parse_bytes(const std::string& bytes, const std::string& name = kTiny) {
  return tfl::parse(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size(), name);
}

// The message of the sl::Error that parsing `bytes` throws ("" when it parses).
std::string parse_error(const std::string& bytes, const std::string& name = kTiny) {
  try {
    parse_bytes(bytes, name);
  } catch (const sl::Error& e) {
    return e.what();
  }
  return "";
}

template <class T>
void poke(std::string& bytes, size_t pos, T v) {
  std::memcpy(&bytes[pos], &v, sizeof(T));
}

// Parses `bytes`: it must either load or throw one sl::Error whose message starts by naming the
// file, on one line. Returns whether it loaded.
bool loads_or_refuses_cleanly(const std::string& bytes, const std::string& name) {
  try {
    const tfl::Model m = parse_bytes(bytes, name);
    for (const tfl::OperatorInfo& op : m.operators) {
      for (const int32_t i : op.inputs) EXPECT_TRUE(i >= -1 && static_cast<size_t>(i + 1) <= m.tensors.size());
      for (const int32_t i : op.outputs) EXPECT_TRUE(i >= 0 && static_cast<size_t>(i) < m.tensors.size());
    }
    return true;
  } catch (const sl::Error& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.rfind("tflite '" + name + "': ", 0), 0u) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    return false;
  }
}

// ---------------------------------------------------------------- the real MobileNetV2
fs::path mobilenet_path() {
  return fs::path(STREETLIGHT_SHARED_DATA) / "weights" / "mobilenet_v2_1.0_224_quant.tflite";
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

#define SKIP_WITHOUT_MOBILENET()                                                                         \
  if (!fs::exists(mobilenet_path()))                                                                     \
  GTEST_SKIP() << "MobileNetV2 not found at " << mobilenet_path() << " (set STREETLIGHT_SHARED_DATA); skipping"

const tfl::Model& mobilenet() {
  static const tfl::Model m = tfl::read(mobilenet_path().string());
  return m;
}

std::vector<const tfl::OperatorInfo*> ops_of(const tfl::Model& m, int code) {
  std::vector<const tfl::OperatorInfo*> out;
  for (const tfl::OperatorInfo& op : m.operators)
    if (op.builtin_code == code) out.push_back(&op);
  return out;
}

TEST(TfliteMobileNet, InputIsOneUint8ImageScaledByOneOver128AroundZeroPoint128) {
  SKIP_WITHOUT_MOBILENET();
  const tfl::Model& m = mobilenet();
  EXPECT_EQ(m.version, 3u);
  EXPECT_EQ(m.subgraph_count, 1u);
  ASSERT_EQ(m.inputs.size(), 1u);
  const tfl::TensorInfo& in = m.tensors[static_cast<size_t>(m.inputs[0])];
  EXPECT_EQ(in.shape, (std::vector<int32_t>{1, 224, 224, 3}));
  EXPECT_EQ(in.type, tfl::TensorType::UInt8);
  EXPECT_TRUE(in.data.empty());
  ASSERT_EQ(in.quant.scale.size(), 1u);
  EXPECT_EQ(in.quant.scale[0], 0.0078125f);
  EXPECT_EQ(in.quant.zero_point, (std::vector<int64_t>{128}));
}

TEST(TfliteMobileNet, OutputIsTheSoftmaxOver1001Classes) {
  SKIP_WITHOUT_MOBILENET();
  const tfl::Model& m = mobilenet();
  ASSERT_EQ(m.outputs.size(), 1u);
  const tfl::TensorInfo& out = m.tensors[static_cast<size_t>(m.outputs[0])];
  EXPECT_EQ(out.shape, (std::vector<int32_t>{1, 1001}));
  EXPECT_EQ(out.type, tfl::TensorType::UInt8);
  EXPECT_EQ(m.operators.back().builtin_code, tfl::kSoftmax);
  EXPECT_EQ(m.operators.back().outputs, m.outputs);
}

TEST(TfliteMobileNet, OperatorCountsAreThoseOfMobileNetV2) {
  SKIP_WITHOUT_MOBILENET();
  std::map<std::string, int> counts;
  for (const tfl::OperatorInfo& op : mobilenet().operators) ++counts[tfl::builtin_name(op.builtin_code)];
  for (const auto& [name, n] : counts) RecordProperty(name, n);
  // What the file holds (66 operators): CONV_2D 36 = 1 stem 3x3 + 16 expansion 1x1 (the first
  // block has none) + 17 projection 1x1 + 1 final 1x1 to 1280 + 1 classifier 1x1 to 1001;
  // 17 depthwise 3x3; 10 residual ADDs; the 7x7 average pool; RESHAPE [1,1,1,1001] -> [1,1001];
  // SOFTMAX. No separate RELU6 (fused into the convolutions), no MEAN, no QUANTIZE.
  const std::map<std::string, int> expected = {{"CONV_2D", 36}, {"DEPTHWISE_CONV_2D", 17}, {"ADD", 10},
                                               {"AVERAGE_POOL_2D", 1}, {"RESHAPE", 1}, {"SOFTMAX", 1}};
  EXPECT_EQ(counts, expected);
  EXPECT_EQ(mobilenet().operators.size(), 66u);
  EXPECT_EQ(mobilenet().tensors.size(), 174u);
}

TEST(TfliteMobileNet, StemConvIsStrideTwoSameRelu6WithOhwiWeights) {
  SKIP_WITHOUT_MOBILENET();
  const tfl::Model& m = mobilenet();
  const tfl::OperatorInfo& stem = m.operators.front();
  ASSERT_EQ(stem.builtin_code, tfl::kConv2D);
  ASSERT_EQ(stem.inputs.size(), 3u);
  EXPECT_EQ(stem.inputs[0], m.inputs[0]);
  const tfl::TensorInfo& w = m.tensors[static_cast<size_t>(stem.inputs[1])];
  EXPECT_EQ(w.shape, (std::vector<int32_t>{32, 3, 3, 3}));  // OHWI
  EXPECT_EQ(w.type, tfl::TensorType::UInt8);
  EXPECT_EQ(w.data.size(), 32u * 3 * 3 * 3);
  EXPECT_EQ(stem.stride_h, 2);
  EXPECT_EQ(stem.stride_w, 2);
  EXPECT_EQ(stem.dilation_h, 1);
  EXPECT_EQ(stem.dilation_w, 1);
  EXPECT_EQ(stem.padding, tfl::Padding::Same);
  EXPECT_EQ(stem.activation, tfl::Activation::Relu6);
  EXPECT_EQ(m.tensors[static_cast<size_t>(stem.outputs[0])].shape, (std::vector<int32_t>{1, 112, 112, 32}));
}

TEST(TfliteMobileNet, DepthwiseWeightsAreOneByThreeByThreeByChannels) {
  SKIP_WITHOUT_MOBILENET();
  const tfl::Model& m = mobilenet();
  int stride_two = 0;
  for (const tfl::OperatorInfo* op : ops_of(m, tfl::kDepthwiseConv2D)) {
    const tfl::TensorInfo& in = m.tensors[static_cast<size_t>(op->inputs[0])];
    const tfl::TensorInfo& w = m.tensors[static_cast<size_t>(op->inputs[1])];
    const int32_t channels = in.shape[3];
    EXPECT_EQ(w.shape, (std::vector<int32_t>{1, 3, 3, channels})) << w.name;
    EXPECT_EQ(op->depth_multiplier, 1);
    EXPECT_EQ(op->padding, tfl::Padding::Same);
    EXPECT_EQ(op->activation, tfl::Activation::Relu6);
    stride_two += op->stride_h == 2 ? 1 : 0;
  }
  EXPECT_EQ(stride_two, 4);  // 112 -> 56 -> 28 -> 14 -> 7 (the stem makes 224 -> 112)
}

TEST(TfliteMobileNet, EveryTensorIsQuantisedPerTensor) {
  SKIP_WITHOUT_MOBILENET();
  for (const tfl::TensorInfo& t : mobilenet().tensors) {
    if (t.type == tfl::TensorType::Int32 && t.quant.scale.empty()) continue;  // the RESHAPE's shape operand
    EXPECT_EQ(t.quant.scale.size(), 1u) << t.name;
    EXPECT_EQ(t.quant.zero_point.size(), 1u) << t.name;
  }
}

TEST(TfliteMobileNet, WeightsDequantiseToFiniteValuesOfPlausibleMagnitude) {
  SKIP_WITHOUT_MOBILENET();
  const tfl::Model& m = mobilenet();
  int weights = 0;
  for (const tfl::OperatorInfo& op : m.operators) {
    if (op.builtin_code != tfl::kConv2D && op.builtin_code != tfl::kDepthwiseConv2D) continue;
    const tfl::TensorInfo& w = m.tensors[static_cast<size_t>(op.inputs[1])];
    const std::vector<float> v = tfl::dequantize(w, "mobilenet");
    ASSERT_EQ(v.size(), w.data.size());
    double max_abs = 0, sum_sq = 0;
    for (const float x : v) {
      ASSERT_TRUE(std::isfinite(x)) << w.name;
      max_abs = std::max(max_abs, double(std::fabs(x)));
      sum_sq += double(x) * x;
    }
    // Batch norms are folded in, so a few weights reach tens, but none is huge and none vanishes.
    EXPECT_LT(max_abs, 100.0) << w.name;
    EXPECT_GT(std::sqrt(sum_sq / double(v.size())), 1e-4) << w.name;
    ++weights;
  }
  EXPECT_EQ(weights, 53);
}

TEST(TfliteMobileNet, BiasesAreInt32WithScaleOfInputTimesWeights) {
  SKIP_WITHOUT_MOBILENET();
  const tfl::Model& m = mobilenet();
  for (const tfl::OperatorInfo& op : m.operators) {
    if (op.builtin_code != tfl::kConv2D && op.builtin_code != tfl::kDepthwiseConv2D) continue;
    const tfl::TensorInfo& in = m.tensors[static_cast<size_t>(op.inputs[0])];
    const tfl::TensorInfo& w = m.tensors[static_cast<size_t>(op.inputs[1])];
    const tfl::TensorInfo& b = m.tensors[static_cast<size_t>(op.inputs[2])];
    ASSERT_EQ(b.type, tfl::TensorType::Int32) << b.name;
    ASSERT_EQ(b.quant.scale.size(), 1u);
    EXPECT_EQ(b.quant.zero_point, (std::vector<int64_t>{0}));
    EXPECT_NEAR(b.quant.scale[0], in.quant.scale[0] * w.quant.scale[0], 1e-6 * b.quant.scale[0]) << b.name;
    const std::vector<float> v = tfl::dequantize(b, "mobilenet");
    ASSERT_EQ(v.size(), static_cast<size_t>(w.shape[op.builtin_code == tfl::kConv2D ? 0 : 3]));
    int32_t q0;
    std::memcpy(&q0, b.data.data(), 4);
    EXPECT_FLOAT_EQ(v[0], static_cast<float>(double(q0) * b.quant.scale[0]));
  }
}

TEST(TfliteMobileNet, TruncatedFilesAreRefusedNamingTheFile) {
  SKIP_WITHOUT_MOBILENET();
  const std::string bytes = slurp(mobilenet_path());
  ASSERT_EQ(bytes.size(), 3610798u);
  // The FlatBuffer ends at byte 3,588,976 (its last object is operator code 0); the 21,822 bytes
  // after it are a zip archive holding imagenet_labels.txt (TFLite metadata's associated file),
  // which the reader does not need. So a cut inside the FlatBuffer is refused, one after it loads.
  const size_t flatbuffer_end = 3588976;
  EXPECT_EQ(bytes.substr(flatbuffer_end, 4), std::string("PK\x03\x04", 4));  // a zip local file header
  std::vector<size_t> lengths;
  for (size_t n = 0; n < 4096; n += 7) lengths.push_back(n);
  for (size_t n = 4096; n < bytes.size(); n += bytes.size() / 300 + 1) lengths.push_back(n);
  for (size_t n = flatbuffer_end - 64; n < flatbuffer_end + 4; ++n) lengths.push_back(n);
  for (const size_t n : lengths) {
    const std::string part = bytes.substr(0, n);
    EXPECT_EQ(loads_or_refuses_cleanly(part, "cut.tflite"), n >= flatbuffer_end) << n << " bytes";
  }
}

TEST(TfliteMobileNet, RandomByteFlipsLoadOrAreRefusedCleanly) {
  SKIP_WITHOUT_MOBILENET();
  const std::string bytes = slurp(mobilenet_path());
  sl::Rng rng(17);
  int refused = 0;
  const int trials = 200;
  for (int trial = 0; trial < trials; ++trial) {
    std::string b = bytes;
    // The FlatBuffer's tables and vectors sit in the last ~60 KB after the weight data: aim half of
    // the flips there, where they hit offsets and lengths.
    const size_t flips = 1 + static_cast<size_t>(rng.uniform(0, 8));
    for (size_t k = 0; k < flips; ++k) {
      const size_t lo = trial % 2 ? 0 : b.size() - 65536;
      const size_t at = lo + static_cast<size_t>(rng.uniform(0, double(b.size() - lo - 1)));
      b[at] = static_cast<char>(static_cast<uint8_t>(rng.uniform(0, 256)));
    }
    refused += loads_or_refuses_cleanly(b, "flipped.tflite") ? 0 : 1;
  }
  RecordProperty("refused", refused);
  EXPECT_GT(refused, 0);
}

// ---------------------------------------------------------------- a tiny hand-built model
TEST(TfliteTiny, ParsesEveryFieldAndTheSchemaDefaults) {
  const tfl::Model m = parse_bytes(tiny_tflite().bytes);
  EXPECT_EQ(m.version, 3u);
  EXPECT_EQ(m.description, "tiny");
  EXPECT_EQ(m.inputs, (std::vector<int32_t>{0}));
  EXPECT_EQ(m.outputs, (std::vector<int32_t>{3}));
  ASSERT_EQ(m.tensors.size(), 4u);
  const tfl::TensorInfo& in = m.tensors[0];
  EXPECT_EQ(in.name, "input");
  EXPECT_EQ(in.type, tfl::TensorType::Float32);  // absent type: FLOAT32 (0)
  EXPECT_EQ(in.buffer, 0u);                      // absent buffer: the empty sentinel
  EXPECT_TRUE(in.data.empty());
  EXPECT_TRUE(in.quant.scale.empty());
  const tfl::TensorInfo& w = m.tensors[1];
  EXPECT_EQ(w.shape, (std::vector<int32_t>{2, 1, 1, 3}));
  EXPECT_EQ(w.type, tfl::TensorType::Int8);
  EXPECT_EQ(w.data.size(), 6u);
  EXPECT_EQ(w.quant.scale, (std::vector<float>{0.5f, 0.25f}));
  EXPECT_EQ(w.quant.zero_point, (std::vector<int64_t>{0, 1}));
  EXPECT_EQ(w.quant.quantized_dimension, 0);
  EXPECT_EQ(m.tensors[3].type, tfl::TensorType::UInt8);

  ASSERT_EQ(m.operators.size(), 3u);
  const tfl::OperatorInfo& conv = m.operators[0];
  EXPECT_EQ(conv.builtin_code, tfl::kConv2D);
  EXPECT_EQ(conv.version, 2);
  EXPECT_EQ(conv.options_type, 1);
  EXPECT_EQ(conv.inputs, (std::vector<int32_t>{0, 1, 2}));
  EXPECT_EQ(conv.outputs, (std::vector<int32_t>{3}));
  EXPECT_EQ(conv.padding, tfl::Padding::Valid);
  EXPECT_EQ(conv.stride_w, 3);
  EXPECT_EQ(conv.stride_h, 2);
  EXPECT_EQ(conv.activation, tfl::Activation::Relu);
  EXPECT_EQ(conv.dilation_w, 1);  // absent: the schema's default 1
  EXPECT_EQ(conv.dilation_h, 1);
  const tfl::OperatorInfo& custom = m.operators[1];
  EXPECT_EQ(custom.builtin_code, 32);
  EXPECT_STREQ(tfl::builtin_name(custom.builtin_code), "CUSTOM");
  EXPECT_EQ(custom.custom_code, "MyOp");
  EXPECT_EQ(custom.version, 1);  // absent: the schema's default 1
  EXPECT_EQ(custom.inputs, (std::vector<int32_t>{3, -1}));  // -1: optional input absent
  EXPECT_EQ(custom.options_type, 0);
  EXPECT_EQ(custom.stride_h, 1);  // no options table: OperatorInfo's defaults
  // The extended builtin_code wins over the deprecated placeholder 127.
  EXPECT_EQ(m.operators[2].builtin_code, 150);
  EXPECT_STREQ(tfl::builtin_name(150), "UNKNOWN");
}

TEST(TfliteTiny, ReadsTheSameFromAFileAndNamesAMissingOne) {
  const fs::path p = fs::temp_directory_path() / ("streetlight_tflite_" + std::to_string(::getpid()) + ".tflite");
  {
    std::ofstream out(p, std::ios::binary);
    const std::string b = tiny_tflite().bytes;
    out.write(b.data(), static_cast<std::streamsize>(b.size()));
  }
  EXPECT_EQ(tfl::read(p.string()).tensors.size(), 4u);
  fs::remove(p);
  try {
    tfl::read(p.string());
    ADD_FAILURE() << "a missing file was read";
  } catch (const sl::Error& e) {
    EXPECT_NE(std::string(e.what()).find(p.string()), std::string::npos) << e.what();
  }
}

TEST(TfliteTiny, PerChannelWeightsDequantiseWithTheirChannelsScaleAndZeroPoint) {
  const tfl::Model m = parse_bytes(tiny_tflite().bytes);
  // w = {-2, -1, 0 | 1, 2, 3}: channel 0 scale 0.5 zero point 0, channel 1 scale 0.25 zero point 1.
  EXPECT_EQ(tfl::dequantize(m.tensors[1], kTiny), (std::vector<float>{-1.0f, -0.5f, 0.0f, 0.0f, 0.25f, 0.5f}));
  EXPECT_EQ(tfl::dequantize(m.tensors[2], kTiny), (std::vector<float>{1.0f, -2.0f}));  // int32 bias · 0.125
}

TEST(TfliteTiny, DequantiseRefusesActivationsAndUnsupportedTypesNamingTheTensor) {
  const tfl::Model m = parse_bytes(tiny_tflite().bytes);
  EXPECT_THROW(
      {
        try {
          tfl::dequantize(m.tensors[0], kTiny);
        } catch (const sl::Error& e) {
          EXPECT_NE(std::string(e.what()).find("tflite 'tiny.tflite': tensor 'input'"), std::string::npos) << e.what();
          throw;
        }
      },
      sl::Error);
  tfl::TensorInfo s;
  s.name = "strings";
  s.type = tfl::TensorType::String;
  s.data = {1, 2, 3};
  EXPECT_THROW(tfl::dequantize(s, kTiny), sl::Error);
  tfl::TensorInfo unscaled = m.tensors[1];
  unscaled.quant = {};
  EXPECT_THROW(tfl::dequantize(unscaled, kTiny), sl::Error);
  tfl::TensorInfo f;
  f.type = tfl::TensorType::Float16;
  f.data = {0x00, 0x3c, 0x00, 0xc0};  // 1.0, -2.0
  EXPECT_EQ(tfl::dequantize(f, kTiny), (std::vector<float>{1.0f, -2.0f}));
}

TEST(TfliteTiny, LargeModelBuffersAreReadFromTheirAbsoluteOffset) {
  TinyTflite t = tiny_tflite();
  // Buffer 1 moves out of the FlatBuffer: offset (field 1) and size (field 2) past its end.
  t.buffers->items[1] = fb_table()->scalar<uint64_t>(1, 0)->scalar<uint64_t>(2, 6);
  std::string bytes = FbWriter().build(t.model);
  const uint64_t offset = bytes.size();
  const std::string tail = {char(-2), char(-1), 0, 1, 2, 3};
  poke<uint64_t>(bytes, t.buffers->items[1]->pos + 8, offset);  // the offset field, 8-aligned
  EXPECT_EQ(parse_bytes(bytes + tail).tensors[1].data, (std::vector<uint8_t>{254, 255, 0, 1, 2, 3}));
  const std::string err = parse_error(bytes + tail.substr(0, 5));
  EXPECT_NE(err.find("buffer 1 data (Buffer.offset/size)"), std::string::npos) << err;
}

// ---------------------------------------------------------------- hostile inputs
TEST(TfliteHostile, AWrongIdentifierIsRefused) {
  const std::string err = parse_error(tiny_tflite("TFL2").bytes);
  EXPECT_EQ(err, "tflite 'tiny.tflite': not a TFLite file: the FlatBuffer identifier at bytes 4-8 is not \"TFL3\"");
  EXPECT_NE(parse_error(std::string(7, '\0')).find("shorter than the 8-byte FlatBuffer header"), std::string::npos);
  EXPECT_NE(parse_error("").find("tflite 'tiny.tflite'"), std::string::npos);
}

TEST(TfliteHostile, RootOffsetPastTheEndIsRefused) {
  std::string b = tiny_tflite().bytes;
  poke<uint32_t>(b, 0, static_cast<uint32_t>(b.size() + 100));
  EXPECT_NE(parse_error(b).find("root table offset"), std::string::npos) << parse_error(b);
  poke<uint32_t>(b, 0, 0xFFFFFFFFu);
  EXPECT_NE(parse_error(b).find("outside the"), std::string::npos) << parse_error(b);
}

TEST(TfliteHostile, VtableOutsideTheFileIsRefused) {
  TinyTflite t = tiny_tflite();
  std::string b = t.bytes;
  poke<int32_t>(b, t.model->pos, std::numeric_limits<int32_t>::min());  // vtable far past the end
  EXPECT_NE(parse_error(b).find("Model: the vtable"), std::string::npos) << parse_error(b);
  poke<int32_t>(b, t.model->pos, static_cast<int32_t>(t.model->pos + 1));  // vtable before byte 0
  EXPECT_NE(parse_error(b).find("outside the"), std::string::npos) << parse_error(b);
}

TEST(TfliteHostile, FieldOffsetOutsideItsTableIsRefused) {
  TinyTflite t = tiny_tflite();
  std::string b = t.bytes;
  int32_t soffset;
  std::memcpy(&soffset, &b[t.model->pos], 4);
  const size_t vtable = t.model->pos - static_cast<size_t>(soffset);
  poke<uint16_t>(b, vtable + 4, 0xFFF0);  // Model.version at offset 65520 of a 24-byte table
  const std::string err = parse_error(b);
  EXPECT_NE(err.find("Model.version: field 0 of the table at byte"), std::string::npos) << err;
}

TEST(TfliteHostile, VectorLengthOfTwoToTheThirtyOneIsRefused) {
  TinyTflite t = tiny_tflite();
  for (const FbPtr& v : {t.tensors, t.operators, t.buffers, t.opcodes}) {
    std::string b = t.bytes;
    poke<uint32_t>(b, v->pos, 0x80000000u);
    const std::string err = parse_error(b);
    EXPECT_NE(err.find("a vector of 2147483648 elements of 4 bytes"), std::string::npos) << err;
  }
  std::string b = t.bytes;
  poke<uint32_t>(b, t.tensor[1]->refs[0].second->pos, 0xFFFFFFFFu);  // w's shape
  EXPECT_NE(parse_error(b).find("tensor 1 'w' shape: a vector of 4294967295 elements"), std::string::npos)
      << parse_error(b);
}

TEST(TfliteHostile, TensorPointingAtAMissingBufferIsRefusedNamingIt) {
  TinyTflite t = tiny_tflite();
  t.tensor[1]->scalars[1].second = std::string("\x63\0\0\0", 4);  // buffer 99
  EXPECT_EQ(parse_error(FbWriter().build(t.model)), "tflite 'tiny.tflite': tensor 1 'w' points at buffer 99 of 4");
}

TEST(TfliteHostile, BufferOfTheWrongSizeIsRefusedNamingTheTensor) {
  TinyTflite t = tiny_tflite();
  t.tensor[1]->refs[0].second = fb_vec<int32_t>({2, 1, 1, 4});  // 8 weights, 6 bytes
  t.tensor[1]->refs.back().second = fb_table()->ref(2, fb_vec<float>({1.0f}));
  EXPECT_EQ(parse_error(FbWriter().build(t.model)),
            "tflite 'tiny.tflite': tensor 1 'w' (INT8 [2, 1, 1, 4]) needs 8 bytes but its buffer 1 holds 6");
  t.tensor[1]->refs[0].second = fb_vec<int32_t>({65536, 65536, 65536, 65536});  // 2^64 elements
  EXPECT_NE(parse_error(FbWriter().build(t.model)).find("needs more than"), std::string::npos);
  t.tensor[1]->refs[0].second = fb_vec<int32_t>({-2, -1, 1, 3});
  EXPECT_NE(parse_error(FbWriter().build(t.model)).find("negative dimension"), std::string::npos);
}

TEST(TfliteHostile, BadIndicesAndEnumsAreRefusedNamingTheObject) {
  {
    TinyTflite t = tiny_tflite();
    t.operators->items[2]->scalars[0].second = std::string("\x07\0\0\0", 4);
    EXPECT_EQ(parse_error(FbWriter().build(t.model)),
              "tflite 'tiny.tflite': operator 2 has opcode_index 7 of 3 operator codes");
  }
  {
    TinyTflite t = tiny_tflite();
    t.operators->items[0]->refs[0].second = fb_vec<int32_t>({0, 4, 2});
    EXPECT_EQ(parse_error(FbWriter().build(t.model)),
              "tflite 'tiny.tflite': operator 0 (CONV_2D) inputs refers to tensor 4 of 4");
    t.operators->items[0]->refs[0].second = fb_vec<int32_t>({0, 1, 2});
    t.operators->items[0]->refs[1].second = fb_vec<int32_t>({-1});  // -1 only for inputs
    EXPECT_EQ(parse_error(FbWriter().build(t.model)),
              "tflite 'tiny.tflite': operator 0 (CONV_2D) outputs refers to tensor -1 of 4");
  }
  {
    TinyTflite t = tiny_tflite();
    t.subgraph->refs[2].second = fb_vec<int32_t>({3, 2147483647});
    EXPECT_EQ(parse_error(FbWriter().build(t.model)),
              "tflite 'tiny.tflite': subgraph 0 outputs refers to tensor 2147483647 of 4");
  }
  {
    TinyTflite t = tiny_tflite();
    t.tensor[3]->scalars[0].second = std::string("\x13", 1);  // type 19
    EXPECT_EQ(parse_error(FbWriter().build(t.model)),
              "tflite 'tiny.tflite': tensor 3 'out' has tensor type 19, which this reader does not know (0-18)");
  }
  {
    TinyTflite t = tiny_tflite();
    t.operators->items[0]->refs[2].second->scalars[0].second = std::string("\x02", 1);
    EXPECT_EQ(parse_error(FbWriter().build(t.model)),
              "tflite 'tiny.tflite': operator 0 (CONV_2D) builtin_options has padding 2 (SAME = 0, VALID = 1)");
  }
  {
    TinyTflite t = tiny_tflite();
    t.tensor[1]->refs.back().second = fb_table()->ref(2, fb_vec<float>({1, 2, 3}));
    EXPECT_EQ(parse_error(FbWriter().build(t.model)),
              "tflite 'tiny.tflite': tensor 1 'w' has 3 quantization scales along dimension 0 of size 2");
    t.tensor[1]->refs.back().second = fb_table()->ref(2, fb_vec<float>({1, 2}))->scalar<int32_t>(6, 7);
    EXPECT_EQ(parse_error(FbWriter().build(t.model)),
              "tflite 'tiny.tflite': tensor 1 'w' is quantized along dimension 7 of a 4-d shape");
    t.tensor[1]->refs.back().second = fb_table()->ref(2, fb_vec<float>({1, 2}))->ref(3, fb_vec<int64_t>({0}));
    EXPECT_EQ(parse_error(FbWriter().build(t.model)),
              "tflite 'tiny.tflite': tensor 1 'w' has 2 quantization scales but 1 zero points");
  }
}

TEST(TfliteHostile, AModelWithoutSubgraphsIsRefused) {
  TinyTflite t = tiny_tflite();
  t.model->refs[1].second = fb_tables({});
  EXPECT_EQ(parse_error(FbWriter().build(t.model)), "tflite 'tiny.tflite': the model has no subgraph");
}

TEST(TfliteHostile, OneBufferSharedByManyTensorsCannotExceedTheMemoryBound) {
  // 20,000 references (80 KB) to one tensor whose buffer holds 64 KiB: 1.3 GB if each were copied.
  TinyTflite t = tiny_tflite();
  t.buffers->items[1] = fb_table()->ref(0, fb_vec(std::vector<uint8_t>(65536, 1)));
  t.tensor[1]->refs[0].second = fb_vec<int32_t>({2, 1, 1, 32768});
  t.tensor[1]->refs.back().second = fb_table()->ref(2, fb_vec<float>({1.0f}));
  t.tensors->items.assign(20000, t.tensor[1]);
  const std::string b = FbWriter().build(t.model);
  ASSERT_LT(b.size(), 200000u);
  EXPECT_NE(parse_error(b).find("bytes per file byte"), std::string::npos) << parse_error(b);
  // A few shared references are fine.
  t.tensors->items.resize(4);
  EXPECT_EQ(parse_bytes(FbWriter().build(t.model)).tensors.size(), 4u);
}

TEST(TfliteHostile, EveryTruncationOfTheTinyModelIsRefused) {
  const std::string b = tiny_tflite().bytes;
  for (size_t n = 0; n < b.size(); ++n) {
    // The last bytes may be padding or a string's terminator, which the reader does not need.
    const bool loaded = loads_or_refuses_cleanly(b.substr(0, n), kTiny);
    if (loaded) {
      EXPECT_GE(n, b.size() - 8) << n;
    }
  }
}

TEST(TfliteHostile, EveryByteOfTheTinyModelSetToExtremesLoadsOrIsRefusedCleanly) {
  const std::string b = tiny_tflite().bytes;
  int refused = 0, trials = 0;
  for (size_t i = 0; i < b.size(); ++i)
    for (const uint8_t v : {uint8_t(0x00), uint8_t(0xFF), uint8_t(0x80), uint8_t(0x7F), uint8_t(b[i] ^ 1)}) {
      std::string c = b;
      c[i] = static_cast<char>(v);
      refused += loads_or_refuses_cleanly(c, kTiny) ? 0 : 1;
      ++trials;
    }
  RecordProperty("refused", refused);
  RecordProperty("trials", trials);
  EXPECT_GT(refused, 0);
}

}  // namespace

}  // namespace sl::test
