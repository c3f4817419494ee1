// Learning-rate schedules: pure functions from a step index (0-based) to a learning rate.
//
// Contract:
// - lr(step) depends only on step, never on call history, so a run resumed from a checkpoint
//   only needs the step count. Negative steps are treated as 0.
// - ConstantLr(lr); StepLr(lr, step_size, gamma): lr·gamma^floor(step / step_size);
//   CosineLr(lr, total_steps, min_lr): min_lr + (lr − min_lr)·(1 + cos(π·min(step, T)/T))/2,
//   flat at min_lr after T; WarmupLr(warmup_steps, after): lr ramps linearly as
//   after.lr(0)·(step + 1)/warmup_steps for step < warmup_steps (so the first step already
//   moves), then after.lr(step − warmup_steps). Schedules compose: WarmupLr(100, CosineLr(...)).
// - Constructors throw sl::Error for non-positive periods, negative rates or a null `after`.
#pragma once
#include <cstdint>
#include <memory>

namespace sl::nn {

class LrSchedule {
 public:
  virtual ~LrSchedule() = default;
  virtual double lr(int64_t step) const = 0;
};

class ConstantLr : public LrSchedule {
 public:
  explicit ConstantLr(double lr);
  double lr(int64_t step) const override { return lr_; }

 private:
  double lr_;
};

class StepLr : public LrSchedule {
 public:
  StepLr(double lr, int64_t step_size, double gamma);
  double lr(int64_t step) const override;

 private:
  double lr_;
  int64_t step_size_;
  double gamma_;
};

class CosineLr : public LrSchedule {
 public:
  CosineLr(double lr, int64_t total_steps, double min_lr = 0.0);
  double lr(int64_t step) const override;

 private:
  double lr_;
  int64_t total_;
  double min_lr_;
};

class WarmupLr : public LrSchedule {
 public:
  WarmupLr(int64_t warmup_steps, std::shared_ptr<const LrSchedule> after);
  double lr(int64_t step) const override;

 private:
  int64_t warmup_;
  std::shared_ptr<const LrSchedule> after_;
};

}  // namespace sl::nn
