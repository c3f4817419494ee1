#include "autodiff/elementwise.h"

#include <cmath>
#include <limits>

#include "autodiff/map.h"
#include "autodiff/reduce.h"
#include "autodiff/tape.h"

namespace sl {
namespace detail {

Shape broadcast_shapes_impl(const char* op, const Shape& a, const Shape& b) {
  const size_t n = std::max(a.size(), b.size());
  Shape out(n);
  for (size_t i = 0; i < n; ++i) {
    const int64_t da = i < n - a.size() ? 1 : a[i - (n - a.size())];
    const int64_t db = i < n - b.size() ? 1 : b[i - (n - b.size())];
    SL_CHECK(da == db || da == 1 || db == 1, op, ": cannot broadcast shapes ", shape_str(a),
             " and ", shape_str(b));
    out[i] = da == 1 ? db : da;
  }
  return out;
}

Shape broadcast_strides(const Tensor& t, const Shape& out_shape) {
  const size_t n = out_shape.size(), m = static_cast<size_t>(t.dim());
  Shape s(n, 0);
  for (size_t i = 0; i < m; ++i) {
    const size_t o = n - m + i;
    s[o] = t.shape()[i] == 1 ? 0 : t.strides()[i];
  }
  return s;
}

}  // namespace detail

Shape broadcast_shapes(const char* op, const Shape& a, const Shape& b) {
  return detail::broadcast_shapes_impl(op, a, b);
}

namespace {
using detail::map_n;

// Records a binary op whose gradients are elementwise functions of (g, a, b), each summed
// back to its operand's shape. da/db are generic lambdas (g, a, b) -> value.
template <class DA, class DB>
void record_binary(const char* op, const Tensor& a, const Tensor& b, const Tensor& y, DA da, DB db) {
  if (!needs_grad({a, b})) return;
  const Tensor ad = a.detach(), bd = b.detach();
  const bool ga = a.requires_grad(), gb = b.requires_grad();
  record(op, {a, b}, {y}, [=](const TensorList& g) {
    TensorList r(2);
    if (ga) r[0] = sum_to(map_n(op, da, g[0], ad, bd), ad.shape());
    if (gb) r[1] = sum_to(map_n(op, db, g[0], ad, bd), bd.shape());
    return r;
  });
}

template <class T>
constexpr T tiny() {
  return std::numeric_limits<T>::min();
}
}  // namespace

// add, sub, mul and div read in backward only the operands their derivatives need: the
// gradient of a sum passes through without a copy, and a product's factor gradient reads g and
// the other factor (two streams, not three).
template <class Backward>
void record_with(const char* op, const Tensor& a, const Tensor& b, const Tensor& y, Backward backward) {
  if (!needs_grad({a, b})) return;
  const bool ga = a.requires_grad(), gb = b.requires_grad();
  const Tensor ad = a.detach(), bd = b.detach();
  record(op, {a, b}, {y}, [=](const TensorList& g) {
    TensorList r(2);
    if (ga) r[0] = sum_to(backward(0, g[0], ad, bd), ad.shape());
    if (gb) r[1] = sum_to(backward(1, g[0], ad, bd), bd.shape());
    return r;
  });
}

Tensor add(const Tensor& a, const Tensor& b) {
  Tensor y = map_n("add", [](auto x, auto z) { return x + z; }, a, b);
  if (!needs_grad({a, b})) return y;
  const bool ga = a.requires_grad(), gb = b.requires_grad();
  const Shape sa = a.shape(), sb = b.shape();
  record("add", {a, b}, {y}, [=](const TensorList& g) {
    return TensorList{ga ? sum_to(g[0], sa) : Tensor(), gb ? sum_to(g[0], sb) : Tensor()};
  });
  return y;
}

Tensor sub(const Tensor& a, const Tensor& b) {
  Tensor y = map_n("sub", [](auto x, auto z) { return x - z; }, a, b);
  if (!needs_grad({a, b})) return y;
  const bool ga = a.requires_grad(), gb = b.requires_grad();
  const Shape sa = a.shape(), sb = b.shape();
  record("sub", {a, b}, {y}, [=](const TensorList& g) {
    return TensorList{ga ? sum_to(g[0], sa) : Tensor(), gb ? sum_to(mul_scalar(g[0], -1.0), sb) : Tensor()};
  });
  return y;
}

Tensor mul(const Tensor& a, const Tensor& b) {
  Tensor y = map_n("mul", [](auto x, auto z) { return x * z; }, a, b);
  record_with("mul", a, b, y, [](int k, const Tensor& g, const Tensor& ad, const Tensor& bd) {
    return map_n("mul", [](auto gv, auto other) { return gv * other; }, g, k == 0 ? bd : ad);
  });
  return y;
}

Tensor div(const Tensor& a, const Tensor& b) {
  Tensor y = map_n("div", [](auto x, auto z) { return x / z; }, a, b);
  record_with("div", a, b, y, [](int k, const Tensor& g, const Tensor& ad, const Tensor& bd) {
    if (k == 0) return map_n("div", [](auto gv, auto z) { return gv / z; }, g, bd);
    return map_n("div", [](auto gv, auto x, auto z) { return -gv * x / (z * z); }, g, ad, bd);
  });
  return y;
}

Tensor pow(const Tensor& a, const Tensor& b) {
  Tensor y = map_n("pow", [](auto x, auto z) { return std::pow(x, z); }, a, b);
  record_binary(
      "pow", a, b, y,
      [](auto g, auto x, auto z) { return z == 0 ? decltype(g)(0) : g * z * std::pow(x, z - 1); },
      [](auto g, auto x, auto z) { return x > 0 ? g * std::pow(x, z) * std::log(x) : decltype(g)(0); });
  return y;
}

Tensor minimum(const Tensor& a, const Tensor& b) {
  Tensor y = map_n("minimum", [](auto x, auto z) { return x < z ? x : z; }, a, b);
  record_binary(
      "minimum", a, b, y,
      [](auto g, auto x, auto z) { return x < z ? g : (x == z ? g / 2 : decltype(g)(0)); },
      [](auto g, auto x, auto z) { return z < x ? g : (x == z ? g / 2 : decltype(g)(0)); });
  return y;
}

Tensor maximum(const Tensor& a, const Tensor& b) {
  Tensor y = map_n("maximum", [](auto x, auto z) { return x > z ? x : z; }, a, b);
  record_binary(
      "maximum", a, b, y,
      [](auto g, auto x, auto z) { return x > z ? g : (x == z ? g / 2 : decltype(g)(0)); },
      [](auto g, auto x, auto z) { return z > x ? g : (x == z ? g / 2 : decltype(g)(0)); });
  return y;
}

Tensor atan2(const Tensor& y_in, const Tensor& x_in) {
  Tensor out = map_n("atan2", [](auto y, auto x) { return std::atan2(y, x); }, y_in, x_in);
  record_binary(
      "atan2", y_in, x_in, out,
      [](auto g, auto y, auto x) {
        using T = decltype(g);
        const T r2 = x * x + y * y;
        return r2 > tiny<T>() ? g * x / r2 : T(0);
      },
      [](auto g, auto y, auto x) {
        using T = decltype(g);
        const T r2 = x * x + y * y;
        return r2 > tiny<T>() ? -g * y / r2 : T(0);
      });
  return out;
}

Tensor where(const Tensor& cond, const Tensor& a, const Tensor& b) {
  Tensor c = cond.dtype() == a.dtype() ? cond : cond.to(a.dtype());
  Tensor y = map_n("where", [](auto s, auto x, auto z) { return s != 0 ? x : z; }, c, a, b);
  if (needs_grad({a, b})) {
    const bool ga = a.requires_grad(), gb = b.requires_grad();
    const Tensor cd = c.detach();
    const Shape sa = a.shape(), sb = b.shape();
    record("where", {a, b}, {y}, [=](const TensorList& g) {
      TensorList r(2);
      using detail::map_n;
      if (ga) r[0] = sum_to(map_n("where", [](auto gg, auto s) { return s != 0 ? gg : decltype(gg)(0); }, g[0], cd), sa);
      if (gb) r[1] = sum_to(map_n("where", [](auto gg, auto s) { return s != 0 ? decltype(gg)(0) : gg; }, g[0], cd), sb);
      return r;
    });
  }
  return y;
}

Tensor add_scalar(const Tensor& a, double s) {
  Tensor y = map_n("add_scalar", [s](auto x) { return x + static_cast<decltype(x)>(s); }, a);
  if (needs_grad({a})) record("add_scalar", {a}, {y}, [](const TensorList& g) { return TensorList{g[0]}; });
  return y;
}

Tensor mul_scalar(const Tensor& a, double s) {
  Tensor y = map_n("mul_scalar", [s](auto x) { return x * static_cast<decltype(x)>(s); }, a);
  if (needs_grad({a}))
    record("mul_scalar", {a}, {y}, [s](const TensorList& g) { return TensorList{mul_scalar(g[0], s)}; });
  return y;
}

Tensor rsub_scalar(double s, const Tensor& a) {
  Tensor y = map_n("rsub_scalar", [s](auto x) { return static_cast<decltype(x)>(s) - x; }, a);
  if (needs_grad({a}))
    record("rsub_scalar", {a}, {y}, [](const TensorList& g) { return TensorList{mul_scalar(g[0], -1.0)}; });
  return y;
}

#define SL_COMPARISON(NAME, EXPR)                                                  \
  Tensor NAME(const Tensor& a, const Tensor& b) {                                  \
    return map_n(#NAME, [](auto x, auto z) { return (EXPR) ? decltype(x)(1) : decltype(x)(0); }, a, b); \
  }
SL_COMPARISON(gt, x > z)
SL_COMPARISON(ge, x >= z)
SL_COMPARISON(eq, x == z)
#undef SL_COMPARISON

}  // namespace sl
