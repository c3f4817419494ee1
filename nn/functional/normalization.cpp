#include "nn/functional/normalization.h"

#include <cmath>
#include <vector>

#include "autodiff/map.h"
#include "autodiff/tape.h"
#include "nn/functional/work_grain.h"
#include "util/parallel.h"

namespace sl::nn {
namespace {

// x viewed as [N, C, S]. Statistics are taken over "sets" of (n, c) rows of length S:
// batch norm has one set per channel (rows (n, c) for every n), group norm one set per
// (n, group) (rows (n, c) for c in the group). set_of(n, c) names a row's set; rows of a set are
// always visited in increasing (n, c) order, which fixes the summation order.
struct NormLayout {
  int64_t N = 0, C = 0, S = 0;
  int64_t sets = 0;
  int64_t groups = 0;     // group norm: channels per set = C / groups
  bool per_channel = false;  // batch norm
  int64_t set_of(int64_t n, int64_t c) const { return per_channel ? c : n * groups + c / (C / groups); }
  template <class F>
  void for_rows(int64_t set, F&& f) const {  // f(row index n·C + c, channel c)
    if (per_channel) {
      for (int64_t n = 0; n < N; ++n) f(n * C + set, set);
    } else {
      const int64_t n = set / groups, cg = C / groups, c0 = (set % groups) * cg;
      for (int64_t c = c0; c < c0 + cg; ++c) f(n * C + c, c);
    }
  }
  int64_t set_count() const { return per_channel ? N * S : (C / groups) * S; }
};

struct Stats {
  std::vector<double> mean, invstd, var;
};

// Eight interleaved double accumulators, combined pairwise: a summation order fixed by the data
// layout alone (never by threads) that the compiler vectorises, where one running sum would
// wait on every add.
struct LaneSum {
  double acc[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  template <class F>
  void add(int64_t n, F&& f) {
    int64_t i = 0;
    for (; i + 8 <= n; i += 8)
      for (int k = 0; k < 8; ++k) acc[k] += f(i + k);
    for (int k = 0; i < n; ++i, ++k) acc[k] += f(i);
  }
  double total() const { return ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7])); }
};

template <class T>
Stats batch_stats(const NormLayout& L, const T* x, double eps) {
  Stats st;
  st.mean.assign(L.sets, 0.0);
  st.invstd.assign(L.sets, 0.0);
  st.var.assign(L.sets, 0.0);
  const double count = static_cast<double>(L.set_count());
  parallel_for(L.sets, detail::grain_for(2 * L.set_count()), [&](int64_t k0, int64_t k1) {
    for (int64_t k = k0; k < k1; ++k) {
      LaneSum s;
      L.for_rows(k, [&](int64_t row, int64_t) {
        const T* xr = x + row * L.S;
        s.add(L.S, [xr](int64_t i) { return static_cast<double>(xr[i]); });
      });
      const double mean = s.total() / count;
      LaneSum sq;  // two passes: exact for inputs with a large common offset
      L.for_rows(k, [&](int64_t row, int64_t) {
        const T* xr = x + row * L.S;
        sq.add(L.S, [xr, mean](int64_t i) {
          const double d = static_cast<double>(xr[i]) - mean;
          return d * d;
        });
      });
      const double q = sq.total();
      st.mean[k] = mean;
      st.var[k] = q / count;
      st.invstd[k] = 1.0 / std::sqrt(q / count + eps);
    }
  });
  return st;
}

// The fused activation, applied as relu / leaky_relu apply it. The kind is a template argument
// so that the normalisation loop stays branch-free and vectorises.
template <NormActivation::Kind K, class T>
struct Act {
  T s;
  T forward(T v) const {
    if constexpr (K == NormActivation::Kind::ReLU) return v > 0 ? v : T(0);
    if constexpr (K == NormActivation::Kind::LeakyReLU) return v > 0 ? v : s * v;
    return v;
  }
};

// The gradient through the activation, from its OUTPUT y: relu's backward reads y (y > 0
// exactly where its input v > 0, NaN included), and for LeakyReLU with slope >= 0 the same
// holds (v <= 0 gives s·v <= 0), so the mask y > 0 equals leaky_relu's v > 0 and the bits
// equal those of the unfused backward.
Tensor activation_grad(const char* op, const NormActivation& act, const Tensor& g, const Tensor& y) {
  if (act.kind == NormActivation::Kind::ReLU)
    return sl::detail::map_n(op, [](auto gv, auto yv) { return yv > 0 ? gv : decltype(gv)(0); }, g, y);
  const double slope = act.slope;
  return sl::detail::map_n(
      op,
      [slope](auto gv, auto yv) {
        const auto s = static_cast<decltype(gv)>(slope);  // converted before the condition (vectorises)
        return yv > 0 ? gv : s * gv;
      },
      g, y);
}

// f(Act<K, T>{slope}) with K = kind as a compile-time constant.
template <class T, class F>
void with_act(const NormActivation& act, F&& f) {
  const T s = static_cast<T>(act.slope);
  switch (act.kind) {
    case NormActivation::Kind::None: f(Act<NormActivation::Kind::None, T>{s}); break;
    case NormActivation::Kind::ReLU: f(Act<NormActivation::Kind::ReLU, T>{s}); break;
    case NormActivation::Kind::LeakyReLU: f(Act<NormActivation::Kind::LeakyReLU, T>{s}); break;
  }
}

// y = act((x - mean) · invstd · w[c] + b[c]), plus the backward. batch_statistics says whether mean
// and invstd depend on x (training / group / instance norm) or are constants (eval mode).
Tensor normalize(const char* op, const Tensor& x_in, const NormLayout& L, Stats st, bool batch_statistics,
                 const Tensor& w_in, const Tensor& b_in, NormActivation act) {
  SL_CHECK(act.kind != NormActivation::Kind::LeakyReLU || act.slope >= 0, op,
           ": a fused LeakyReLU needs a slope >= 0, got ", act.slope);
  const bool fused = act.kind != NormActivation::Kind::None;
  const Tensor x = x_in.detach().contiguous();
  const Tensor w = w_in.defined() ? w_in.detach().contiguous() : Tensor();
  const Tensor b = b_in.defined() ? b_in.detach().contiguous() : Tensor();
  Tensor y = Tensor::empty(x.shape(), x.dtype());
  SL_DISPATCH_FLOAT(x.dtype(), op, [&] {
    using T = scalar_t;
    const T* px = x.data<T>();
    const T* pw = w.defined() ? w.data<T>() : nullptr;
    const T* pb = b.defined() ? b.data<T>() : nullptr;
    T* py = y.data<T>();
    with_act<T>(act, [&](const auto a) {
      parallel_for(L.N * L.C, detail::grain_for(L.S), [&](int64_t r0, int64_t r1) {
        for (int64_t row = r0; row < r1; ++row) {
          const int64_t n = row / L.C, c = row % L.C, k = L.set_of(n, c);
          const T scale = static_cast<T>(st.invstd[k] * (pw ? static_cast<double>(pw[c]) : 1.0));
          const T shift = static_cast<T>((pb ? static_cast<double>(pb[c]) : 0.0) - st.mean[k] * static_cast<double>(scale));
          const T* xr = px + row * L.S;
          T* yr = py + row * L.S;
          const auto f = a;  // a local copy: known not to alias yr, so the loop vectorises
          for (int64_t i = 0; i < L.S; ++i) yr[i] = f.forward(xr[i] * scale + shift);
        }
      });
    });
  });
  if (!needs_grad({x_in, w_in, b_in})) return y;
  const bool gx = x_in.requires_grad(), gw = w_in.defined() && w_in.requires_grad();
  const bool gb = b_in.defined() && b_in.requires_grad();
  const Tensor y_saved = fused ? y.detach() : Tensor();  // the activation's mask (shares y's storage)
  record(op, {x_in, w_in, b_in}, {y}, [=](const TensorList& grads) {
    // The gradient through the activation first, in one vectorised pass (the activation's
    // own backward, as its unfused op computes it), then the normalisation's backward.
    const Tensor dy = fused ? activation_grad(op, act, grads[0], y_saved) : grads[0].contiguous();
    TensorList r(3);
    SL_DISPATCH_FLOAT(x.dtype(), op, [&] {
      using T = scalar_t;
      const T* px = x.data<T>();
      const T* pdy = dy.data<T>();
      const T* pw = w.defined() ? w.data<T>() : nullptr;
      // One pass gives each (n, c) row's Σ dy and Σ dy·(x - mean); the weight, bias and input
      // gradients are all combinations of these sums, in a fixed order.
      const int64_t rows = L.N * L.C;
      std::vector<double> row_dy(static_cast<size_t>(rows)), row_dyx(static_cast<size_t>(rows));
      const bool need_sums = gw || gb || batch_statistics;  // eval mode's dx needs none
      parallel_for(need_sums ? rows : 0, detail::grain_for(2 * L.S), [&](int64_t r0, int64_t r1) {
        for (int64_t row = r0; row < r1; ++row) {
          const T* xr = px + row * L.S;
          const T* gr = pdy + row * L.S;
          const double mean = st.mean[L.set_of(row / L.C, row % L.C)];
          LaneSum sdy, sdyx;
          sdy.add(L.S, [gr](int64_t i) { return static_cast<double>(gr[i]); });
          sdyx.add(L.S, [gr, xr, mean](int64_t i) { return static_cast<double>(gr[i]) * (static_cast<double>(xr[i]) - mean); });
          row_dy[row] = sdy.total();
          row_dyx[row] = sdyx.total();
        }
      });
      if (gw || gb) {  // per channel, rows in increasing n: a fixed order
        Tensor dw = Tensor::empty({L.C}, x.dtype()), db = Tensor::empty({L.C}, x.dtype());
        T* pdw = dw.data<T>();
        T* pdb = db.data<T>();
        for (int64_t c = 0; c < L.C; ++c) {
          double sw = 0, sb = 0;
          for (int64_t n = 0; n < L.N; ++n) {
            sw += row_dyx[n * L.C + c] * st.invstd[L.set_of(n, c)];
            sb += row_dy[n * L.C + c];
          }
          pdw[c] = static_cast<T>(sw);
          pdb[c] = static_cast<T>(sb);
        }
        if (gw) r[1] = dw;
        if (gb) r[2] = db;
      }
      if (gx) {
        // With g = dy·w: dx = invstd · (g - mean(g) - xhat · mean(g · xhat)) for batch statistics,
        // in double and rounded once.
        std::vector<double> mg(static_cast<size_t>(L.sets), 0.0), mgx(static_cast<size_t>(L.sets), 0.0);
        if (batch_statistics) {
          const double inv_count = 1.0 / static_cast<double>(L.set_count());
          for (int64_t k = 0; k < L.sets; ++k) {
            double sg = 0, sgx = 0;
            L.for_rows(k, [&](int64_t row, int64_t c) {
              const double wc = pw ? static_cast<double>(pw[c]) : 1.0;
              sg += wc * row_dy[row];
              sgx += wc * row_dyx[row];
            });
            mg[k] = sg * inv_count;
            mgx[k] = sgx * st.invstd[k] * inv_count;
          }
        }
        Tensor dx = Tensor::empty(x.shape(), x.dtype());
        T* pdx = dx.data<T>();
        parallel_for(rows, detail::grain_for(L.S), [&](int64_t r0, int64_t r1) {
          for (int64_t row = r0; row < r1; ++row) {
            const int64_t c = row % L.C, k = L.set_of(row / L.C, c);
            const double invstd = st.invstd[k], wc = pw ? static_cast<double>(pw[c]) : 1.0;
            const double mean = st.mean[k], mgk = mg[k], mgxk = mgx[k];
            const T* xr = px + row * L.S;
            const T* gr = pdy + row * L.S;
            T* dr = pdx + row * L.S;
            for (int64_t i = 0; i < L.S; ++i) {
              const double xhat = (static_cast<double>(xr[i]) - mean) * invstd;
              dr[i] = static_cast<T>(invstd * (static_cast<double>(gr[i]) * wc - mgk - xhat * mgxk));
            }
          }
        });
        r[0] = dx;
      }
    });
    return r;
  });
  return y;
}

void check_affine(const char* op, const Tensor& x, const Tensor& t, const char* what) {
  if (!t.defined()) return;
  SL_CHECK(t.dim() == 1 && t.size(0) == x.size(1), op, ": ", what, " ", shape_str(t.shape()), " must be [",
           x.size(1), "] for input ", shape_str(x.shape()));
  SL_CHECK(t.dtype() == x.dtype(), op, ": dtypes differ: input ", x.describe(), ", ", what, " ", t.describe());
}

NormLayout layout_of(const Tensor& x) {
  NormLayout L;
  L.N = x.size(0);
  L.C = x.size(1);
  L.S = 1;
  for (int64_t d = 2; d < x.dim(); ++d) L.S *= x.size(d);
  return L;
}

}  // namespace

Tensor batch_norm(const Tensor& x, const Tensor& running_mean, const Tensor& running_var, const Tensor& weight,
                  const Tensor& bias, bool training, double momentum, double eps, NormActivation act) {
  const char* op = "batch_norm";
  SL_CHECK(x.defined() && x.dim() >= 2, op, ": input must be [N, C, ...], got ",
           x.defined() ? x.describe() : "undefined");
  SL_CHECK(x.dtype() != DType::I64, op, ": expected a floating tensor, got ", x.describe());
  check_affine(op, x, weight, "weight");
  check_affine(op, x, bias, "bias");
  check_affine(op, x, running_mean, "running_mean");
  check_affine(op, x, running_var, "running_var");
  SL_CHECK(training || (running_mean.defined() && running_var.defined()), op,
           ": eval mode needs running_mean and running_var");
  NormLayout L = layout_of(x);
  L.per_channel = true;
  L.sets = L.C;
  Stats st;
  const Tensor xc = x.detach().contiguous();
  if (training) {
    SL_CHECK(L.set_count() > 1, op, ": training needs more than one value per channel, got input ",
             shape_str(x.shape()));
    SL_DISPATCH_FLOAT(x.dtype(), op, [&] { st = batch_stats<scalar_t>(L, xc.data<scalar_t>(), eps); });
    if (running_mean.defined() && running_var.defined()) {
      const double unbias = static_cast<double>(L.set_count()) / static_cast<double>(L.set_count() - 1);
      std::vector<double> rm = running_mean.to_vector(), rv = running_var.to_vector();
      for (int64_t c = 0; c < L.C; ++c) {
        rm[c] = (1 - momentum) * rm[c] + momentum * st.mean[c];
        rv[c] = (1 - momentum) * rv[c] + momentum * st.var[c] * unbias;
      }
      NoGradGuard no_grad;
      Tensor(running_mean).copy_(Tensor::from_vector(rm, {L.C}, DType::F64));  // handles share storage
      Tensor(running_var).copy_(Tensor::from_vector(rv, {L.C}, DType::F64));
    }
  } else {
    st.mean = running_mean.to_vector();
    st.var = running_var.to_vector();
    st.invstd.resize(static_cast<size_t>(L.C));
    for (int64_t c = 0; c < L.C; ++c) st.invstd[c] = 1.0 / std::sqrt(std::max(st.var[c], 0.0) + eps);
  }
  return normalize(op, x, L, std::move(st), training, weight, bias, act);
}

namespace {
Tensor group_norm_as(const char* op, const Tensor& x, int64_t groups, const Tensor& weight, const Tensor& bias,
                     double eps, NormActivation act) {
  SL_CHECK(x.defined() && x.dim() >= 2, op, ": input must be [N, C, ...], got ",
           x.defined() ? x.describe() : "undefined");
  SL_CHECK(groups >= 1 && x.size(1) % groups == 0, op, ": ", x.size(1), " channels of input ",
           shape_str(x.shape()), " do not split into ", groups, " groups");
  check_affine(op, x, weight, "weight");
  check_affine(op, x, bias, "bias");
  NormLayout L = layout_of(x);
  L.groups = groups;
  L.sets = L.N * groups;
  Stats st;
  const Tensor xc = x.detach().contiguous();
  SL_DISPATCH_FLOAT(x.dtype(), op, [&] { st = batch_stats<scalar_t>(L, xc.data<scalar_t>(), eps); });
  return normalize(op, x, L, std::move(st), true, weight, bias, act);
}
}  // namespace

Tensor group_norm(const Tensor& x, int64_t groups, const Tensor& weight, const Tensor& bias, double eps,
                  NormActivation act) {
  return group_norm_as("group_norm", x, groups, weight, bias, eps, act);
}

// Instance norm is group norm with one channel per group.
Tensor instance_norm(const Tensor& x, const Tensor& weight, const Tensor& bias, double eps, NormActivation act) {
  SL_CHECK(x.defined() && x.dim() >= 3, "instance_norm: input must be [N, C, spatial...], got ",
           x.defined() ? x.describe() : "undefined");
  return group_norm_as("instance_norm", x, x.size(1), weight, bias, eps, act);
}

}  // namespace sl::nn
