// The algorithms behind vector_math.h, written once over a SIMD wrapper (internal).
//
// Each ISA translation unit (vector_math_{scalar,avx2,avx512}.cpp) instantiates the one lane
// wrapper of vector_math_lanes.h at its width (V: float lanes, VD: double lanes); every function
// below is a fixed sequence of IEEE operations (fma where written, never contracted otherwise:
// these units build with -ffp-contract=off), so all levels agree bit for bit.
//
// Methods (the error bounds are stated and tested in vector_math.h):
// - exp: x = n·ln2 + r with n = round(x·log2 e), ln2 split in a 9-bit head (n·head exact) and a
//   tail; e^r by its degree-7 Taylor polynomial on |r| ≤ ln2/2 (truncation < 0.1 ulp), the last
//   step 1 + r·(...) one fma; 2^n
//   applied as two factors 2^⌊n/2⌋·2^(n-⌊n/2⌋) so the result underflows through the denormals
//   with one rounding and overflows to inf.
// - log: x = 2^e·m with m in [√½, √2] (denormals pre-scaled by 2^23); log m = log(1 + g) with
//   g = m - 1 exact, as g - (g²/2 - s·(g²/2 + R)), s = g/(2+g), R the atanh series in s² to s^10
//   (the form of fdlibm's log, so that the rounding of s only reaches small terms); e·ln2 added
//   head first.
// - tanh: |x| < atanh(½): x + x³·P(x²), P a degree-4 near-minimax fit of (tanh x - x)/x³
//   (scripts/fit_tanh_poly.py); otherwise 1 - 2/(e^{2|x|} + 1), whose result is ≥ ½ so the
//   subtraction loses nothing; the sign of x is copied.
// - sigmoid: e = e^{-|x|}; (x ≥ 0 ? 1 : e) / (1 + e), which neither overflows nor cancels.
// - softplus: max(x, 0) + log1p(e^{-|x|}), log1p(t) by the log kernel on t itself (t < √2 - 1)
//   or on (t - 1)/2 plus ln2, never rounding 1 + t.
// - pow: in double: log|x| by the same atanh series to f^13, t = p·log|x|, e^t by Taylor to
//   degree 11, rounded once to float; then the C99 special cases (zeros, infinities, NaN,
//   negative bases with integer p).
#pragma once
#include <cstdint>
#include <cstring>
#include <initializer_list>

namespace sl::vm::detail {

template <class V>
struct FloatKernels {
  using F = typename V::F;
  using M = typename V::M;

  static F exp(F x) {
    // Clamp first (NaN passes through min/max in this argument order).
    x = V::min(V::set(89.0f), V::max(V::set(-104.0f), x));
    const F magic = V::set(12582912.0f);  // 1.5·2^23: adding it rounds to an integer
    const F t = V::fma(x, V::set(1.44269502f), magic);
    const F n = V::sub(t, magic);
    F r = V::fma(n, V::set(-0.693359375f), x);
    r = V::fma(n, V::set(2.12194440e-4f), r);
    F p = V::set(1.0f / 5040.0f);
    p = V::fma(p, r, V::set(1.0f / 720.0f));
    p = V::fma(p, r, V::set(1.0f / 120.0f));
    p = V::fma(p, r, V::set(1.0f / 24.0f));
    p = V::fma(p, r, V::set(1.0f / 6.0f));
    p = V::fma(p, r, V::set(0.5f));
    p = V::fma(p, r, V::set(1.0f));
    const F y = V::fma(p, r, V::set(1.0f));
    const auto ni = V::subi(V::as_int(t), V::as_int(magic));
    const auto n1 = V::template srai<1>(ni);
    const auto n2 = V::subi(ni, n1);
    const F s1 = V::as_float(V::template slli<23>(V::addi(n1, V::seti(127))));
    const F s2 = V::as_float(V::template slli<23>(V::addi(n2, V::seti(127))));
    return V::mul(V::mul(y, s1), s2);
  }

  // ef·ln2 + log(1 + g) for g in [√½ - 1, √2 - 1], g exact: log(1+g) = g - (h - s·(h + R)) with
  // h = g²/2, s = g/(2+g), R = 2s²/3 + 2s⁴/5 + ... (= 2·atanh(s) - 2s over s, times s).
  // Rounding errors of s and h only touch the small correction terms.
  static F log1p_reduced(F g, F ef) {
    const F s = V::div(g, V::add(V::set(2.0f), g));
    const F z = V::mul(s, s);
    F R = V::set(2.0f / 11.0f);
    R = V::fma(R, z, V::set(2.0f / 9.0f));
    R = V::fma(R, z, V::set(2.0f / 7.0f));
    R = V::fma(R, z, V::set(2.0f / 5.0f));
    R = V::fma(R, z, V::set(2.0f / 3.0f));
    R = V::mul(R, z);
    const F h = V::mul(V::mul(V::set(0.5f), g), g);
    const F t = V::fma(s, V::add(h, R), V::mul(ef, V::set(-2.12194440e-4f)));
    return V::fma(ef, V::set(0.693359375f), V::sub(g, V::sub(h, t)));
  }

  static F log(F x) {
    const M tiny = V::lt(x, V::set(1.17549435e-38f));  // denormals (and ≤ 0, fixed below)
    const F xs = V::select(tiny, V::mul(x, V::set(8388608.0f)), x);
    const auto bits = V::as_int(xs);
    auto e = V::subi(V::template srai<23>(bits), V::seti(127));
    F m = V::as_float(V::ori(V::andi(bits, V::seti(0x007fffff)), V::seti(0x3f800000)));
    const M big = V::lt(V::set(1.41421356f), m);
    m = V::select(big, V::mul(m, V::set(0.5f)), m);
    F ef = V::add(V::cvt(e), V::select(big, V::set(1.0f), V::set(0.0f)));
    ef = V::sub(ef, V::select(tiny, V::set(23.0f), V::set(0.0f)));
    F r = log1p_reduced(V::sub(m, V::set(1.0f)), ef);
    const F inf = V::set(__builtin_inff());
    r = V::select(V::eq(x, V::set(0.0f)), V::set(-__builtin_inff()), r);
    r = V::select(V::lt(x, V::set(0.0f)), V::set(__builtin_nanf("")), r);
    r = V::select(V::eq(x, inf), inf, r);
    return V::select(V::isnan(x), x, r);
  }

  // log1p(t) for t in [0, 1] (or NaN): t itself below √2 - 1, else ln2 + log1p((t - 1)/2) with
  // (t - 1)/2 exact by one fma.
  static F log1p_unit(F t) {
    const M big = V::lt(V::set(0.414213538f), t);
    const F g = V::select(big, V::fma(t, V::set(0.5f), V::set(-0.5f)), t);
    return log1p_reduced(g, V::select(big, V::set(1.0f), V::set(0.0f)));
  }

  static F tanh(F x) {
    const F a = V::abs(x);
    const F z = V::mul(x, x);
    F p = V::set(-0.006279478315263987f);
    p = V::fma(p, z, V::set(0.021075159311294556f));
    p = V::fma(p, z, V::set(-0.053853098303079605f));
    p = V::fma(p, z, V::set(0.13332593441009521f));
    p = V::fma(p, z, V::set(-0.33333316445350647f));
    const F small = V::copysign(V::fma(V::mul(a, z), p, a), x);  // keeps tanh(-0) = -0
    const F e = exp(V::add(a, a));
    const F large = V::copysign(V::sub(V::set(1.0f), V::div(V::set(2.0f), V::add(e, V::set(1.0f)))), x);
    return V::select(V::lt(a, V::set(0.549306144f)), small, large);
  }

  static F sigmoid(F x) {
    const F e = exp(V::sub(V::set(0.0f), V::abs(x)));
    const F num = V::select(V::lt(x, V::set(0.0f)), e, V::set(1.0f));
    return V::div(num, V::add(V::set(1.0f), e));
  }

  static F softplus(F x) {
    const F e = exp(V::sub(V::set(0.0f), V::abs(x)));
    return V::add(V::max(V::set(0.0f), x), log1p_unit(e));
  }
};

// pow(x, p) for one scalar p (finite, non-zero: the caller handles the others), in double.
template <class VD>
struct PowKernel {
  using D = typename VD::D;
  using M = typename VD::M;
  float p;
  bool p_odd_integer, p_integer;

  D log_abs(D ax) const {  // ax > 0 finite (a float widened, so never denormal in double)
    const auto bits = VD::as_int(ax);
    auto e = VD::subi(VD::template srli<52>(bits), VD::seti(1023));
    D m = VD::as_float(VD::ori(VD::andi(bits, VD::seti(0x000fffffffffffffLL)), VD::seti(0x3ff0000000000000LL)));
    const M big = VD::lt(VD::set(1.4142135623730951), m);
    m = VD::select(big, VD::mul(m, VD::set(0.5)), m);
    // int64 → double for |e| < 2^51 by the magic-number trick (no AVX2 instruction for it).
    const D magic = VD::set(6755399441055744.0);  // 1.5·2^52
    D ef = VD::sub(VD::as_float(VD::addi(e, VD::as_int(magic))), magic);
    ef = VD::add(ef, VD::select(big, VD::set(1.0), VD::set(0.0)));
    const D f = VD::div(VD::sub(m, VD::set(1.0)), VD::add(m, VD::set(1.0)));
    const D z = VD::mul(f, f);
    D s = VD::set(1.0 / 13.0);
    for (double c : {1.0 / 11.0, 1.0 / 9.0, 1.0 / 7.0, 1.0 / 5.0, 1.0 / 3.0}) s = VD::fma(s, z, VD::set(c));
    const D f2 = VD::add(f, f);
    return VD::fma(ef, VD::set(0.69314718055994531), VD::fma(VD::mul(f2, z), s, f2));
  }

  D exp_of(D t) const {  // |t| ≤ 200
    const D magic = VD::set(6755399441055744.0);
    const D tn = VD::fma(t, VD::set(1.4426950408889634), magic);
    const D n = VD::sub(tn, magic);
    D r = VD::fma(n, VD::set(-0.69314718055994529), t);
    r = VD::fma(n, VD::set(-2.3190468138462996e-17), r);
    D q = VD::set(1.0 / 39916800.0);
    for (double c : {1.0 / 3628800.0, 1.0 / 362880.0, 1.0 / 40320.0, 1.0 / 5040.0, 1.0 / 720.0, 1.0 / 120.0,
                     1.0 / 24.0, 1.0 / 6.0, 0.5})
      q = VD::fma(q, r, VD::set(c));
    const D y = VD::add(VD::fma(q, VD::mul(r, r), r), VD::set(1.0));
    const auto ni = VD::subi(VD::as_int(tn), VD::as_int(magic));
    return VD::mul(y, VD::as_float(VD::template slli<52>(VD::addi(ni, VD::seti(1023)))));
  }

  D operator()(D x) const {
    const D ax = VD::abs(x);
    const M zero = VD::eq(ax, VD::set(0.0));
    const M inf = VD::eq(ax, VD::set(__builtin_inf()));
    const D safe = VD::select(VD::mor(zero, inf), VD::set(1.0), ax);
    D t = VD::mul(VD::set(static_cast<double>(p)), log_abs(safe));
    t = VD::min(VD::set(200.0), VD::max(VD::set(-200.0), t));
    D y = exp_of(t);
    // |x| = 0 or inf: 0 or inf by the sign of p (C99 F.9.4.4).
    const D at_zero = VD::set(p > 0 ? 0.0 : __builtin_inf());
    const D at_inf = VD::set(p > 0 ? __builtin_inf() : 0.0);
    y = VD::select(zero, at_zero, y);
    y = VD::select(inf, at_inf, y);
    if (p_odd_integer) y = VD::copysign(y, x);
    if (!p_integer) {
      const M neg_finite = VD::mand(VD::lt(x, VD::set(0.0)), VD::lt(VD::set(-__builtin_inf()), x));
      y = VD::select(neg_finite, VD::set(__builtin_nan("")), y);
    }
    return VD::select(VD::isnan(x), x, y);
  }
};

// Runs f over n floats, V::kLanes at a time; the tail goes through a padded buffer so that it
// sees exactly the same operations.
template <class V, class Fn>
inline void map_array(const float* x, float* y, int64_t n, Fn f) {
  constexpr int L = V::kLanes;
  int64_t i = 0;
  for (; i + L <= n; i += L) V::store(y + i, f(V::load(x + i)));
  if (i < n) {
    float buf[L] = {};
    std::memcpy(buf, x + i, static_cast<size_t>(n - i) * sizeof(float));
    V::store(buf, f(V::load(buf)));
    std::memcpy(y + i, buf, static_cast<size_t>(n - i) * sizeof(float));
  }
}

template <class V, class Fn>
inline void map_array2(const float* a, const float* b, float* y, int64_t n, Fn f) {
  constexpr int L = V::kLanes;
  int64_t i = 0;
  for (; i + L <= n; i += L) V::store(y + i, f(V::load(a + i), V::load(b + i)));
  if (i < n) {
    float ba[L] = {}, bb[L] = {};
    std::memcpy(ba, a + i, static_cast<size_t>(n - i) * sizeof(float));
    std::memcpy(bb, b + i, static_cast<size_t>(n - i) * sizeof(float));
    V::store(ba, f(V::load(ba), V::load(bb)));
    std::memcpy(y + i, ba, static_cast<size_t>(n - i) * sizeof(float));
  }
}

template <class VD>
inline void map_pow(const float* x, float* y, int64_t n, const PowKernel<VD>& k) {
  constexpr int L = VD::kLanes;
  int64_t i = 0;
  for (; i + L <= n; i += L) VD::store(y + i, k(VD::load(x + i)));
  if (i < n) {
    float buf[L] = {};
    std::memcpy(buf, x + i, static_cast<size_t>(n - i) * sizeof(float));
    VD::store(buf, k(VD::load(buf)));
    std::memcpy(y + i, buf, static_cast<size_t>(n - i) * sizeof(float));
  }
}

// Σ x[0..n) in double (vector_math.h sum): 32 accumulators, acc[j] the sum of x[i] for
// i ≡ j (mod 32) in index order, held as 32 / VD::kLanes vectors; then combined pairwise in one
// fixed order (j with j + 16, then + 8, + 4, + 2, + 1) and the n mod 32 tail added in order.
// Every level does the same double operations in the same order: identical bits.
template <class VD>
inline double sum_array(const float* x, int64_t n) {
  constexpr int L = VD::kLanes, K = 32 / L;
  typename VD::F acc[K];
  for (int v = 0; v < K; ++v) acc[v] = VD::set(0.0);
  int64_t i = 0;
  // No software prefetch: the hardware prefetchers follow this one stream. Prefetching 4 KB ahead
  // made the 16M-float sum (64 MB, from DRAM) 30% slower on an AMD EPYC of family 25 (2 threads,
  // scratch program, 1.21-1.31 ms against 0.88-0.98 in alternating runs) and changed nothing on
  // L3-resident arrays of 4 and 16 MB there.
  for (; i + 32 <= n; i += 32)
    for (int v = 0; v < K; ++v) acc[v] = VD::add(acc[v], VD::load(x + i + v * L));
  // a[j] += a[j + w] for w = 16, 8, …, 1: while w ≥ L whole vectors (a[j] and a[j + w] share a
  // lane), then within the first vector.
  for (int w = K / 2; w >= 1; w /= 2)
    for (int v = 0; v < w; ++v) acc[v] = VD::add(acc[v], acc[v + w]);
  double a[L];
  for (int l = 0; l < L; ++l) a[l] = acc[0][l];
  for (int w = L / 2; w >= 1; w /= 2)
    for (int j = 0; j < w; ++j) a[j] = a[j] + a[j + w];
  double total = a[0];
  for (; i < n; ++i) total = total + static_cast<double>(x[i]);
  return total;
}

// One ISA's entry points (vector_math.cpp picks a table).
struct Table {
  void (*exp)(const float*, float*, int64_t);
  void (*log)(const float*, float*, int64_t);
  void (*tanh)(const float*, float*, int64_t);
  void (*sigmoid)(const float*, float*, int64_t);
  void (*softplus)(const float*, float*, int64_t);
  void (*pow)(const float*, float*, int64_t, float p, bool p_integer, bool p_odd_integer);
  void (*softplus_backward)(const float*, const float*, float*, int64_t);
  double (*sum)(const float*, int64_t);
};

const Table& scalar_table();
const Table& avx2_table();
const Table& avx512_table();

// Defines the table of one ISA from its wrappers (expanded once per ISA unit).
#define SL_VM_DEFINE_TABLE(NAME, V, VD)                                                              \
  const Table& NAME() {                                                                              \
    static const Table table{                                                                        \
        [](const float* x, float* y, int64_t n) { map_array<V>(x, y, n, FloatKernels<V>::exp); },      \
        [](const float* x, float* y, int64_t n) { map_array<V>(x, y, n, FloatKernels<V>::log); },      \
        [](const float* x, float* y, int64_t n) { map_array<V>(x, y, n, FloatKernels<V>::tanh); },     \
        [](const float* x, float* y, int64_t n) { map_array<V>(x, y, n, FloatKernels<V>::sigmoid); },  \
        [](const float* x, float* y, int64_t n) { map_array<V>(x, y, n, FloatKernels<V>::softplus); }, \
        [](const float* x, float* y, int64_t n, float p, bool pi, bool po) {                        \
          map_pow<VD>(x, y, n, PowKernel<VD>{p, po, pi});                                            \
        },                                                                                           \
        [](const float* g, const float* x, float* dx, int64_t n) {                                   \
          map_array2<V>(g, x, dx, n, [](typename V::F gv, typename V::F xv) {                        \
            return V::mul(gv, FloatKernels<V>::sigmoid(xv));                                         \
          });                                                                                        \
        },                                                                                           \
        [](const float* x, int64_t n) { return sum_array<VD>(x, n); }};                              \
    return table;                                                                                    \
  }

}  // namespace sl::vm::detail
