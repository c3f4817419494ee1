#include "nn/safetensors.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <vector>

#include "autodiff/tape.h"
#include "util/file.h"

namespace sl::nn {

static_assert(std::endian::native == std::endian::little,
              "safetensors stores little-endian data; this reader assumes a little-endian host");

namespace {

using json = nlohmann::json;


// ---------------------------------------------------------------- dtypes
struct FileDType {
  const char* name;
  size_t bytes;
  DType target;  // what it is read into
};

constexpr FileDType kReadable[] = {
    {"F32", 4, DType::F32}, {"F64", 8, DType::F64}, {"F16", 2, DType::F32}, {"BF16", 2, DType::F32},
    {"I64", 8, DType::I64}, {"I32", 4, DType::I64}, {"I16", 2, DType::I64}, {"I8", 1, DType::I64},
    {"U64", 8, DType::I64}, {"U32", 4, DType::I64}, {"U16", 2, DType::I64}, {"U8", 1, DType::I64},
    {"BOOL", 1, DType::I64},
};

const FileDType* find_dtype(const std::string& name) {
  for (const FileDType& d : kReadable)
    if (name == d.name) return &d;
  return nullptr;
}

const char* file_dtype_name(DType d) {
  switch (d) {
    case DType::F32: return "F32";
    case DType::F64: return "F64";
    case DType::I64: return "I64";
  }
  return "?";
}

// binary32 -> IEEE binary16, rounding to nearest even; NaN stays NaN, overflow gives ±inf,
// tiny values become subnormal or ±0.
uint16_t float_to_half(float f) {
  const uint32_t x = std::bit_cast<uint32_t>(f);
  const uint16_t sign = static_cast<uint16_t>((x >> 16) & 0x8000u);
  const uint32_t abs = x & 0x7fffffffu;
  if (abs >= 0x7f800000u) return sign | 0x7c00u | (abs > 0x7f800000u ? 0x200u : 0u);  // inf / NaN
  if (abs >= 0x477ff000u) return sign | 0x7c00u;  // rounds above 65504: overflow
  if (abs < 0x33000001u) return sign;              // below half the smallest subnormal
  const int e = static_cast<int>(abs >> 23) - 127;
  uint32_t mant = (abs & 0x7fffffu) | 0x800000u;   // with the implicit bit
  const int shift = e >= -14 ? 13 : 13 + (-14 - e);  // subnormals lose more bits
  const uint32_t kept = mant >> shift, rest = mant & ((1u << shift) - 1), half = 1u << (shift - 1);
  uint32_t r = kept + ((rest > half || (rest == half && (kept & 1u))) ? 1u : 0u);
  if (e >= -14) {
    // Normal: r holds 11 bits (implicit bit included); a carry into bit 11 bumps the exponent.
    return sign | static_cast<uint16_t>((static_cast<uint32_t>(e + 15) << 10) + (r - 0x400u));
  }
  return sign | static_cast<uint16_t>(r);  // subnormal (r may round up into the smallest normal)
}

}  // namespace

// IEEE binary16 -> binary32, exact (subnormals, infinities and NaN included).
float half_to_float(uint16_t h) {
  const uint32_t sign = uint32_t(h & 0x8000u) << 16;
  uint32_t exp = (h >> 10) & 0x1fu, mant = h & 0x3ffu, bits;
  if (exp == 0x1f) {
    bits = sign | 0x7f800000u | (mant << 13);
  } else if (exp != 0) {
    bits = sign | ((exp + 112) << 23) | (mant << 13);
  } else if (mant == 0) {
    bits = sign;
  } else {  // subnormal: normalise the mantissa
    int e = -1;
    do {
      ++e;
      mant <<= 1;
    } while (!(mant & 0x400u));
    bits = sign | (uint32_t(112 - e) << 23) | ((mant & 0x3ffu) << 13);
  }
  return std::bit_cast<float>(bits);
}

namespace {

template <class S>
void widen_to_i64(const char* src, int64_t n, int64_t* dst) {
  for (int64_t i = 0; i < n; ++i) {
    S v;
    std::memcpy(&v, src + i * sizeof(S), sizeof(S));
    dst[i] = static_cast<int64_t>(v);
  }
}

// Converts raw little-endian bytes of `dtype` into the tensor `out` (its target dtype).
void convert(const std::string& path, const std::string& name, const std::string& dtype, const char* src,
             Tensor& out) {
  const int64_t n = out.numel();
  if (dtype == "F32" || dtype == "F64" || dtype == "I64") {
    std::memcpy(out.raw_data(), src, static_cast<size_t>(n) * dtype_size(out.dtype()));
  } else if (dtype == "F16" || dtype == "BF16") {
    float* dst = out.data<float>();
    for (int64_t i = 0; i < n; ++i) {
      uint16_t h;
      std::memcpy(&h, src + 2 * i, 2);
      dst[i] = dtype == "F16" ? half_to_float(h) : std::bit_cast<float>(uint32_t(h) << 16);
    }
  } else {
    int64_t* dst = out.data<int64_t>();
    if (dtype == "I32") widen_to_i64<int32_t>(src, n, dst);
    else if (dtype == "I16") widen_to_i64<int16_t>(src, n, dst);
    else if (dtype == "I8") widen_to_i64<int8_t>(src, n, dst);
    else if (dtype == "U32") widen_to_i64<uint32_t>(src, n, dst);
    else if (dtype == "U16") widen_to_i64<uint16_t>(src, n, dst);
    else if (dtype == "U8" || dtype == "BOOL") widen_to_i64<uint8_t>(src, n, dst);
    else if (dtype == "U64") {
      for (int64_t i = 0; i < n; ++i) {
        uint64_t v;
        std::memcpy(&v, src + 8 * i, 8);
        SL_CHECK(v <= uint64_t(std::numeric_limits<int64_t>::max()), path, ": tensor '", name,
                 "' (U64) holds ", v, ", which does not fit in I64");
        dst[i] = static_cast<int64_t>(v);
      }
    }
  }
}

// ---------------------------------------------------------------- header parsing
struct Entry {
  std::string name, dtype;
  Shape shape;
  uint64_t begin = 0, end = 0;
};

uint64_t as_u64(const std::string& path, const std::string& what, const json& v) {
  SL_CHECK(v.is_number_unsigned() || (v.is_number_integer() && v.get<int64_t>() >= 0), path, ": ", what,
           " must be a non-negative integer, got ", v.dump());
  return v.get<uint64_t>();
}

Entry parse_entry(const std::string& path, const std::string& name, const json& v) {
  const std::string where = cat("tensor '", name, "'");
  SL_CHECK(v.is_object(), path, ": ", where, " must be a JSON object, got ", v.dump().substr(0, 80));
  for (const char* key : {"dtype", "shape", "data_offsets"})
    SL_CHECK(v.contains(key), path, ": ", where, " has no \"", key, "\"");
  Entry e;
  e.name = name;
  SL_CHECK(v["dtype"].is_string(), path, ": ", where, ": dtype must be a string");
  e.dtype = v["dtype"].get<std::string>();
  const FileDType* dt = find_dtype(e.dtype);
  SL_CHECK(dt, path, ": ", where, " has dtype ", e.dtype,
           ", which this reader does not support (supported: F32 F64 F16 BF16 I64 I32 I16 I8 U64 U32 U16 U8 BOOL)");
  const json& shape = v["shape"];
  SL_CHECK(shape.is_array() && shape.size() <= 64, path, ": ", where, ": shape must be an array of at most 64 dims");
  // numel · bytes must fit comfortably in 63 bits; larger claims cannot match a real file.
  // The extent (product of max(dim, 1)) is bounded too: a zero dimension makes numel 0 but the
  // other dimensions still multiply into the tensor's strides, which must not overflow int64.
  unsigned __int128 bytes = dt->bytes, extent = 1;
  for (const json& d : shape) {
    const uint64_t s = as_u64(path, where + " shape entry", d);
    SL_CHECK(s <= (uint64_t(1) << 62), path, ": ", where, ": dimension ", s, " is too large");
    extent *= std::max<uint64_t>(s, 1);
    SL_CHECK(extent <= (unsigned __int128)(uint64_t(1) << 62), path, ": ", where, ": shape ", shape.dump(),
             " spans more than 2^62 elements");
    e.shape.push_back(static_cast<int64_t>(s));
    bytes *= s;
    if (bytes > (unsigned __int128)(uint64_t(1) << 62)) bytes = (unsigned __int128)(uint64_t(1) << 62) + 1;
  }
  const json& off = v["data_offsets"];
  SL_CHECK(off.is_array() && off.size() == 2, path, ": ", where, ": data_offsets must be [begin, end]");
  e.begin = as_u64(path, where + " data_offsets", off[0]);
  e.end = as_u64(path, where + " data_offsets", off[1]);
  SL_CHECK(e.begin <= e.end, path, ": ", where, ": data_offsets [", e.begin, ", ", e.end, "] are reversed");
  SL_CHECK((unsigned __int128)(e.end - e.begin) == bytes, path, ": ", where, ": data_offsets [", e.begin, ", ",
           e.end, "] span ", e.end - e.begin, " bytes but ", e.dtype, shape_str(e.shape), " needs ",
           (bytes > (unsigned __int128)(uint64_t(1) << 62) ? std::string("more than 2^62")
                                                           : std::to_string(uint64_t(bytes))));
  return e;
}

}  // namespace

// ---------------------------------------------------------------- writing
void write_file_atomically(const std::string& path, const std::string& bytes) {
  AtomicFile f(path);
  f.write(bytes.data(), bytes.size());
  f.commit();
}

void write_safetensors(const std::string& path, const StateDict& tensors, const Metadata& metadata,
                       const SafetensorsWriteOptions& options) {
  NoGradGuard no_grad;
  json header = json::object();
  std::vector<std::string> data;
  uint64_t offset = 0;
  for (const auto& [name, t] : tensors) {  // std::map: name order
    SL_CHECK(!name.empty() && name != "__metadata__", "write ", path, ": invalid tensor name '", name, "'");
    SL_CHECK(t.defined(), "write ", path, ": tensor '", name, "' is undefined");
    const Tensor c = t.contiguous();
    std::string bytes;
    std::string dtype = file_dtype_name(c.dtype());
    if (options.f32_as_f16 && c.dtype() == DType::F32) {
      dtype = "F16";
      bytes.resize(static_cast<size_t>(c.numel()) * 2);
      const float* src = c.data<float>();
      for (int64_t i = 0; i < c.numel(); ++i) {
        SL_CHECK(!std::isfinite(src[i]) || std::fabs(src[i]) <= 65504.0f, "write ", path, ": tensor '", name,
                 "' holds ", src[i], ", beyond the F16 range; store it as F32");
        const uint16_t h = float_to_half(src[i]);
        std::memcpy(&bytes[static_cast<size_t>(i) * 2], &h, 2);
      }
    } else {
      bytes.assign(static_cast<const char*>(c.raw_data()), static_cast<size_t>(c.numel()) * dtype_size(c.dtype()));
    }
    header[name] = {{"dtype", dtype}, {"shape", c.shape()}, {"data_offsets", {offset, offset + bytes.size()}}};
    offset += bytes.size();
    data.push_back(std::move(bytes));
  }
  if (!metadata.empty()) header["__metadata__"] = metadata;
  std::string text = header.dump();
  text.append((8 - text.size() % 8) % 8, ' ');  // keeps the data 8-byte aligned
  const uint64_t n = text.size();

  AtomicFile f(path);
  f.write(&n, 8);
  f.write(text.data(), text.size());
  for (const std::string& b : data) f.write(b.data(), b.size());
  f.commit();
}

// ---------------------------------------------------------------- reading
SafetensorsFile read_safetensors(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  SL_CHECK(in.is_open(), path, ": cannot open for reading");
  in.seekg(0, std::ios::end);
  const std::streamoff size_signed = in.tellg();
  SL_CHECK(size_signed >= 0, path, ": cannot determine the file size");
  const uint64_t size = static_cast<uint64_t>(size_signed);
  SL_CHECK(size >= 8, path, ": not a safetensors file: ", size, " bytes, shorter than the 8-byte header length");
  in.seekg(0);
  uint64_t n = 0;
  in.read(reinterpret_cast<char*>(&n), 8);
  SL_CHECK(in.good(), path, ": cannot read the header length");
  SL_CHECK(n <= kMaxSafetensorsHeaderBytes, path, ": declares a JSON header of ", n,
           " bytes, above the 100 MB limit (corrupted or not a safetensors file)");
  SL_CHECK(n <= size - 8, path, ": declares a JSON header of ", n, " bytes but only ", size - 8,
           " bytes follow (truncated file?)");
  std::string text(static_cast<size_t>(n), '\0');
  in.read(text.data(), static_cast<std::streamsize>(n));
  SL_CHECK(in.good(), path, ": cannot read the ", n, "-byte header");

  // The format nests at most 3 deep; refusing deeper input bounds the parser's work on garbage.
  json header;
  try {
    header = json::parse(text, [&](int depth, json::parse_event_t, json&) {
      if (depth > 4) fail(path, ": header JSON nests deeper than the safetensors format allows");
      return true;
    });
  } catch (const json::exception& e) {
    fail(path, ": header is not valid JSON (", e.what(), ")");
  }
  SL_CHECK(header.is_object(), path, ": header must be a JSON object, got ", header.type_name());

  SafetensorsFile out;
  std::vector<Entry> entries;
  for (auto it = header.begin(); it != header.end(); ++it) {
    if (it.key() == "__metadata__") {
      SL_CHECK(it->is_object(), path, ": __metadata__ must be an object of strings");
      for (auto m = it->begin(); m != it->end(); ++m) {
        SL_CHECK(m->is_string(), path, ": __metadata__ value of '", m.key(), "' must be a string, got ",
                 m->dump().substr(0, 80));
        out.metadata[m.key()] = m->get<std::string>();
      }
      continue;
    }
    entries.push_back(parse_entry(path, it.key(), *it));
  }

  const uint64_t data_bytes = size - 8 - n;
  std::sort(entries.begin(), entries.end(), [](const Entry& a, const Entry& b) {
    return a.begin != b.begin ? a.begin < b.begin : a.end < b.end;
  });
  const Entry* furthest = nullptr;  // the non-empty entry reaching furthest so far
  for (const Entry& e : entries) {
    SL_CHECK(e.end <= data_bytes, path, ": tensor '", e.name, "' data [", e.begin, ", ", e.end,
             ") lies beyond the ", data_bytes, " data bytes in the file (truncated file?)");
    if (e.end == e.begin) continue;
    if (furthest && e.begin < furthest->end)
      fail(path, ": tensors '", furthest->name, "' and '", e.name, "' overlap (data [", furthest->begin, ", ",
           furthest->end, ") and [", e.begin, ", ", e.end, "))");
    if (!furthest || e.end > furthest->end) furthest = &e;
  }

  std::vector<char> raw;
  for (const Entry& e : entries) {
    const FileDType* dt = find_dtype(e.dtype);
    Tensor t = Tensor::empty(e.shape, dt->target);
    raw.resize(static_cast<size_t>(e.end - e.begin));
    in.seekg(static_cast<std::streamoff>(8 + n + e.begin));
    in.read(raw.data(), static_cast<std::streamsize>(raw.size()));
    SL_CHECK(in.good() || raw.empty(), path, ": cannot read the data of tensor '", e.name, "'");
    convert(path, e.name, e.dtype, raw.data(), t);
    out.tensors.emplace(e.name, t);
    out.file_dtypes.emplace(e.name, e.dtype);
  }
  return out;
}

}  // namespace sl::nn
