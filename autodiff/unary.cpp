#include "autodiff/unary.h"

#include <cmath>

#include "autodiff/map.h"
#include "autodiff/tape.h"
#include "autodiff/vector_math.h"
#include "util/parallel.h"

namespace sl {
namespace {
using detail::map_n;

// What a backward formula reads besides the output gradient g: saving and streaming only that
// halves the memory traffic of a memory-bound backward (g and y, not g, x and y).
enum class Uses { X, Y, XY };

template <Uses U, class Bwd>
void record_unary(const char* op, const Tensor& x, const Tensor& y, Bwd bwd) {
  if (!needs_grad({x})) return;
  if constexpr (U == Uses::X) {
    const Tensor xd = x.detach();
    record(op, {x}, {y}, [=](const TensorList& g) { return TensorList{map_n(op, bwd, g[0], xd)}; });
  } else if constexpr (U == Uses::Y) {
    const Tensor yd = y.detach();
    record(op, {x}, {y}, [=](const TensorList& g) { return TensorList{map_n(op, bwd, g[0], yd)}; });
  } else {
    const Tensor xd = x.detach(), yd = y.detach();
    record(op, {x}, {y}, [=](const TensorList& g) { return TensorList{map_n(op, bwd, g[0], xd, yd)}; });
  }
}

// y = fwd(x); dx = bwd(g, x), bwd(g, y) or bwd(g, x, y) as U says. Forward and backward of each
// op sit together below.
template <Uses U, class Fwd, class Bwd>
Tensor unary(const char* op, const Tensor& x, Fwd fwd, Bwd bwd) {
  Tensor y = map_n(op, fwd, x);
  record_unary<U>(op, x, y, bwd);
  return y;
}

// Elements per parallel chunk of the vectorised paths (fixed: results never depend on threads).
constexpr int64_t kVectorGrain = 32768;

// Float32 operands go through the vectorised kernels of vector_math.h: contiguous ones in chunks
// of kVectorGrain elements, strided views (a channel slice) row by row wherever their innermost
// stride is 1. Other dtypes and rows through map_n / the scalar function with libm. Each element's
// result depends only on that element and on which of the two paths its row took, never on threads.
template <class Vec, class Scalar>
Tensor map_vm(const char* op, const Tensor& x, Vec vec, Scalar scalar) {
  if (x.dtype() != DType::F32) return map_n(op, scalar, x);
  Tensor y = Tensor::empty(x.shape(), DType::F32);
  const float* px = x.data<float>();
  float* py = y.data<float>();
  if (x.is_contiguous()) {
    parallel_for(x.numel(), kVectorGrain, [&](int64_t b, int64_t e) { vec(px + b, py + b, e - b); });
    return y;
  }
  detail::for_each_strided<2>(x.shape(), {y.strides(), x.strides()}, [&](const auto& off, int64_t n, const auto& st) {
    if (st[1] == 1) {
      vec(px + off[1], py + off[0], n);
    } else {
      for (int64_t i = 0; i < n; ++i) py[off[0] + i] = scalar(px[off[1] + i * st[1]]);
    }
  });
  return y;
}

// Same for a binary kernel dx = vec(g, x).
template <class Vec, class Scalar>
Tensor map_vm2(const char* op, const Tensor& g, const Tensor& x, Vec vec, Scalar scalar) {
  if (g.dtype() != DType::F32 || x.dtype() != DType::F32 || g.shape() != x.shape()) return map_n(op, scalar, g, x);
  Tensor y = Tensor::empty(x.shape(), DType::F32);
  const float *pg = g.data<float>(), *px = x.data<float>();
  float* py = y.data<float>();
  if (g.is_contiguous() && x.is_contiguous()) {
    parallel_for(x.numel(), kVectorGrain, [&](int64_t b, int64_t e) { vec(pg + b, px + b, py + b, e - b); });
    return y;
  }
  detail::for_each_strided<3>(x.shape(), {y.strides(), g.strides(), x.strides()},
                              [&](const auto& off, int64_t n, const auto& st) {
                                if (st[1] == 1 && st[2] == 1) {
                                  vec(pg + off[1], px + off[2], py + off[0], n);
                                } else {
                                  for (int64_t i = 0; i < n; ++i)
                                    py[off[0] + i] = scalar(pg[off[1] + i * st[1]], px[off[2] + i * st[2]]);
                                }
                              });
  return y;
}

// unary() with a vectorised float32 forward.
template <Uses U, class Vec, class Fwd, class Bwd>
Tensor unary_vm(const char* op, const Tensor& x, Vec vec, Fwd fwd, Bwd bwd) {
  Tensor y = map_vm(op, x, vec, fwd);
  record_unary<U>(op, x, y, bwd);
  return y;
}

template <class T>
T acos_grad_floor() {
  return sizeof(T) == 4 ? T(1e-6) : T(1e-12);
}
}  // namespace

#define SL_T decltype(g)

Tensor neg(const Tensor& x) {
  return unary<Uses::X>("neg", x, [](auto v) { return -v; }, [](auto g, auto) { return -g; });
}

Tensor exp(const Tensor& x) {
  return unary_vm<Uses::Y>("exp", x, vm::exp, [](auto v) { return std::exp(v); },
                           [](auto g, auto y) { return g * y; });
}

Tensor log(const Tensor& x) {
  return unary_vm<Uses::X>("log", x, vm::log, [](auto v) { return std::log(v); },
                           [](auto g, auto v) { return g / v; });
}

Tensor log1p(const Tensor& x) {
  return unary<Uses::X>("log1p", x, [](auto v) { return std::log1p(v); },
                        [](auto g, auto v) { return g / (SL_T(1) + v); });
}

Tensor expm1(const Tensor& x) {
  return unary<Uses::Y>("expm1", x, [](auto v) { return std::expm1(v); },
                        [](auto g, auto y) { return g * (y + SL_T(1)); });
}

Tensor sqrt(const Tensor& x) {
  return unary<Uses::Y>("sqrt", x, [](auto v) { return std::sqrt(v); },
                        [](auto g, auto y) { return g / (SL_T(2) * y); });
}

Tensor square(const Tensor& x) {
  return unary<Uses::X>("square", x, [](auto v) { return v * v; }, [](auto g, auto v) { return SL_T(2) * g * v; });
}

Tensor abs(const Tensor& x) {
  return unary<Uses::X>("abs", x, [](auto v) { return std::abs(v); },
                        [](auto g, auto v) { return v > 0 ? g : (v < 0 ? -g : SL_T(0)); });
}

// Backward: p·x^(p-1) with x^(p-1) vectorised in float32 (pow_vm), g multiplied after.
Tensor pow_scalar(const Tensor& x, double p) {
  const auto fwd = [p](auto v) { return std::pow(v, static_cast<decltype(v)>(p)); };
  const auto pow_vm = [](double q) {
    return [qf = static_cast<float>(q)](const float* a, float* b, int64_t n) { vm::pow(a, qf, b, n); };
  };
  Tensor y = map_vm("pow_scalar", x, pow_vm(p), fwd);
  if (needs_grad({x})) {
    const Tensor xd = x.detach();
    record("pow_scalar", {x}, {y}, [=](const TensorList& g) {
      if (p == 0.0) return TensorList{map_n("pow_scalar", [](auto gv) { return decltype(gv)(0); }, g[0])};
      if (p == 1.0) return TensorList{g[0]};
      if (p == 2.0)
        return TensorList{map_n("pow_scalar", [](auto gv, auto v) { return decltype(gv)(2) * gv * v; }, g[0], xd)};
      const Tensor xpm1 = map_vm("pow_scalar", xd, pow_vm(p - 1.0), [p](auto v) {
        return std::pow(v, static_cast<decltype(v)>(p - 1.0));
      });
      return TensorList{map_n(
          "pow_scalar", [p](auto gv, auto q) { return gv * static_cast<decltype(gv)>(p) * q; }, g[0], xpm1)};
    });
  }
  return y;
}

Tensor clamp(const Tensor& x, double lo, double hi) {
  SL_CHECK(lo <= hi, "clamp: lo ", lo, " > hi ", hi);
  return unary<Uses::X>(
      "clamp", x,
      [lo, hi](auto v) {
        using T = decltype(v);
        const T l = static_cast<T>(lo), h = static_cast<T>(hi);  // converted outside the condition
        return v < l ? l : (v > h ? h : v);
      },
      [lo, hi](auto g, auto v) {
        const SL_T l = static_cast<SL_T>(lo), h = static_cast<SL_T>(hi);
        return ((v >= l) & (v <= h)) ? g : SL_T(0);
      });
}

Tensor relu(const Tensor& x) {
  // y > 0 exactly where x > 0 (NaN gives y = 0): backward reads y, so x may be freed.
  return unary<Uses::Y>("relu", x, [](auto v) { return v > 0 ? v : decltype(v)(0); },
                        [](auto g, auto y) { return y > 0 ? g : SL_T(0); });
}

Tensor leaky_relu(const Tensor& x, double slope) {
  // Constants are converted before the condition: a conversion under a condition is an
  // operation that may trap, which GCC (trapping math) will not vectorise.
  return unary<Uses::X>(
      "leaky_relu", x,
      [slope](auto v) {
        const auto s = static_cast<decltype(v)>(slope);
        return v > 0 ? v : s * v;
      },
      [slope](auto g, auto v) {
        const auto s = static_cast<SL_T>(slope);
        return v > 0 ? g : s * g;
      });
}

Tensor elu(const Tensor& x, double alpha) {
  return unary<Uses::XY>("elu", x, [alpha](auto v) { return v > 0 ? v : static_cast<decltype(v)>(alpha) * std::expm1(v); },
               [alpha](auto g, auto v, auto y) { return v > 0 ? g : g * (y + static_cast<SL_T>(alpha)); });
}

Tensor sigmoid(const Tensor& x) {
  return unary_vm<Uses::Y>(
      "sigmoid", x, vm::sigmoid,
      [](auto v) {
        using T = decltype(v);
        if (v >= 0) return T(1) / (T(1) + std::exp(-v));
        const T e = std::exp(v);
        return e / (T(1) + e);
      },
      [](auto g, auto y) { return g * y * (SL_T(1) - y); });
}

Tensor softplus(const Tensor& x) {
  Tensor y = map_vm("softplus", x, vm::softplus,
                    [](auto v) { return (v > 0 ? v : decltype(v)(0)) + std::log1p(std::exp(-std::abs(v))); });
  if (needs_grad({x})) {
    const Tensor xd = x.detach();
    record("softplus", {x}, {y}, [=](const TensorList& g) {
      return TensorList{map_vm2("softplus", g[0], xd, vm::softplus_backward, [](auto gv, auto v) {
        using T = decltype(gv);
        const T s = v >= 0 ? T(1) / (T(1) + std::exp(-v)) : std::exp(v) / (T(1) + std::exp(v));
        return gv * s;
      })};
    });
  }
  return y;
}

Tensor tanh(const Tensor& x) {
  return unary_vm<Uses::Y>("tanh", x, vm::tanh, [](auto v) { return std::tanh(v); },
                           [](auto g, auto y) { return g * (SL_T(1) - y * y); });
}

Tensor sin(const Tensor& x) {
  return unary<Uses::X>("sin", x, [](auto v) { return std::sin(v); }, [](auto g, auto v) { return g * std::cos(v); });
}

Tensor cos(const Tensor& x) {
  return unary<Uses::X>("cos", x, [](auto v) { return std::cos(v); }, [](auto g, auto v) { return -g * std::sin(v); });
}

Tensor acos(const Tensor& x) {
  return unary<Uses::X>(
      "acos", x,
      [](auto v) {
        using T = decltype(v);
        return std::acos(v < T(-1) ? T(-1) : (v > T(1) ? T(1) : v));
      },
      [](auto g, auto v) {
        using T = SL_T;
        if (v < T(-1) || v > T(1)) return T(0);  // clamped region
        const T one_minus = std::fmax(T(1) - v * v, acos_grad_floor<T>());
        return -g / std::sqrt(one_minus);
      });
}

#undef SL_T

}  // namespace sl
