#include "autodiff/tensor.h"

#include <atomic>
#include <cstdlib>
#include <cstring>

#include "autodiff/buffer_cache.h"
#include "autodiff/strided.h"
#include "autodiff/tape.h"
#include "util/random.h"

namespace sl {

size_t dtype_size(DType dtype) {
  switch (dtype) {
    case DType::F32: return 4;
    case DType::F64: return 8;
    case DType::I64: return 8;
  }
  return 0;
}

const char* dtype_name(DType dtype) {
  switch (dtype) {
    case DType::F32: return "f32";
    case DType::F64: return "f64";
    case DType::I64: return "i64";
  }
  return "?";
}

int64_t shape_numel(const Shape& shape) {
  int64_t n = 1;
  for (int64_t s : shape) {
    SL_CHECK(s >= 0, "negative dimension in shape ", shape_str(shape));
    n *= s;
  }
  return n;
}

Shape contiguous_strides(const Shape& shape) {
  Shape strides(shape.size());
  int64_t s = 1;
  for (size_t d = shape.size(); d-- > 0;) {
    strides[d] = s;
    s *= std::max<int64_t>(shape[d], 1);
  }
  return strides;
}

// ---------------------------------------------------------------- Storage
static std::atomic<int64_t> g_live_bytes{0};
static std::atomic<int64_t> g_peak_bytes{0};

Storage::Storage(size_t bytes) : bytes_(bytes) {
  const Buffer b = acquire_buffer(bytes);
  data_ = b.data;
  capacity_ = b.capacity;
  if (!data_) fail("out of memory allocating ", bytes, " bytes");
  const int64_t now = g_live_bytes += static_cast<int64_t>(bytes_);
  int64_t peak = g_peak_bytes.load(std::memory_order_relaxed);
  while (now > peak && !g_peak_bytes.compare_exchange_weak(peak, now, std::memory_order_relaxed)) {
  }
}

Storage::~Storage() {
  release_buffer({data_, capacity_});
  g_live_bytes -= static_cast<int64_t>(bytes_);
}

int64_t Storage::live_bytes() { return g_live_bytes.load(); }
int64_t Storage::peak_bytes() { return g_peak_bytes.load(); }
void Storage::reset_peak_bytes() { g_peak_bytes.store(g_live_bytes.load()); }

// ---------------------------------------------------------------- factories
Tensor Tensor::empty(const Shape& shape, DType dtype) {
  Tensor t;
  t.impl_ = std::make_shared<TensorImpl>();
  const int64_t n = shape_numel(shape);
  t.impl_->storage = std::make_shared<Storage>(static_cast<size_t>(n) * dtype_size(dtype));
  t.impl_->shape = shape;
  t.impl_->strides = contiguous_strides(shape);
  t.impl_->dtype = dtype;
  return t;
}

Tensor Tensor::zeros(const Shape& shape, DType dtype) {
  Tensor t = empty(shape, dtype);
  std::memset(t.raw_data(), 0, static_cast<size_t>(t.numel()) * dtype_size(dtype));
  return t;
}

Tensor Tensor::ones(const Shape& shape, DType dtype) { return full(shape, 1.0, dtype); }

Tensor Tensor::full(const Shape& shape, double value, DType dtype) {
  Tensor t = empty(shape, dtype);
  t.fill_(value);
  return t;
}

Tensor Tensor::scalar(double value, DType dtype) { return full({}, value, dtype); }

Tensor Tensor::from_vector(const std::vector<double>& values, const Shape& shape, DType dtype) {
  SL_CHECK(static_cast<int64_t>(values.size()) == shape_numel(shape), "from_vector: ",
           values.size(), " values for shape ", shape_str(shape));
  Tensor t = empty(shape, dtype);
  const int64_t n = t.numel();
  switch (dtype) {
    case DType::F32: for (int64_t i = 0; i < n; ++i) t.data<float>()[i] = static_cast<float>(values[i]); break;
    case DType::F64: for (int64_t i = 0; i < n; ++i) t.data<double>()[i] = values[i]; break;
    case DType::I64: for (int64_t i = 0; i < n; ++i) t.data<int64_t>()[i] = static_cast<int64_t>(values[i]); break;
  }
  return t;
}

Tensor Tensor::from_indices(const std::vector<int64_t>& values, const Shape& shape) {
  SL_CHECK(static_cast<int64_t>(values.size()) == shape_numel(shape), "from_indices: ",
           values.size(), " values for shape ", shape_str(shape));
  Tensor t = empty(shape, DType::I64);
  if (!values.empty()) std::memcpy(t.raw_data(), values.data(), values.size() * sizeof(int64_t));
  return t;
}

Tensor Tensor::arange(int64_t n, DType dtype) {
  std::vector<double> v(static_cast<size_t>(n));
  for (int64_t i = 0; i < n; ++i) v[i] = static_cast<double>(i);
  return from_vector(v, {n}, dtype);
}

Tensor Tensor::uniform(const Shape& shape, double lo, double hi, uint64_t seed, DType dtype) {
  Tensor t = empty(shape, dtype);
  SL_DISPATCH_FLOAT(dtype, "uniform", [&] {
    scalar_t* p = t.data<scalar_t>();
    parallel_for(t.numel(), 65536, [&](int64_t b, int64_t e) {
      for (int64_t i = b; i < e; ++i)
        p[i] = static_cast<scalar_t>(lo + (hi - lo) * uniform01(seed, static_cast<uint64_t>(i)));
    });
  });
  return t;
}

Tensor Tensor::normal(const Shape& shape, double mean, double stddev, uint64_t seed, DType dtype) {
  Tensor t = empty(shape, dtype);
  SL_DISPATCH_FLOAT(dtype, "normal", [&] {
    scalar_t* p = t.data<scalar_t>();
    parallel_for(t.numel(), 65536, [&](int64_t b, int64_t e) {
      for (int64_t i = b; i < e; ++i)
        p[i] = static_cast<scalar_t>(mean + stddev * normal01(seed, static_cast<uint64_t>(i)));
    });
  });
  return t;
}

// ---------------------------------------------------------------- metadata
static const TensorImpl& checked(const std::shared_ptr<TensorImpl>& impl) {
  if (!impl) fail("operation on an undefined tensor");
  return *impl;
}

const Shape& Tensor::shape() const { return checked(impl_).shape; }
const Shape& Tensor::strides() const { return checked(impl_).strides; }
int64_t Tensor::offset() const { return checked(impl_).offset; }
int64_t Tensor::numel() const { return shape_numel(shape()); }
DType Tensor::dtype() const { return checked(impl_).dtype; }

int64_t Tensor::size(int64_t d) const {
  const int64_t nd = dim();
  const int64_t dd = d < 0 ? d + nd : d;
  SL_CHECK(dd >= 0 && dd < nd, "size(", d, "): tensor has shape ", shape_str(shape()));
  return shape()[static_cast<size_t>(dd)];
}

bool Tensor::is_contiguous() const {
  const Shape& sh = shape();
  const Shape& st = strides();
  int64_t expected = 1;
  for (size_t d = sh.size(); d-- > 0;) {
    if (sh[d] == 1) continue;
    if (st[d] != expected) return false;
    expected *= sh[d];
  }
  return true;
}

std::string Tensor::describe() const {
  if (!defined()) return "undefined";
  return cat(dtype_name(dtype()), shape_str(shape()));
}

void* Tensor::raw_data() const {
  const TensorImpl& t = checked(impl_);
  return static_cast<char*>(t.storage->data()) + t.offset * static_cast<int64_t>(dtype_size(t.dtype));
}

const std::shared_ptr<Storage>& Tensor::storage() const { return checked(impl_).storage; }

static double read_at(const Tensor& t, int64_t off) {
  switch (t.dtype()) {
    case DType::F32: return static_cast<const float*>(t.raw_data())[off];
    case DType::F64: return static_cast<const double*>(t.raw_data())[off];
    case DType::I64: return static_cast<double>(static_cast<const int64_t*>(t.raw_data())[off]);
  }
  return 0;
}

double Tensor::item() const {
  SL_CHECK(numel() == 1, "item(): tensor has shape ", shape_str(shape()), ", expected one element");
  int64_t off = 0;  // all indices zero
  return read_at(*this, off);
}

double Tensor::at(std::initializer_list<int64_t> index) const {
  SL_CHECK(static_cast<int64_t>(index.size()) == dim(), "at(): ", index.size(),
           " indices for shape ", shape_str(shape()));
  int64_t off = 0, d = 0;
  for (int64_t i : index) {
    SL_CHECK(i >= 0 && i < shape()[d], "at(): index ", i, " out of range for dim ", d,
             " of shape ", shape_str(shape()));
    off += i * strides()[d++];
  }
  return read_at(*this, off);
}

std::vector<double> Tensor::to_vector() const {
  Tensor c = contiguous().to(DType::F64);
  const double* p = c.data<double>();
  return std::vector<double>(p, p + c.numel());
}

std::vector<int64_t> Tensor::to_indices() const {
  SL_CHECK(dtype() == DType::I64, "to_indices(): tensor is ", describe());
  Tensor c = contiguous();
  const int64_t* p = c.data<int64_t>();
  return std::vector<int64_t>(p, p + c.numel());
}

void Tensor::fill_(double value) {
  const int64_t n = numel();
  if (n == 0) return;
  auto run = [&](auto* p, auto v) {
    detail::for_each_strided<1>(shape(), {strides()}, [&](const auto& off, int64_t cnt, const auto& st) {
      for (int64_t i = 0; i < cnt; ++i) p[off[0] + i * st[0]] = v;
    });
  };
  switch (dtype()) {
    case DType::F32: run(data<float>(), static_cast<float>(value)); break;
    case DType::F64: run(data<double>(), value); break;
    case DType::I64: run(data<int64_t>(), static_cast<int64_t>(value)); break;
  }
}

namespace {
template <class D, class S>
void strided_copy(const Tensor& dst, const Tensor& src) {
  D* pd = static_cast<D*>(dst.raw_data());
  const S* ps = static_cast<const S*>(src.raw_data());
  detail::for_each_strided<2>(dst.shape(), {dst.strides(), src.strides()},
                              [&](const auto& off, int64_t n, const auto& st) {
                                D* d = pd + off[0];
                                const S* s = ps + off[1];
                                if (st[0] == 1 && st[1] == 1) {
                                  for (int64_t i = 0; i < n; ++i) d[i] = static_cast<D>(s[i]);
                                } else {
                                  for (int64_t i = 0; i < n; ++i) d[i * st[0]] = static_cast<D>(s[i * st[1]]);
                                }
                              });
}
template <class D>
void copy_from(const Tensor& dst, const Tensor& src) {
  switch (src.dtype()) {
    case DType::F32: strided_copy<D, float>(dst, src); break;
    case DType::F64: strided_copy<D, double>(dst, src); break;
    case DType::I64: strided_copy<D, int64_t>(dst, src); break;
  }
}
}  // namespace

void Tensor::copy_(const Tensor& src) {
  SL_CHECK(shape() == src.shape(), "copy_: destination ", describe(), " and source ",
           src.describe(), " differ in shape");
  switch (dtype()) {
    case DType::F32: copy_from<float>(*this, src); break;
    case DType::F64: copy_from<double>(*this, src); break;
    case DType::I64: copy_from<int64_t>(*this, src); break;
  }
}

// ---------------------------------------------------------------- views and conversions
Tensor Tensor::make_view(const Tensor& base, Shape shape, Shape strides, int64_t offset) {
  Tensor t;
  t.impl_ = std::make_shared<TensorImpl>();
  t.impl_->storage = base.storage();
  t.impl_->shape = std::move(shape);
  t.impl_->strides = std::move(strides);
  t.impl_->offset = offset;
  t.impl_->dtype = base.dtype();
  return t;
}

Tensor Tensor::detach() const { return make_view(*this, shape(), strides(), offset()); }

Tensor Tensor::clone() const {
  Tensor out = empty(shape(), dtype());
  out.copy_(*this);
  if (needs_grad({*this}))
    record("clone", {*this}, {out}, [](const TensorList& g) { return TensorList{g[0]}; });
  return out;
}

Tensor Tensor::contiguous() const {
  if (is_contiguous()) return *this;
  return clone();
}

Tensor Tensor::to(DType target) const {
  if (target == dtype()) return *this;
  Tensor out = empty(shape(), target);
  out.copy_(*this);
  if (target != DType::I64 && needs_grad({*this})) {
    const DType source = dtype();
    record("to", {*this}, {out}, [source](const TensorList& g) { return TensorList{g[0].to(source)}; });
  }
  return out;
}

// ---------------------------------------------------------------- autograd state
bool Tensor::requires_grad() const { return impl_ && impl_->requires_grad; }

Tensor& Tensor::set_requires_grad(bool value) {
  SL_CHECK(defined(), "set_requires_grad on an undefined tensor");
  SL_CHECK(is_leaf(), "set_requires_grad: only leaves can be marked; this tensor ", describe(),
           " was produced by an op (use detach() first)");
  SL_CHECK(!value || dtype() != DType::I64, "set_requires_grad: integer tensor ", describe(),
           " cannot require grad");
  impl_->requires_grad = value;
  return *this;
}

bool Tensor::is_leaf() const { return !checked(impl_).has_producer; }

const Tensor& Tensor::grad() const { return checked(impl_).grad; }

void Tensor::set_grad(const Tensor& grad) {
  SL_CHECK(defined(), "set_grad on an undefined tensor");
  SL_CHECK(!grad.defined() || grad.shape() == shape(), "set_grad: gradient ", grad.describe(),
           " does not match tensor ", describe());
  impl_->grad = grad;
}

void Tensor::zero_grad() {
  if (impl_) impl_->grad = Tensor();
}

const std::string& Tensor::name() const { return checked(impl_).name; }

Tensor& Tensor::set_name(const std::string& name) {
  SL_CHECK(defined(), "set_name on an undefined tensor");
  impl_->name = name;
  return *this;
}

}  // namespace sl
