// Wall time of the phases of one training step (streetlight-bench train-step, metrics.jsonl).
#pragma once
#include <chrono>

namespace sl::train {

// Milliseconds between successive lap() calls (the first from construction).
class PhaseClock {
 public:
  double lap() {
    const auto now = std::chrono::steady_clock::now();
    const double ms = std::chrono::duration<double, std::milli>(now - last_).count();
    last_ = now;
    return ms;
  }

 private:
  std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
};

}  // namespace sl::train
