// The safetensors file format (docs/DESIGN.md, "Checkpoints"): reading and atomic writing.
//
// Layout: 8-byte little-endian header length N; N bytes of JSON
//   {"<name>": {"dtype": "F32", "shape": [2, 3], "data_offsets": [begin, end]}, ...,
//    "__metadata__": {"<key>": "<string>", ...}}
// padded with spaces to a multiple of 8; then the raw little-endian data, offsets relative to
// its start. Files written here are readable by the official library and PyTorch.
//
// Contract:
// - write_safetensors writes F32 (optionally as F16), F64 and I64 tensors of any shape (0-d and empty included)
//   under their names (non-empty, not "__metadata__"), tightly packed in name order, to a
//   temporary file in the target's folder, flushes and fsyncs it, then renames it over the
//   target: a crash leaves either the old file or the new one, never a half-written file.
//   Throws sl::Error naming the path and the OS error on failure.
// - read_safetensors validates BEFORE allocating anything sized by the file: the header length
//   against the file size and a 100 MB cap, the JSON structure, every dtype and shape, that
//   end − begin equals numel × dtype size, and that data ranges are ordered, non-overlapping
//   and inside the file. Any violation (truncation, garbage, hostile sizes) throws ONE
//   sl::Error naming the file and the offending tensor or field; it never crashes, hangs or
//   allocates more than the file's size (times 8 for widened integers).
// - dtypes: F32, F64 and I64 are read exactly; F16 and BF16 are widened exactly to F32; I8, U8,
//   I16, U16, I32, U32, BOOL exactly to I64; U64 to I64 when every value fits. Other dtypes
//   (F8 variants, ...) throw naming the tensor and the dtype. file_dtypes keeps what was stored.
#pragma once
#include <cstdint>
#include <map>
#include <string>

#include "nn/module.h"

namespace sl::nn {

using Metadata = std::map<std::string, std::string>;

struct SafetensorsFile {
  StateDict tensors;
  std::map<std::string, std::string> file_dtypes;  // name -> dtype as stored ("F16", ...)
  Metadata metadata;
};

inline constexpr uint64_t kMaxSafetensorsHeaderBytes = 100ull << 20;

// f32_as_f16: store F32 tensors as F16 (round to nearest even; a finite value beyond ±65504
// throws naming the tensor), e.g. for released weights; the reader widens them back.
struct SafetensorsWriteOptions {
  bool f32_as_f16 = false;
};
void write_safetensors(const std::string& path, const StateDict& tensors, const Metadata& metadata = {},
                       const SafetensorsWriteOptions& options = {});
SafetensorsFile read_safetensors(const std::string& path);

// IEEE binary16 -> binary32, exact (subnormals, infinities and NaN included); also nn/tflite.cpp's.
float half_to_float(uint16_t h);

// Writes `bytes` to `path` atomically (temp file in the same folder, fsync, rename).
void write_file_atomically(const std::string& path, const std::string& bytes);

}  // namespace sl::nn
