// Harness: nn/tflite.h parse (the bytes as a .tflite file) and dequantize of every constant tensor.
// Invariant: a returned model's operator and subgraph tensor indices are in range (−1 only for
// operator inputs), each constant tensor of a fixed-size type holds exactly product(shape) ×
// element size bytes, dequantize returns one float per element or refuses with sl::Error, and the
// model holds at most kMaxModelBytesPerFileByte × size + 1 MiB bytes of vectors and strings.
#include <string>

#include "nn/tflite.h"
#include "tests/fuzz/harness/fuzz_harness.h"

namespace sl::test {

namespace {
namespace tfl = nn::tflite;

void check_indices(const char* target, const std::vector<int32_t>& indices, size_t tensors, bool allow_absent) {
  for (const int32_t i : indices)
    if (!((i >= 0 && static_cast<size_t>(i) < tensors) || (allow_absent && i == -1)))
      violation(target, "tensor index " + std::to_string(i) + " of " + std::to_string(tensors) + " returned");
}

uint64_t element_bits(tfl::TensorType t) {
  switch (t) {
    case tfl::TensorType::String: case tfl::TensorType::Resource: case tfl::TensorType::Variant: return 0;
    case tfl::TensorType::Int4: return 4;
    case tfl::TensorType::UInt8: case tfl::TensorType::Int8: case tfl::TensorType::Bool: return 8;
    case tfl::TensorType::Float16: case tfl::TensorType::Int16: case tfl::TensorType::UInt16:
    case tfl::TensorType::BFloat16: return 16;
    case tfl::TensorType::Float32: case tfl::TensorType::Int32: case tfl::TensorType::UInt32: return 32;
    case tfl::TensorType::Complex128: return 128;
    default: return 64;
  }
}
}  // namespace

void fuzz_tflite(const uint8_t* data, size_t size) {
  const char* target = "tflite";
  refuses_cleanly_or_runs(target, [&] {
    const tfl::Model m = tfl::parse(data, size, "input.tflite");
    const size_t n = m.tensors.size();
    check_indices(target, m.inputs, n, false);
    check_indices(target, m.outputs, n, false);
    uint64_t bytes = m.description.size() + n * sizeof(tfl::TensorInfo) + m.operators.size() * sizeof(tfl::OperatorInfo);
    for (const tfl::OperatorInfo& op : m.operators) {
      check_indices(target, op.inputs, n, true);
      check_indices(target, op.outputs, n, false);
      bytes += op.custom_code.size() + 4 * (op.inputs.size() + op.outputs.size());
    }
    for (const tfl::TensorInfo& t : m.tensors) {
      bytes += t.name.size() + 4 * t.shape.size() + t.data.size() + 4 * t.quant.scale.size() +
               8 * t.quant.zero_point.size();
      if (t.data.empty() || element_bits(t.type) == 0) continue;
      unsigned __int128 elements = 1;
      for (const int32_t d : t.shape) {
        if (d < 0) violation(target, "constant tensor '" + t.name + "' with a negative dimension");
        elements *= static_cast<uint64_t>(d);
        if (elements > size * uint64_t{8}) violation(target, "tensor '" + t.name + "' larger than the file");
      }
      if ((elements * element_bits(t.type) + 7) / 8 != t.data.size())
        violation(target, "tensor '" + t.name + "' holds data of the wrong size");
      refuses_cleanly_or_runs(target, [&] {
        const std::vector<float> v = tfl::dequantize(t, "input.tflite");
        if (v.size() != static_cast<size_t>(elements))
          violation(target, "dequantize of '" + t.name + "' returned " + std::to_string(v.size()) + " values");
      });
    }
    if (bytes > tfl::kMaxModelBytesPerFileByte * size + (uint64_t{1} << 20))
      violation(target, "the model holds " + std::to_string(bytes) + " bytes from a " + std::to_string(size) +
                            "-byte file");
  });
}

}  // namespace sl::test
