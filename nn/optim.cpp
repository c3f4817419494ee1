#include "nn/optim.h"

#include <algorithm>
#include <cmath>

#include "autodiff/tape.h"
#include "util/parallel.h"

namespace sl::nn {

namespace {
constexpr int64_t kGrain = 1 << 14;  // elements per parallel chunk; updates are independent
}

// ---------------------------------------------------------------- Optimizer
Optimizer::Optimizer(std::string type_name, NamedTensors params, double lr, std::vector<std::string> slots)
    : type_name_(std::move(type_name)), params_(std::move(params)), slot_names_(std::move(slots)) {
  set_lr(lr);
  for (const auto& [name, p] : params_) {
    SL_CHECK(p.defined() && p.dtype() != DType::I64, type_name_, ": parameter '", name,
             "' must be a floating tensor, got ", p.describe());
    SL_CHECK(p.is_leaf() && p.is_contiguous(), type_name_, ": parameter '", name,
             "' must be a contiguous leaf, got ", p.describe());
  }
  state_.resize(slot_names_.size());
  for (auto& slot : state_)
    for (const auto& [name, p] : params_) slot.push_back(Tensor::zeros(p.shape(), p.dtype()));
  for (size_t i = 0; i < params_.size(); ++i) steps_.push_back(Tensor::zeros({}, DType::I64));
  lr_scale_.assign(params_.size(), 1.0);
}

void Optimizer::set_lr_scale(const std::string& prefix, double scale) {
  SL_CHECK(std::isfinite(scale) && scale > 0, type_name_, ": the learning-rate scale of '", prefix,
           "' must be finite and > 0, got ", scale);
  bool any = false;
  for (size_t i = 0; i < params_.size(); ++i)
    if (params_[i].first.rfind(prefix, 0) == 0) lr_scale_[i] = scale, any = true;
  SL_CHECK(any, type_name_, ": no parameter's name starts with '", prefix, "'");
}

void Optimizer::set_lr(double lr) {
  SL_CHECK(std::isfinite(lr) && lr >= 0, type_name_, ": learning rate must be finite and >= 0, got ", lr);
  lr_ = lr;
}

void Optimizer::step() {
  NoGradGuard no_grad;
  for (size_t i = 0; i < params_.size(); ++i) {
    const Tensor& p = params_[i].second;
    if (!p.grad().defined()) continue;
    Tensor g = p.grad().contiguous();
    if (g.dtype() != p.dtype()) g = g.to(p.dtype());
    int64_t& t = steps_[i].data<int64_t>()[0];
    ++t;
    update(i, g, t);
    if (averaging()) update_average(i, t);
  }
}

void Optimizer::enable_average(double decay) {
  SL_CHECK(std::isfinite(decay) && decay > 0 && decay < 1, type_name_, ": average decay must lie in (0, 1), got ", decay);
  SL_CHECK(!averaging(), type_name_, ": weight averaging is already on");
  average_decay_ = decay;
  average_slot_ = slot_names_.size();
  slot_names_.push_back("average");
  state_.emplace_back();
  for (const auto& [name, p] : params_) state_.back().push_back(Tensor::zeros(p.shape(), p.dtype()));
}

void Optimizer::update_average(size_t i, int64_t t) {
  const Tensor& p = params_[i].second;
  Tensor& a = state_[average_slot_][i];
  const double d = t == 1 ? 0.0 : std::min(average_decay_, (1.0 + double(t)) / (10.0 + double(t)));
  SL_DISPATCH_FLOAT(p.dtype(), "weight average", [&] {
    using T = scalar_t;
    const T* pp = p.data<T>();
    T* pa = a.data<T>();
    parallel_for(p.numel(), kGrain, [&](int64_t b, int64_t e) {
      for (int64_t k = b; k < e; ++k) pa[k] = T(d * double(pa[k]) + (1.0 - d) * double(pp[k]));
    });
  });
}

void Optimizer::swap_average() {
  SL_CHECK(averaging(), type_name_, ".swap_average: weight averaging is off");
  NoGradGuard no_grad;
  for (size_t i = 0; i < params_.size(); ++i) {
    if (steps_[i].data<int64_t>()[0] == 0) continue;
    const Tensor& p = params_[i].second;
    Tensor& a = state_[average_slot_][i];
    SL_DISPATCH_FLOAT(p.dtype(), "swap_average", [&] {
      std::swap_ranges(p.data<scalar_t>(), p.data<scalar_t>() + p.numel(), a.data<scalar_t>());
    });
  }
}

void Optimizer::zero_grad() {
  for (auto& [name, p] : params_) p.zero_grad();
}

StateDict Optimizer::state_dict() const {
  StateDict out;
  for (size_t i = 0; i < params_.size(); ++i) {
    const std::string& name = params_[i].first;
    for (size_t s = 0; s < slot_names_.size(); ++s) out.emplace(slot_names_[s] + "." + name, state_[s][i]);
    out.emplace("step." + name, steps_[i]);
  }
  return out;
}

void Optimizer::load_state_dict(const StateDict& state) {
  StateDict own = state_dict();
  const StateMismatch m = compare_state(own, state);
  SL_CHECK(m.empty(), type_name_, ".load_state_dict: ", m.message());
  for (auto& [name, t] : own) t.copy_(state.at(name));
}

// ---------------------------------------------------------------- SGD
SGD::SGD(NamedTensors params, SgdOptions options)
    : Optimizer("SGD", std::move(params), options.lr,
                options.momentum > 0 ? std::vector<std::string>{"momentum_buffer"} : std::vector<std::string>{}),
      opt_(options) {
  SL_CHECK(options.momentum >= 0 && options.weight_decay >= 0, "SGD: momentum ", options.momentum,
           " and weight_decay ", options.weight_decay, " must be >= 0");
  SL_CHECK(!options.nesterov || (options.momentum > 0 && options.dampening == 0),
           "SGD: nesterov needs momentum > 0 and dampening 0");
}

void SGD::update(size_t i, const Tensor& g, int64_t t) {
  const Tensor& p = params()[i].second;
  const double lr = lr_of(i), wd = opt_.weight_decay, mu = opt_.momentum, damp = opt_.dampening;
  const bool nesterov = opt_.nesterov, first = t == 1;
  Tensor buf = mu > 0 ? slot(0, i) : Tensor();
  SL_DISPATCH_FLOAT(p.dtype(), "SGD", [&] {
    using T = scalar_t;
    T* pp = p.data<T>();
    const T* pg = g.data<T>();
    T* pb = mu > 0 ? buf.data<T>() : nullptr;
    parallel_for(p.numel(), kGrain, [&](int64_t b, int64_t e) {
      for (int64_t k = b; k < e; ++k) {
        double d = double(pg[k]) + wd * double(pp[k]);
        if (pb) {
          const double m = first ? d : mu * double(pb[k]) + (1.0 - damp) * d;
          pb[k] = T(m);
          d = nesterov ? d + mu * m : m;
        }
        pp[k] = T(double(pp[k]) - lr * d);
      }
    });
  });
}

// ---------------------------------------------------------------- Adam / AdamW
Adam::Adam(NamedTensors params, AdamOptions options) : Adam("Adam", std::move(params), options, false) {}

Adam::Adam(std::string name, NamedTensors params, AdamOptions options, bool decoupled)
    : Optimizer(std::move(name), std::move(params), options.lr, {"exp_avg", "exp_avg_sq"}),
      opt_(options),
      decoupled_(decoupled) {
  SL_CHECK(options.beta1 >= 0 && options.beta1 < 1 && options.beta2 >= 0 && options.beta2 < 1,
           type_name(), ": betas must lie in [0, 1), got (", options.beta1, ", ", options.beta2, ")");
  SL_CHECK(options.eps > 0 && options.weight_decay >= 0, type_name(), ": eps ", options.eps,
           " must be > 0 and weight_decay ", options.weight_decay, " >= 0");
}

void Adam::update(size_t i, const Tensor& g, int64_t t) {
  const Tensor& p = params()[i].second;
  const double lr = lr_of(i), wd = opt_.weight_decay, b1 = opt_.beta1, b2 = opt_.beta2, eps = opt_.eps;
  const double bc1 = 1.0 - std::pow(b1, double(t));
  const double sqrt_bc2 = std::sqrt(1.0 - std::pow(b2, double(t)));
  const double step_size = lr / bc1;
  const double decay = decoupled_ ? 1.0 - lr * wd : 1.0;
  const double l2 = decoupled_ ? 0.0 : wd;
  Tensor m = slot(0, i), v = slot(1, i);
  SL_DISPATCH_FLOAT(p.dtype(), "Adam", [&] {
    using T = scalar_t;
    T* pp = p.data<T>();
    const T* pg = g.data<T>();
    T* pm = m.data<T>();
    T* pv = v.data<T>();
    parallel_for(p.numel(), kGrain, [&](int64_t b, int64_t e) {
      for (int64_t k = b; k < e; ++k) {
        const double param = double(pp[k]) * decay;
        const double d = double(pg[k]) + l2 * double(pp[k]);
        const double mk = b1 * double(pm[k]) + (1.0 - b1) * d;
        const double vk = b2 * double(pv[k]) + (1.0 - b2) * d * d;
        pm[k] = T(mk);
        pv[k] = T(vk);
        pp[k] = T(param - step_size * mk / (std::sqrt(vk) / sqrt_bc2 + eps));
      }
    });
  });
}

AdamW::AdamW(NamedTensors params, AdamOptions options) : Adam("AdamW", std::move(params), options, true) {}

// ---------------------------------------------------------------- clipping
double clip_grad_norm(const std::vector<Tensor>& params, double max_norm) {
  SL_CHECK(max_norm > 0, "clip_grad_norm: max_norm must be > 0, got ", max_norm);
  double sq = 0.0;
  for (const Tensor& p : params) {
    if (!p.defined() || !p.grad().defined()) continue;
    const Tensor g = p.grad().contiguous();
    SL_DISPATCH_FLOAT(g.dtype(), "clip_grad_norm", [&] {
      const scalar_t* pg = g.data<scalar_t>();
      sq += deterministic_sum(g.numel(), [&](int64_t k) { return double(pg[k]) * double(pg[k]); });
    });
  }
  const double norm = std::sqrt(sq);
  if (!std::isfinite(norm)) return norm;
  const double coef = max_norm / (norm + 1e-6);
  if (coef >= 1.0) return norm;
  NoGradGuard no_grad;
  for (const Tensor& p : params) {
    if (!p.defined() || !p.grad().defined()) continue;
    Tensor g = p.grad().contiguous();
    SL_DISPATCH_FLOAT(g.dtype(), "clip_grad_norm", [&] {
      scalar_t* pg = g.data<scalar_t>();
      const int64_t n = g.numel();  // once: numel() walks the shape on every call
      for (int64_t k = 0; k < n; ++k) pg[k] = scalar_t(double(pg[k]) * coef);
    });
    Tensor handle = p;  // shares autograd state with p
    handle.set_grad(g);
  }
  return norm;
}

double clip_grad_norm(const NamedTensors& params, double max_norm) {
  std::vector<Tensor> list;
  for (const auto& [name, p] : params) list.push_back(p);
  return clip_grad_norm(list, max_norm);
}

}  // namespace sl::nn
