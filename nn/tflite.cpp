#include "nn/tflite.h"

#include <algorithm>
#include <bit>
#include <cstring>
#include <fstream>
#include <limits>

#include "nn/safetensors.h"
#include "util/error.h"

namespace sl::nn::tflite {

static_assert(std::endian::native == std::endian::little,
              "FlatBuffers store little-endian data; this reader assumes a little-endian host");

namespace {

// Field indices of schema.fbs (a union takes two: its type tag, then its table).
namespace field {
constexpr int kModelVersion = 0, kModelOperatorCodes = 1, kModelSubgraphs = 2, kModelDescription = 3,
              kModelBuffers = 4;
constexpr int kOpCodeDeprecatedBuiltin = 0, kOpCodeCustom = 1, kOpCodeVersion = 2, kOpCodeBuiltin = 3;
constexpr int kSubGraphTensors = 0, kSubGraphInputs = 1, kSubGraphOutputs = 2, kSubGraphOperators = 3;
constexpr int kTensorShape = 0, kTensorType = 1, kTensorBuffer = 2, kTensorName = 3, kTensorQuantization = 4;
constexpr int kQuantScale = 2, kQuantZeroPoint = 3, kQuantDimension = 6;
constexpr int kBufferData = 0, kBufferOffset = 1, kBufferSize = 2;
constexpr int kOperatorOpcodeIndex = 0, kOperatorInputs = 1, kOperatorOutputs = 2, kOperatorOptionsType = 3,
              kOperatorOptions = 4;
}  // namespace field

// BuiltinOptions union tags (schema.fbs order, NONE = 0).
namespace options {
constexpr int kConv2D = 1, kDepthwiseConv2D = 2, kPool2D = 5, kFullyConnected = 8, kConcatenation = 10, kAdd = 11,
              kL2Norm = 12, kMul = 21, kSub = 28, kDiv = 29;
}  // namespace options

constexpr uint64_t kMiB = uint64_t{1} << 20;

// A table: its position and its vtable's.
struct Table {
  uint64_t pos = 0, vtable = 0;
  uint16_t vtable_size = 0, table_size = 0;
};

// A vector: the position of its first element and its length.
struct Vec {
  uint64_t begin = 0;
  uint32_t length = 0;
};

// Bounds-checked access to the FlatBuffer; every failure names the file and what was being read.
class Reader {
 public:
  Reader(const uint8_t* bytes, size_t size, const std::string& file)
      : bytes_(bytes), size_(size), file_(file), budget_(kMaxModelBytesPerFileByte * size + kMiB) {}

  template <class... Args>
  [[noreturn]] void error(const Args&... args) const {
    fail("tflite '", file_, "': ", args...);
  }

  uint64_t size() const { return size_; }

  // Charges `bytes` of output against the memory bound.
  void charge(uint64_t bytes, const std::string& what) {
    if (bytes > budget_)
      error(what, " would make the model hold more than ", kMaxModelBytesPerFileByte,
            " bytes per file byte (objects shared by many references?)");
    budget_ -= bytes;
  }

  void need(uint64_t pos, uint64_t n, const std::string& what) const {
    if (pos > size_ || n > size_ - pos)
      error(what, " at byte ", pos, " (", n, " bytes) lies outside the ", size_, "-byte file");
  }

  template <class T>
  T scalar(uint64_t pos, const std::string& what) const {
    need(pos, sizeof(T), what);
    T v;
    std::memcpy(&v, bytes_ + pos, sizeof(T));
    return v;
  }

  // The object a u32 offset at `pos` refers to.
  uint64_t follow(uint64_t pos, const std::string& what) const {
    const uint64_t target = pos + scalar<uint32_t>(pos, what);
    need(target, 0, what);
    return target;
  }

  Table table(uint64_t pos, const std::string& what) const {
    Table t;
    t.pos = pos;
    const int64_t soffset = scalar<int32_t>(pos, what + " (table)");
    const int64_t vtable = static_cast<int64_t>(pos) - soffset;
    if (vtable < 0 || static_cast<uint64_t>(vtable) > size_)
      error(what, ": the vtable of the table at byte ", pos, " would be at byte ", vtable, ", outside the ", size_,
            "-byte file");
    t.vtable = static_cast<uint64_t>(vtable);
    t.vtable_size = scalar<uint16_t>(t.vtable, what + " (vtable)");
    t.table_size = scalar<uint16_t>(t.vtable + 2, what + " (vtable)");
    if (t.vtable_size < 4 || t.vtable_size % 2 != 0)
      error(what, ": the vtable at byte ", t.vtable, " declares ", t.vtable_size, " bytes (need an even number >= 4)");
    if (t.table_size < 4) error(what, ": the vtable at byte ", t.vtable, " declares a ", t.table_size, "-byte table");
    need(t.vtable, t.vtable_size, what + " (vtable)");
    need(pos, t.table_size, what + " (table)");
    return t;
  }

  // The position of field `index` of `t`, or 0 when absent; the field's `bytes` lie in the table.
  uint64_t field_pos(const Table& t, int index, uint64_t bytes, const std::string& what) const {
    const uint64_t entry = 4 + 2 * static_cast<uint64_t>(index);
    if (entry + 2 > t.vtable_size) return 0;
    const uint16_t off = scalar<uint16_t>(t.vtable + entry, what);
    if (off == 0) return 0;
    if (off < 4 || off + bytes > t.table_size)
      error(what, ": field ", index, " of the table at byte ", t.pos, " sits at offset ", off, " (", bytes,
            " bytes), outside its ", t.table_size, "-byte table");
    return t.pos + off;
  }

  template <class T>
  T field(const Table& t, int index, T fallback, const std::string& what) const {
    const uint64_t p = field_pos(t, index, sizeof(T), what);
    return p ? scalar<T>(p, what) : fallback;
  }

  // The table, vector or string a field refers to; 0 when the field is absent.
  uint64_t ref(const Table& t, int index, const std::string& what) const {
    const uint64_t p = field_pos(t, index, 4, what);
    return p ? follow(p, what) : 0;
  }

  bool has_table(const Table& t, int index, Table& out, const std::string& what) const {
    const uint64_t p = ref(t, index, what);
    if (!p) return false;
    out = table(p, what);
    return true;
  }

  // A vector field of elements of `elem` bytes; absent gives an empty vector.
  Vec vec(const Table& t, int index, uint64_t elem, const std::string& what) const {
    const uint64_t p = ref(t, index, what);
    if (!p) return {};
    return vec_at(p, elem, what);
  }

  Vec vec_at(uint64_t p, uint64_t elem, const std::string& what) const {
    Vec v;
    v.length = scalar<uint32_t>(p, what + " (vector length)");
    v.begin = p + 4;
    // length < 2^32 and elem <= 8: the product fits in 64 bits.
    if (uint64_t(v.length) * elem > size_ - std::min(size_, v.begin))
      error(what, ": a vector of ", v.length, " elements of ", elem, " bytes at byte ", p, " runs past the end of the ",
            size_, "-byte file");
    return v;
  }

  // Element i of a vector of tables.
  Table table_in(const Vec& v, uint32_t i, const std::string& what) const {
    return table(follow(v.begin + 4 * uint64_t(i), what), what);
  }

  template <class T>
  std::vector<T> copy_vec(const Table& t, int index, const std::string& what) {
    const Vec v = vec(t, index, sizeof(T), what);
    charge(uint64_t(v.length) * sizeof(T), what);
    std::vector<T> out(v.length);
    if (v.length) std::memcpy(out.data(), bytes_ + v.begin, uint64_t(v.length) * sizeof(T));
    return out;
  }

  std::string string(const Table& t, int index, const std::string& what) {
    const Vec v = vec(t, index, 1, what);
    charge(v.length, what);
    return std::string(reinterpret_cast<const char*>(bytes_ + v.begin), v.length);
  }

  std::vector<uint8_t> bytes(uint64_t pos, uint64_t n, const std::string& what) {
    need(pos, n, what);
    charge(n, what);
    return std::vector<uint8_t>(bytes_ + pos, bytes_ + pos + n);
  }

 private:
  const uint8_t* bytes_;
  uint64_t size_;
  const std::string& file_;
  uint64_t budget_;
};

struct Buffer {
  uint64_t pos = 0, size = 0;  // where the bytes are in the file
};

// Bits per element; 0 for types whose size is not fixed (STRING, RESOURCE, VARIANT).
int element_bits(TensorType t) {
  switch (t) {
    case TensorType::Float32: case TensorType::Int32: case TensorType::UInt32: return 32;
    case TensorType::Float16: case TensorType::Int16: case TensorType::UInt16: case TensorType::BFloat16: return 16;
    case TensorType::UInt8: case TensorType::Int8: case TensorType::Bool: return 8;
    case TensorType::Int64: case TensorType::UInt64: case TensorType::Float64: case TensorType::Complex64: return 64;
    case TensorType::Complex128: return 128;
    case TensorType::Int4: return 4;
    case TensorType::String: case TensorType::Resource: case TensorType::Variant: return 0;
  }
  return 0;
}

std::vector<Buffer> read_buffers(Reader& r, const Table& model) {
  const Vec v = r.vec(model, field::kModelBuffers, 4, "Model.buffers");
  r.charge(uint64_t(v.length) * sizeof(Buffer), "Model.buffers");
  std::vector<Buffer> out(v.length);
  for (uint32_t i = 0; i < v.length; ++i) {
    const std::string what = cat("buffer ", i);
    const Table b = r.table_in(v, i, what);
    const uint64_t offset = r.field<uint64_t>(b, field::kBufferOffset, 0, what + " offset");
    if (offset > 1) {  // large models: the data follows the FlatBuffer (offset 1 is a writer's placeholder)
      out[i].size = r.field<uint64_t>(b, field::kBufferSize, 0, what + " size");
      out[i].pos = offset;
      r.need(offset, out[i].size, what + " data (Buffer.offset/size)");
    } else {
      const Vec data = r.vec(b, field::kBufferData, 1, what + " data");
      out[i] = {data.begin, data.length};
    }
  }
  return out;
}

struct OpCode {
  int builtin = 0, version = 1;
  std::string custom;
};

std::vector<OpCode> read_opcodes(Reader& r, const Table& model) {
  const Vec v = r.vec(model, field::kModelOperatorCodes, 4, "Model.operator_codes");
  r.charge(uint64_t(v.length) * sizeof(OpCode), "Model.operator_codes");
  std::vector<OpCode> out(v.length);
  for (uint32_t i = 0; i < v.length; ++i) {
    const std::string what = cat("operator code ", i);
    const Table t = r.table_in(v, i, what);
    const int deprecated = r.field<int8_t>(t, field::kOpCodeDeprecatedBuiltin, 0, what);
    const int extended = r.field<int32_t>(t, field::kOpCodeBuiltin, 0, what);
    out[i].builtin = std::max(deprecated, extended);
    out[i].version = r.field<int32_t>(t, field::kOpCodeVersion, 1, what);
    out[i].custom = r.string(t, field::kOpCodeCustom, what + " custom_code");
  }
  return out;
}

std::string tensor_label(uint32_t i, const std::string& name) { return cat("tensor ", i, " '", name, "'"); }

Quantization read_quantization(Reader& r, const Table& tensor, const std::string& what) {
  Quantization q;
  Table t;
  if (!r.has_table(tensor, field::kTensorQuantization, t, what + " quantization")) return q;
  q.scale = r.copy_vec<float>(t, field::kQuantScale, what + " quantization scale");
  q.zero_point = r.copy_vec<int64_t>(t, field::kQuantZeroPoint, what + " quantization zero_point");
  q.quantized_dimension = r.field<int32_t>(t, field::kQuantDimension, 0, what + " quantized_dimension");
  return q;
}

// Checks a tensor's type, quantisation and constant data against its shape.
void check_tensor(const Reader& r, const TensorInfo& t, const std::string& what) {
  const Quantization& q = t.quant;
  if (!q.zero_point.empty() && q.zero_point.size() != q.scale.size())
    r.error(what, " has ", q.scale.size(), " quantization scales but ", q.zero_point.size(), " zero points");
  if (q.scale.size() > 1) {
    const int32_t d = q.quantized_dimension;
    if (d < 0 || static_cast<size_t>(d) >= t.shape.size())
      r.error(what, " is quantized along dimension ", d, " of a ", t.shape.size(), "-d shape");
    if (static_cast<int64_t>(t.shape[static_cast<size_t>(d)]) != static_cast<int64_t>(q.scale.size()))
      r.error(what, " has ", q.scale.size(), " quantization scales along dimension ", d, " of size ",
              t.shape[static_cast<size_t>(d)]);
  }
  if (t.data.empty()) return;
  const int bits = element_bits(t.type);
  if (bits == 0) return;  // variable-size elements: nothing to check against the shape
  unsigned __int128 elements = 1;
  for (const int32_t d : t.shape) {
    if (d < 0) r.error(what, " holds data but has a negative dimension in its shape");
    elements *= static_cast<uint64_t>(d);  // ≤ 2^31 per factor, and it stops growing once past the file
    if (elements > (unsigned __int128)(r.size()) * 8) elements = (unsigned __int128)(r.size()) * 8 + 1;
  }
  const unsigned __int128 need_bytes = (elements * static_cast<unsigned>(bits) + 7) / 8;
  if (need_bytes != t.data.size())
    r.error(what, " (", type_name(t.type), " ", shape_str(std::vector<int64_t>(t.shape.begin(), t.shape.end())),
            ") needs ", need_bytes > r.size() ? cat("more than ", r.size()) : cat(uint64_t(need_bytes)),
            " bytes but its buffer ", t.buffer, " holds ", t.data.size());
}

std::vector<TensorInfo> read_tensors(Reader& r, const Table& subgraph, const std::vector<Buffer>& buffers) {
  const Vec v = r.vec(subgraph, field::kSubGraphTensors, 4, "SubGraph.tensors");
  r.charge(uint64_t(v.length) * sizeof(TensorInfo), "SubGraph.tensors");
  std::vector<TensorInfo> out(v.length);
  for (uint32_t i = 0; i < v.length; ++i) {
    const Table t = r.table_in(v, i, cat("tensor ", i));
    TensorInfo& ti = out[i];
    ti.name = r.string(t, field::kTensorName, cat("tensor ", i, " name"));
    const std::string what = tensor_label(i, ti.name);
    ti.shape = r.copy_vec<int32_t>(t, field::kTensorShape, what + " shape");
    const int type = r.field<int8_t>(t, field::kTensorType, 0, what + " type");
    if (type < 0 || type > static_cast<int>(TensorType::BFloat16))
      r.error(what, " has tensor type ", type, ", which this reader does not know (0-18)");
    ti.type = static_cast<TensorType>(type);
    ti.buffer = r.field<uint32_t>(t, field::kTensorBuffer, 0, what + " buffer");
    if (ti.buffer >= buffers.size())
      r.error(what, " points at buffer ", ti.buffer, " of ", buffers.size());
    ti.quant = read_quantization(r, t, what);
    const Buffer& b = buffers[ti.buffer];
    ti.data = r.bytes(b.pos, b.size, what + " data");
    check_tensor(r, ti, what);
  }
  return out;
}

std::vector<int32_t> tensor_indices(Reader& r, const Table& t, int index, size_t tensors, bool allow_absent,
                                    const std::string& what) {
  std::vector<int32_t> out = r.copy_vec<int32_t>(t, index, what);
  for (const int32_t i : out)
    if (!(i >= 0 && static_cast<size_t>(i) < tensors) && !(allow_absent && i == -1))
      r.error(what, " refers to tensor ", i, " of ", tensors);
  return out;
}

Padding padding_of(const Reader& r, int8_t v, const std::string& what) {
  if (v == 0) return Padding::Same;
  if (v == 1) return Padding::Valid;
  r.error(what, " has padding ", int(v), " (SAME = 0, VALID = 1)");
}

Activation activation_of(int8_t v) {
  switch (v) {
    case 0: return Activation::None;
    case 1: return Activation::Relu;
    case 2: return Activation::ReluN1To1;
    case 3: return Activation::Relu6;
    case 4: return Activation::Tanh;
    default: return Activation::Other;
  }
}

void read_options(Reader& r, const Table& o, OperatorInfo& op, const std::string& what) {
  auto i32 = [&](int index, int32_t fallback) { return r.field<int32_t>(o, index, fallback, what); };
  auto i8 = [&](int index) { return r.field<int8_t>(o, index, 0, what); };
  switch (op.options_type) {
    case options::kConv2D:
      op.padding = padding_of(r, i8(0), what);
      op.stride_w = i32(1, 0);
      op.stride_h = i32(2, 0);
      op.activation = activation_of(i8(3));
      op.dilation_w = i32(4, 1);
      op.dilation_h = i32(5, 1);
      break;
    case options::kDepthwiseConv2D:
      op.padding = padding_of(r, i8(0), what);
      op.stride_w = i32(1, 0);
      op.stride_h = i32(2, 0);
      op.depth_multiplier = i32(3, 0);
      op.activation = activation_of(i8(4));
      op.dilation_w = i32(5, 1);
      op.dilation_h = i32(6, 1);
      break;
    case options::kPool2D:
      op.padding = padding_of(r, i8(0), what);
      op.stride_w = i32(1, 0);
      op.stride_h = i32(2, 0);
      op.filter_w = i32(3, 0);
      op.filter_h = i32(4, 0);
      op.activation = activation_of(i8(5));
      break;
    case options::kConcatenation:
      op.activation = activation_of(i8(1));
      break;
    case options::kFullyConnected: case options::kAdd: case options::kL2Norm: case options::kMul:
    case options::kSub: case options::kDiv:
      op.activation = activation_of(i8(0));
      break;
    default: break;
  }
}

std::vector<OperatorInfo> read_operators(Reader& r, const Table& subgraph, const std::vector<OpCode>& codes,
                                         size_t tensors) {
  const Vec v = r.vec(subgraph, field::kSubGraphOperators, 4, "SubGraph.operators");
  r.charge(uint64_t(v.length) * sizeof(OperatorInfo), "SubGraph.operators");
  std::vector<OperatorInfo> out(v.length);
  for (uint32_t i = 0; i < v.length; ++i) {
    std::string what = cat("operator ", i);
    const Table t = r.table_in(v, i, what);
    OperatorInfo& op = out[i];
    const uint32_t code = r.field<uint32_t>(t, field::kOperatorOpcodeIndex, 0, what + " opcode_index");
    if (code >= codes.size()) r.error(what, " has opcode_index ", code, " of ", codes.size(), " operator codes");
    op.builtin_code = codes[code].builtin;
    op.version = codes[code].version;
    op.custom_code = codes[code].custom;
    r.charge(op.custom_code.size(), what + " custom_code");
    what += cat(" (", builtin_name(op.builtin_code), ")");
    op.inputs = tensor_indices(r, t, field::kOperatorInputs, tensors, true, what + " inputs");
    op.outputs = tensor_indices(r, t, field::kOperatorOutputs, tensors, false, what + " outputs");
    op.options_type = r.field<uint8_t>(t, field::kOperatorOptionsType, 0, what + " builtin_options_type");
    Table o;
    if (op.options_type != 0 && r.has_table(t, field::kOperatorOptions, o, what + " builtin_options"))
      read_options(r, o, op, what + " builtin_options");
  }
  return out;
}

}  // namespace

const char* type_name(TensorType t) {
  static const char* const names[] = {"FLOAT32", "FLOAT16", "INT32", "UINT8",  "INT64",    "STRING",  "BOOL",
                                      "INT16",   "COMPLEX64", "INT8", "FLOAT64", "COMPLEX128", "UINT64", "RESOURCE",
                                      "VARIANT", "UINT32",  "UINT16", "INT4",   "BFLOAT16"};
  const int i = static_cast<int>(t);
  return i >= 0 && i < static_cast<int>(std::size(names)) ? names[i] : "UNKNOWN";
}

const char* builtin_name(int code) {
  switch (code) {
    case kAdd: return "ADD";
    case kAveragePool2D: return "AVERAGE_POOL_2D";
    case kConcatenation: return "CONCATENATION";
    case kConv2D: return "CONV_2D";
    case kDepthwiseConv2D: return "DEPTHWISE_CONV_2D";
    case kDequantize: return "DEQUANTIZE";
    case kFullyConnected: return "FULLY_CONNECTED";
    case kLogistic: return "LOGISTIC";
    case kMaxPool2D: return "MAX_POOL_2D";
    case kMul: return "MUL";
    case kRelu: return "RELU";
    case kRelu6: return "RELU6";
    case kReshape: return "RESHAPE";
    case kSoftmax: return "SOFTMAX";
    case 28: return "TANH";
    case 32: return "CUSTOM";
    case kPad: return "PAD";
    case kMean: return "MEAN";
    case kSub: return "SUB";
    case kSqueeze: return "SQUEEZE";
    case kQuantize: return "QUANTIZE";
    case kHardSwish: return "HARD_SWISH";
    default: return "UNKNOWN";
  }
}

Model parse(const uint8_t* bytes, size_t size, const std::string& file_for_errors) {
  Reader r(bytes, size, file_for_errors);
  if (size < 8) r.error("not a TFLite file: ", size, " bytes, shorter than the 8-byte FlatBuffer header");
  if (std::memcmp(bytes + 4, "TFL3", 4) != 0)
    r.error("not a TFLite file: the FlatBuffer identifier at bytes 4-8 is not \"TFL3\"");
  const Table root = r.table(r.follow(0, "root table offset"), "Model");

  Model m;
  m.version = r.field<uint32_t>(root, field::kModelVersion, 0, "Model.version");
  m.description = r.string(root, field::kModelDescription, "Model.description");
  const std::vector<Buffer> buffers = read_buffers(r, root);
  const std::vector<OpCode> codes = read_opcodes(r, root);

  const Vec subgraphs = r.vec(root, field::kModelSubgraphs, 4, "Model.subgraphs");
  if (subgraphs.length == 0) r.error("the model has no subgraph");
  m.subgraph_count = subgraphs.length;
  const Table sg = r.table_in(subgraphs, 0, "subgraph 0");
  m.tensors = read_tensors(r, sg, buffers);
  m.inputs = tensor_indices(r, sg, field::kSubGraphInputs, m.tensors.size(), false, "subgraph 0 inputs");
  m.outputs = tensor_indices(r, sg, field::kSubGraphOutputs, m.tensors.size(), false, "subgraph 0 outputs");
  m.operators = read_operators(r, sg, codes, m.tensors.size());
  return m;
}

Model read(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  SL_CHECK(in.is_open(), "tflite '", path, "': cannot open for reading");
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  SL_CHECK(size >= 0, "tflite '", path, "': cannot determine the file size");
  std::vector<uint8_t> bytes(static_cast<size_t>(size));
  in.seekg(0);
  in.read(reinterpret_cast<char*>(bytes.data()), size);
  SL_CHECK(in.good() || size == 0, "tflite '", path, "': cannot read its ", size, " bytes");
  return parse(bytes.data(), bytes.size(), path);
}

namespace {

template <class Q>
std::vector<float> dequantize_ints(const TensorInfo& t, const std::string& what, const std::string& file) {
  const Quantization& q = t.quant;
  SL_CHECK(!q.scale.empty(), "tflite '", file, "': ", what, " (", type_name(t.type),
           ") has no quantization scale to dequantize with");
  const size_t n = t.data.size() / sizeof(Q);
  SL_CHECK(n * sizeof(Q) == t.data.size(), "tflite '", file, "': ", what, " holds ", t.data.size(),
           " bytes, not a whole number of ", type_name(t.type), " values");
  // Per channel: element i belongs to channel (i / inner) % channels, inner = product of the
  // dimensions after the quantized one.
  size_t channels = 1, inner = 1;
  if (q.scale.size() > 1) {
    const size_t d = static_cast<size_t>(q.quantized_dimension);
    SL_CHECK(q.quantized_dimension >= 0 && d < t.shape.size() &&
                 static_cast<int64_t>(t.shape[d]) == static_cast<int64_t>(q.scale.size()),
             "tflite '", file, "': ", what, " has ", q.scale.size(), " scales that do not match dimension ",
             q.quantized_dimension, " of its shape");
    channels = q.scale.size();
    for (size_t k = d + 1; k < t.shape.size(); ++k) inner *= static_cast<size_t>(std::max(t.shape[k], 0));
  }
  SL_CHECK(q.zero_point.empty() || q.zero_point.size() == q.scale.size(), "tflite '", file, "': ", what, " has ",
           q.scale.size(), " scales but ", q.zero_point.size(), " zero points");
  std::vector<float> out(n);
  for (size_t i = 0; i < n; ++i) {
    const size_t c = channels > 1 && inner > 0 ? (i / inner) % channels : 0;
    Q v;
    std::memcpy(&v, t.data.data() + i * sizeof(Q), sizeof(Q));
    const int64_t zp = q.zero_point.empty() ? 0 : q.zero_point[c];
    // In double: int32 biases and int64 values minus a zero point are exact there up to 2^53.
    out[i] = static_cast<float>((static_cast<double>(v) - static_cast<double>(zp)) * static_cast<double>(q.scale[c]));
  }
  return out;
}

}  // namespace

std::vector<float> dequantize(const TensorInfo& t, const std::string& file_for_errors) {
  const std::string what = cat("tensor '", t.name, "'");
  SL_CHECK(!t.data.empty(), "tflite '", file_for_errors, "': ", what,
           " has no constant data (an activation) to dequantize");
  switch (t.type) {
    case TensorType::UInt8: return dequantize_ints<uint8_t>(t, what, file_for_errors);
    case TensorType::Int8: return dequantize_ints<int8_t>(t, what, file_for_errors);
    case TensorType::Int16: return dequantize_ints<int16_t>(t, what, file_for_errors);
    case TensorType::Int32: return dequantize_ints<int32_t>(t, what, file_for_errors);
    case TensorType::Int64: return dequantize_ints<int64_t>(t, what, file_for_errors);
    case TensorType::Float32: {
      SL_CHECK(t.data.size() % 4 == 0, "tflite '", file_for_errors, "': ", what, " holds ", t.data.size(),
               " bytes, not a whole number of FLOAT32 values");
      std::vector<float> out(t.data.size() / 4);
      std::memcpy(out.data(), t.data.data(), t.data.size());
      return out;
    }
    case TensorType::Float16: {
      SL_CHECK(t.data.size() % 2 == 0, "tflite '", file_for_errors, "': ", what, " holds ", t.data.size(),
               " bytes, not a whole number of FLOAT16 values");
      std::vector<float> out(t.data.size() / 2);
      for (size_t i = 0; i < out.size(); ++i) {
        uint16_t h;
        std::memcpy(&h, t.data.data() + 2 * i, 2);
        out[i] = half_to_float(h);
      }
      return out;
    }
    default:
      fail("tflite '", file_for_errors, "': ", what, " has type ", type_name(t.type),
           ", which dequantize does not support (UINT8, INT8, INT16, INT32, INT64, FLOAT32, FLOAT16)");
  }
}

}  // namespace sl::nn::tflite
