#include "autodiff/gradcheck.h"

#include <cmath>

#include "autodiff/ops.h"
#include "util/random.h"

namespace sl {
namespace {

double weighted_sum(const Tensor& y, const Tensor& w) {
  const Tensor yc = y.contiguous();
  const double* py = yc.data<double>();
  const double* pw = w.data<double>();
  double s = 0.0;
  for (int64_t i = 0; i < yc.numel(); ++i) s += py[i] * pw[i];
  return s;
}

// Storage offset of the i-th logical element of t.
int64_t element_offset(const Tensor& t, int64_t i) {
  int64_t off = 0;
  for (int64_t d = t.dim() - 1; d >= 0; --d) {
    off += (i % t.shape()[d]) * t.strides()[d];
    i /= t.shape()[d];
  }
  return off;
}

}  // namespace

GradcheckResult gradcheck(const std::function<Tensor(const TensorList&)>& fn, TensorList inputs, double eps,
                          double atol, double rtol) {
  GradcheckResult result;
  for (size_t k = 0; k < inputs.size(); ++k) {
    SL_CHECK(inputs[k].dtype() == DType::F64, "gradcheck: input ", k, " is ", inputs[k].describe(), "; use f64");
    SL_CHECK(inputs[k].is_leaf(), "gradcheck: input ", k, " must be a leaf");
    inputs[k].set_requires_grad(true);
    inputs[k].zero_grad();
  }
  Tensor y = fn(inputs);
  SL_CHECK(y.dtype() == DType::F64, "gradcheck: output is ", y.describe(), "; expected f64");
  const Tensor w = Tensor::uniform(y.shape(), 0.5, 1.5, 0x5eed, DType::F64);
  if (y.numel() > 0 && y.requires_grad()) backward(y, w);
  y = Tensor();

  for (size_t k = 0; k < inputs.size(); ++k) {
    Tensor& x = inputs[k];
    const Tensor analytic = x.grad().defined() ? x.grad().contiguous() : Tensor::zeros(x.shape(), DType::F64);
    double* px = x.data<double>();
    for (int64_t i = 0; i < x.numel(); ++i) {
      const int64_t off = element_offset(x, i);
      const double saved = px[off];
      double lp, lm;
      {
        NoGradGuard no_grad;
        px[off] = saved + eps;
        lp = weighted_sum(fn(inputs), w);
        px[off] = saved - eps;
        lm = weighted_sum(fn(inputs), w);
        px[off] = saved;
      }
      const double numeric = (lp - lm) / (2 * eps);
      const double a = analytic.data<double>()[i];
      const double err = std::abs(a - numeric);
      result.max_abs_error = std::max(result.max_abs_error, std::isnan(err) ? INFINITY : err);
      if (!(err <= atol + rtol * std::abs(numeric)) && result.ok) {
        result.ok = false;
        result.message = cat("input ", k, " ", x.describe(), " element ", i, ": analytic ", a, " vs numeric ",
                             numeric, " (|diff| ", err, ")");
      }
    }
    x.zero_grad();
  }
  return result;
}

}  // namespace sl
