#include "nn/init.h"

#include <cmath>

#include "autodiff/tape.h"
#include "util/random.h"

namespace sl::nn {

uint64_t name_stream(const std::string& name) {
  uint64_t h = 0xcbf29ce484222325ULL;
  for (unsigned char c : name) {
    h ^= c;
    h *= 0x100000001b3ULL;
  }
  return h;
}

std::pair<int64_t, int64_t> fans(const Tensor& w, const std::string& name) {
  SL_CHECK(w.defined() && w.dim() >= 1, "init of '", name, "': need a tensor with at least one dim, got ",
           w.describe());
  if (w.dim() == 1) return {w.size(0), w.size(0)};
  int64_t receptive = 1;
  for (int64_t d = 2; d < w.dim(); ++d) receptive *= w.size(d);
  return {w.size(1) * receptive, w.size(0) * receptive};
}

namespace {
thread_local bool skip_init = false;
}  // namespace

SkipInitGuard::SkipInitGuard() : previous_(skip_init) { skip_init = true; }
SkipInitGuard::~SkipInitGuard() { skip_init = previous_; }
bool init_skipped() { return skip_init; }

namespace {

template <class Draw>
void fill_with(Tensor& w, const std::string& name, Draw draw) {
  SL_CHECK(w.defined() && w.dtype() != DType::I64, "init of '", name, "': need a floating tensor, got ",
           w.describe());
  SL_CHECK(w.is_contiguous(), "init of '", name, "': tensor ", w.describe(), " is not contiguous");
  if (init_skipped()) return;  // the caller loads every parameter next (SkipInitGuard)
  NoGradGuard no_grad;
  SL_DISPATCH_FLOAT(w.dtype(), "init", [&] {
    scalar_t* p = w.data<scalar_t>();
    for (int64_t i = 0; i < w.numel(); ++i) p[i] = static_cast<scalar_t>(draw(static_cast<uint64_t>(i)));
  });
}

int64_t pick_fan(const Tensor& w, const std::string& name, FanMode mode) {
  const auto [fan_in, fan_out] = fans(w, name);
  const int64_t fan = mode == FanMode::FanIn ? fan_in : fan_out;
  SL_CHECK(fan > 0, "init of '", name, "': zero fan for shape ", shape_str(w.shape()));
  return fan;
}

double kaiming_gain(double a) { return std::sqrt(2.0 / (1.0 + a * a)); }

}  // namespace

void uniform_init(Tensor& w, double lo, double hi, uint64_t seed, const std::string& name) {
  const uint64_t stream = name_stream(name);
  fill_with(w, name, [&](uint64_t i) { return lo + (hi - lo) * uniform01(seed, stream, i); });
}

void normal_init(Tensor& w, double mean, double stddev, uint64_t seed, const std::string& name) {
  const uint64_t stream = name_stream(name);
  fill_with(w, name, [&](uint64_t i) { return mean + stddev * normal01(seed, stream, i); });
}

void kaiming_normal_init(Tensor& w, uint64_t seed, const std::string& name, double a, FanMode mode) {
  normal_init(w, 0.0, kaiming_gain(a) / std::sqrt(double(pick_fan(w, name, mode))), seed, name);
}

void kaiming_uniform_init(Tensor& w, uint64_t seed, const std::string& name, double a, FanMode mode) {
  const double bound = kaiming_gain(a) * std::sqrt(3.0 / double(pick_fan(w, name, mode)));
  uniform_init(w, -bound, bound, seed, name);
}

void xavier_normal_init(Tensor& w, uint64_t seed, const std::string& name, double gain) {
  const auto [fan_in, fan_out] = fans(w, name);
  SL_CHECK(fan_in + fan_out > 0, "init of '", name, "': zero fan for shape ", shape_str(w.shape()));
  normal_init(w, 0.0, gain * std::sqrt(2.0 / double(fan_in + fan_out)), seed, name);
}

void xavier_uniform_init(Tensor& w, uint64_t seed, const std::string& name, double gain) {
  const auto [fan_in, fan_out] = fans(w, name);
  SL_CHECK(fan_in + fan_out > 0, "init of '", name, "': zero fan for shape ", shape_str(w.shape()));
  const double bound = gain * std::sqrt(6.0 / double(fan_in + fan_out));
  uniform_init(w, -bound, bound, seed, name);
}

void default_layer_init(Tensor& weight, Tensor& bias, uint64_t seed, const std::string& prefix) {
  kaiming_uniform_init(weight, seed, prefix + "weight", std::sqrt(5.0));
  if (bias.defined()) {
    const double bound = 1.0 / std::sqrt(double(pick_fan(weight, prefix + "weight", FanMode::FanIn)));
    uniform_init(bias, -bound, bound, seed, prefix + "bias");
  }
}

void norm_affine_init(Tensor& weight, Tensor& bias) {
  weight.fill_(1.0);
  bias.fill_(0.0);
}

}  // namespace sl::nn
