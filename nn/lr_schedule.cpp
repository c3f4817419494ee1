#include "nn/lr_schedule.h"

#include <algorithm>
#include <cmath>

#include "util/error.h"
#include "util/math.h"

namespace sl::nn {

namespace {
void check_rate(const char* who, double lr) {
  SL_CHECK(std::isfinite(lr) && lr >= 0, who, ": learning rate must be finite and >= 0, got ", lr);
}
}  // namespace

ConstantLr::ConstantLr(double lr) : lr_(lr) { check_rate("ConstantLr", lr); }

StepLr::StepLr(double lr, int64_t step_size, double gamma) : lr_(lr), step_size_(step_size), gamma_(gamma) {
  check_rate("StepLr", lr);
  SL_CHECK(step_size > 0 && gamma >= 0, "StepLr: step_size ", step_size, " must be > 0 and gamma ", gamma,
           " >= 0");
}

double StepLr::lr(int64_t step) const {
  return lr_ * std::pow(gamma_, double(std::max<int64_t>(step, 0) / step_size_));
}

CosineLr::CosineLr(double lr, int64_t total_steps, double min_lr) : lr_(lr), total_(total_steps), min_lr_(min_lr) {
  check_rate("CosineLr", lr);
  check_rate("CosineLr (min_lr)", min_lr);
  SL_CHECK(total_steps > 0, "CosineLr: total_steps must be > 0, got ", total_steps);
}

double CosineLr::lr(int64_t step) const {
  const double s = double(std::clamp<int64_t>(step, 0, total_));
  return min_lr_ + (lr_ - min_lr_) * 0.5 * (1.0 + std::cos(kPi * s / double(total_)));
}

WarmupLr::WarmupLr(int64_t warmup_steps, std::shared_ptr<const LrSchedule> after)
    : warmup_(warmup_steps), after_(std::move(after)) {
  SL_CHECK(warmup_steps > 0, "WarmupLr: warmup_steps must be > 0, got ", warmup_steps);
  SL_CHECK(after_ != nullptr, "WarmupLr: the schedule after warmup is null");
}

double WarmupLr::lr(int64_t step) const {
  step = std::max<int64_t>(step, 0);
  if (step < warmup_) return after_->lr(0) * double(step + 1) / double(warmup_);
  return after_->lr(step - warmup_);
}

}  // namespace sl::nn
