// A slow reference render kept on disk between benchmark runs, so iterating on a fast setting
// does not pay for its reference every time (streetlight-bench insert --reference-dir).
//
// Contract:
// - Fingerprint hashes (FNV-1a, 64 bit) everything a reference depends on that the caller adds:
//   tensors by dtype, shape and values, plain values by their bytes, strings by their characters.
//   The renderer's code is not hashed: the caller adds a version string that names it, and a
//   stored reference is a development aid only (final figures come from a fresh reference).
// - store_tensors() writes the tensors (as float64) atomically (util/file.h); load_tensors()
//   returns false when the file is absent, and throws sl::Error naming the file when it is
//   present but malformed or holds a different number of tensors.
#pragma once
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "autodiff/tensor.h"
#include "util/check.h"
#include "util/file.h"

namespace sl::bench {

class Fingerprint {
 public:
  void bytes(const void* p, size_t n) {
    const auto* b = static_cast<const unsigned char*>(p);
    for (size_t i = 0; i < n; ++i) h_ = (h_ ^ b[i]) * 1099511628211ull;
  }
  template <class T>
  void value(const T& v) {
    bytes(&v, sizeof v);
  }
  void text(const std::string& s) {
    value(s.size());
    bytes(s.data(), s.size());
  }
  void tensor(const Tensor& t) {
    if (!t.defined()) return text("undefined");
    value(int(t.dtype()));
    for (int64_t d = 0; d < t.dim(); ++d) value(t.size(d));
    const std::vector<double> v = t.to_vector();
    bytes(v.data(), v.size() * sizeof(double));
  }
  std::string hex() const {
    char buf[17];
    std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h_));
    return buf;
  }

 private:
  uint64_t h_ = 1469598103934665603ull;
};

inline constexpr char kReferenceMagic[8] = {'S', 'L', 'R', 'E', 'F', '0', '0', '1'};

inline void store_tensors(const std::string& path, const std::vector<Tensor>& ts) {
  std::string out(kReferenceMagic, 8);
  auto put = [&](const void* p, size_t n) { out.append(static_cast<const char*>(p), n); };
  const int64_t count = int64_t(ts.size());
  put(&count, sizeof count);
  for (const Tensor& t : ts) {
    const int64_t nd = t.dim();
    put(&nd, sizeof nd);
    for (int64_t d = 0; d < nd; ++d) {
      const int64_t s = t.size(d);
      put(&s, sizeof s);
    }
    const std::vector<double> v = t.to_vector();
    put(v.data(), v.size() * sizeof(double));
  }
  write_file_atomic(path, out);
}

inline bool load_tensors(const std::string& path, std::vector<Tensor>& ts, int64_t expected) {
  if (!std::filesystem::exists(path)) return false;
  std::ifstream f(path, std::ios::binary);
  char magic[8];
  auto get = [&](void* p, size_t n) {
    f.read(static_cast<char*>(p), std::streamsize(n));
    SL_CHECK(bool(f), "reference file ", path, " is truncated");
  };
  get(magic, 8);
  SL_CHECK(std::memcmp(magic, kReferenceMagic, 8) == 0, "reference file ", path, " is not a stored reference");
  int64_t count = 0;
  get(&count, sizeof count);
  SL_CHECK(count == expected, "reference file ", path, " holds ", count, " tensors, expected ", expected);
  ts.clear();
  for (int64_t i = 0; i < count; ++i) {
    int64_t nd = 0;
    get(&nd, sizeof nd);
    SL_CHECK(nd >= 0 && nd <= 8, "reference file ", path, ": tensor ", i, " has ", nd, " dimensions");
    Shape shape;
    int64_t n = 1;
    for (int64_t d = 0; d < nd; ++d) {
      int64_t s = 0;
      get(&s, sizeof s);
      SL_CHECK(s >= 0 && s < (int64_t(1) << 32), "reference file ", path, ": tensor ", i, " has size ", s);
      shape.push_back(s);
      n *= s;
    }
    std::vector<double> v(static_cast<size_t>(n));
    get(v.data(), v.size() * sizeof(double));
    ts.push_back(Tensor::from_vector(v, shape));
  }
  return true;
}

}  // namespace sl::bench
