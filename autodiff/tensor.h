// Tensor: a dense, row-major N-d array with shared 64-byte-aligned storage and autograd state.
//
// Contract:
// - dtypes: F32 and F64 for computation (F64 for gradient checks), I64 for indices only.
// - A Tensor is a cheap handle; copies share the same storage and autograd identity.
//   Views (reshape of contiguous data, permute, slice, expand, detach) share storage;
//   clone(), contiguous() of a non-contiguous view and to() copy.
// - Shapes have any rank (0-d scalars included) and dims may be 0.
// - Every shape or dtype mismatch throws sl::Error naming the op and both shapes or dtypes.
// - Autograd: a tensor either is a leaf (created by a factory; requires_grad is set by the
//   user) or was produced by a recorded op. Leaves that require grad accumulate .grad() over
//   backward calls until zero_grad(). See tape.h.
// - In-place writes (fill_, copy_, data<T>()) bypass the tape: use them on leaves under
//   NoGradGuard (optimisers) or on fresh tensors inside op kernels.
#pragma once
#include <cstdint>
#include <initializer_list>
#include <memory>
#include <string>
#include <vector>

#include "util/error.h"

namespace sl {

enum class DType : uint8_t { F32, F64, I64 };

size_t dtype_size(DType dtype);
const char* dtype_name(DType dtype);
template <class T>
constexpr DType dtype_of();
template <>
constexpr DType dtype_of<float>() { return DType::F32; }
template <>
constexpr DType dtype_of<double>() { return DType::F64; }
template <>
constexpr DType dtype_of<int64_t>() { return DType::I64; }

using Shape = std::vector<int64_t>;
int64_t shape_numel(const Shape& shape);
Shape contiguous_strides(const Shape& shape);

// A 64-byte aligned byte buffer (from autodiff/buffer_cache.h: buffers of 1 MiB and more are
// reused after release). live_bytes() counts every live Storage in the process (never the
// cache), which lets tests prove that memory returns to its level from before a forward pass.
class Storage {
 public:
  explicit Storage(size_t bytes);
  ~Storage();
  Storage(const Storage&) = delete;
  Storage& operator=(const Storage&) = delete;
  void* data() const { return data_; }
  size_t bytes() const { return bytes_; }
  static int64_t live_bytes();
  // Highest live_bytes() since the last reset_peak_bytes() (for memory benchmarks).
  static int64_t peak_bytes();
  static void reset_peak_bytes();

 private:
  void* data_ = nullptr;
  size_t bytes_ = 0;
  size_t capacity_ = 0;
};

struct Node;
struct TensorImpl;

class Tensor {
 public:
  Tensor() = default;

  // ---- factories (leaves, requires_grad = false)
  static Tensor empty(const Shape& shape, DType dtype = DType::F32);
  static Tensor zeros(const Shape& shape, DType dtype = DType::F32);
  static Tensor ones(const Shape& shape, DType dtype = DType::F32);
  static Tensor full(const Shape& shape, double value, DType dtype = DType::F32);
  static Tensor scalar(double value, DType dtype = DType::F32);
  static Tensor from_vector(const std::vector<double>& values, const Shape& shape,
                            DType dtype = DType::F32);
  static Tensor from_indices(const std::vector<int64_t>& values, const Shape& shape);
  static Tensor arange(int64_t n, DType dtype = DType::F32);
  // Counter-based: element i is a function of (seed, i) only.
  static Tensor uniform(const Shape& shape, double lo, double hi, uint64_t seed,
                        DType dtype = DType::F32);
  static Tensor normal(const Shape& shape, double mean, double stddev, uint64_t seed,
                       DType dtype = DType::F32);

  // ---- metadata
  bool defined() const { return impl_ != nullptr; }
  const Shape& shape() const;
  const Shape& strides() const;
  int64_t offset() const;
  int64_t dim() const { return static_cast<int64_t>(shape().size()); }
  int64_t numel() const;
  int64_t size(int64_t d) const;  // negative d counts from the end
  DType dtype() const;
  bool is_contiguous() const;
  std::string describe() const;  // "f32[2, 3]"

  // ---- data access (no autograd)
  template <class T>
  T* data() const;  // element [0,...,0] of this view; throws on dtype mismatch
  void* raw_data() const;
  const std::shared_ptr<Storage>& storage() const;
  double item() const;                               // numel must be 1
  double at(std::initializer_list<int64_t> index) const;
  std::vector<double> to_vector() const;             // logical row-major order
  std::vector<int64_t> to_indices() const;
  void fill_(double value);
  void copy_(const Tensor& src);  // same shape; any strides, any float dtypes

  // ---- differentiable conversions
  Tensor contiguous() const;  // returns *this when already contiguous
  Tensor clone() const;
  Tensor to(DType dtype) const;
  Tensor detach() const;  // shares storage; never requires grad

  // ---- autograd state (see tape.h)
  bool requires_grad() const;
  Tensor& set_requires_grad(bool value);  // leaves only
  bool is_leaf() const;
  const Tensor& grad() const;  // undefined until a backward reaches this leaf
  void set_grad(const Tensor& grad);
  void zero_grad();            // drops the gradient
  const std::string& name() const;
  Tensor& set_name(const std::string& name);

  // Internal: used by ops and the tape.
  static Tensor make_view(const Tensor& base, Shape shape, Shape strides, int64_t offset);
  const std::shared_ptr<TensorImpl>& impl() const { return impl_; }
  bool same(const Tensor& other) const { return impl_ == other.impl_; }

 private:
  std::shared_ptr<TensorImpl> impl_;
};

struct TensorImpl {
  std::shared_ptr<Storage> storage;
  Shape shape;
  Shape strides;
  int64_t offset = 0;  // in elements
  DType dtype = DType::F32;
  // autograd
  bool requires_grad = false;
  bool has_producer = false;  // produced by a recorded op (then not a leaf)
  std::weak_ptr<Node> producer;
  int output_index = 0;  // which output of the producer this is
  Tensor grad;           // leaves only
  std::string name;
};

template <class T>
T* Tensor::data() const {
  SL_CHECK(defined(), "data(): tensor is undefined");
  SL_CHECK(dtype() == dtype_of<T>(), "data<", dtype_name(dtype_of<T>()), ">(): tensor is ",
           describe());
  return static_cast<T*>(raw_data());
}

// Dispatch on a floating dtype: SL_DISPATCH_FLOAT(t.dtype(), "op", { using T = scalar_t; ... })
#define SL_DISPATCH_FLOAT(DTYPE, OPNAME, ...)                                         \
  [&] {                                                                               \
    switch (DTYPE) {                                                                  \
      case ::sl::DType::F32: {                                                        \
        using scalar_t = float;                                                       \
        return __VA_ARGS__();                                                         \
      }                                                                               \
      case ::sl::DType::F64: {                                                        \
        using scalar_t = double;                                                      \
        return __VA_ARGS__();                                                         \
      }                                                                               \
      default:                                                                        \
        ::sl::fail(OPNAME, ": expected a floating tensor, got ", ::sl::dtype_name(DTYPE)); \
    }                                                                                 \
  }()

}  // namespace sl
