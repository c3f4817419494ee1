// streetlight-fit-demo: the smallest end-to-end use of the framework. An MLP built from nn/
// modules learns f(x, y) = sin(3x)·cos(2y) on [-1, 1]² from samples the program draws itself
// (counter-based, so a seed reproduces the run), with Adam and a warmup-then-cosine schedule.
// Progress goes to stderr; the result (initial, final and held-out loss) to stdout.
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>

#include "autodiff/ops.h"
#include "nn/lr_schedule.h"
#include "nn/modules/mlp.h"
#include "nn/optim.h"
#include "util/random.h"

namespace {

constexpr const char* kUsage = R"(usage: streetlight-fit-demo [--steps N] [--seed S] [--json] [--help]

Trains a small MLP (2 -> 64 -> 64 -> 1, tanh) to fit f(x, y) = sin(3x)·cos(2y) on [-1, 1]^2
from 1024 generated samples, with Adam and a linear-warmup + cosine learning-rate schedule.
Prints progress lines to stderr and a summary with the initial and final loss to stdout.

options:
  --steps N   optimiser steps, 1..10000000 (default 1000)
  --seed S    seed for the samples and the initial weights, a non-negative integer (default 0)
  --json      print the summary as one JSON object
  --help      show this help and exit
)";

struct Args {
  int64_t steps = 1000;
  uint64_t seed = 0;
  bool json = false;
  bool help = false;
};

template <class T>
T parse_number(const std::string& flag, const std::string& text) {
  T value{};
  const char* end = text.data() + text.size();
  const auto [p, ec] = std::from_chars(text.data(), end, value);
  SL_CHECK(ec == std::errc() && p == end && !text.empty(), flag, " expects a non-negative integer, got '", text, "'");
  return value;
}

Args parse_args(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&]() -> std::string {
      SL_CHECK(i + 1 < argc, arg, " needs a value (see --help)");
      return argv[++i];
    };
    if (arg == "--help" || arg == "-h") a.help = true;
    else if (arg == "--json") a.json = true;
    else if (arg == "--steps") a.steps = parse_number<int64_t>(arg, value());
    else if (arg == "--seed") a.seed = parse_number<uint64_t>(arg, value());
    else sl::fail("unknown argument '", arg, "' (valid: --steps N, --seed S, --json, --help)");
  }
  SL_CHECK(a.steps >= 1 && a.steps <= 10'000'000, "--steps must lie in 1..10000000, got ", a.steps);
  return a;
}

// n points uniform in [-1, 1]² and their targets sin(3x)·cos(2y).
std::pair<sl::Tensor, sl::Tensor> make_samples(int64_t n, uint64_t seed, uint64_t stream) {
  std::vector<double> xy(static_cast<size_t>(2 * n)), f(static_cast<size_t>(n));
  for (int64_t i = 0; i < n; ++i) {
    const double x = 2 * sl::uniform01(seed, stream, static_cast<uint64_t>(2 * i)) - 1;
    const double y = 2 * sl::uniform01(seed, stream, static_cast<uint64_t>(2 * i + 1)) - 1;
    xy[static_cast<size_t>(2 * i)] = x;
    xy[static_cast<size_t>(2 * i + 1)] = y;
    f[static_cast<size_t>(i)] = std::sin(3 * x) * std::cos(2 * y);
  }
  return {sl::Tensor::from_vector(xy, {n, 2}), sl::Tensor::from_vector(f, {n, 1})};
}

double mse(const sl::Tensor& pred, const sl::Tensor& target) {
  return sl::mean(sl::square(sl::sub(pred, target))).item();
}

int run(const Args& args) {
  using namespace sl;
  const auto t0 = std::chrono::steady_clock::now();
  const auto [train_x, train_y] = make_samples(1024, args.seed, 1);
  const auto [test_x, test_y] = make_samples(256, args.seed, 2);
  nn::MLP model({.widths = {2, 64, 64, 1}, .activation = "tanh", .seed = args.seed});
  nn::Adam optimizer(model.named_parameters(), {.lr = 1e-2});
  const int64_t warmup = std::min<int64_t>(50, std::max<int64_t>(1, args.steps / 10));
  const nn::WarmupLr schedule(warmup, std::make_shared<nn::CosineLr>(1e-2, std::max<int64_t>(1, args.steps - warmup), 1e-4));

  double initial = 0, last = 0;
  const int64_t report_every = std::max<int64_t>(1, args.steps / 10);
  for (int64_t step = 0; step < args.steps; ++step) {
    optimizer.set_lr(schedule.lr(step));
    optimizer.zero_grad();
    const Tensor loss = mean(square(sub(model.forward(train_x), train_y)));
    last = loss.item();
    if (step == 0) initial = last;
    if (!std::isfinite(last)) {
      std::fprintf(stderr, "error: the loss became %g at step %lld\n", last, static_cast<long long>(step));
      return 1;
    }
    backward(loss);
    optimizer.step();
    if ((step + 1) % report_every == 0 || step + 1 == args.steps)
      std::fprintf(stderr, "step %lld/%lld  loss %.6f  lr %.2e\n", static_cast<long long>(step + 1),
                   static_cast<long long>(args.steps), last, optimizer.lr());
  }
  double final_loss, test_loss;
  {
    NoGradGuard no_grad;
    final_loss = mse(model.forward(train_x), train_y);
    test_loss = mse(model.forward(test_x), test_y);
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (args.json) {
    const nlohmann::json out = {{"function", "sin(3x)*cos(2y)"}, {"steps", args.steps},
                                {"seed", args.seed},             {"parameters", model.parameter_count()},
                                {"initial_loss", initial},       {"final_loss", final_loss},
                                {"test_loss", test_loss},        {"seconds", seconds}};
    std::cout << out.dump() << "\n";
  } else {
    std::printf("fit sin(3x)*cos(2y) with a %lld-parameter MLP in %lld steps (%.2f s)\n",
                static_cast<long long>(model.parameter_count()), static_cast<long long>(args.steps), seconds);
    std::printf("initial loss %.6f  final loss %.6f  held-out loss %.6f\n", initial, final_loss, test_loss);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Args args;
  try {
    args = parse_args(argc, argv);
  } catch (const sl::Error& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  }
  if (args.help) {
    std::fputs(kUsage, stdout);
    return 0;
  }
  try {
    return run(args);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
