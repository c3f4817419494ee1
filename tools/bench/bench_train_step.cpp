// streetlight-bench train-step: the wall time of one training step of any stage, split by phase
// (data, forward, renderer, backward, optimizer), from the same JSON config streetlight-train
// takes. It builds the stage exactly as the trainer does (train/trainer.h make_stage), runs its
// initialise() and `--warmup` steps, then reports the mean of `--steps` steps with the 95%
// interval of that mean and the fastest and slowest step. Steps differ: a lighting batch may or
// may not hold real crops, so 5 steps could mislead by 10-20% (2026-11-26: width 48 read 503 ms
// over 5 steps and 584 ms over 30, against 587 ms per step in the real run); the default is 20.
// "data" is the time a step WAITS for its batch: the lighting stages build the next batch in the
// background.
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>

#include "tools/bench/bench.h"
#include "tools/common/cli.h"
#include "tools/common/config.h"
#include "train/trainer.h"
#include "train/train_config.h"

namespace sl::bench {
namespace {

int run_train_step(const std::vector<std::string>& args) {
  bool json = false;
  int64_t steps = 20, warmup = 2;
  std::string config_file;
  std::vector<std::string> sets;
  for (size_t i = 0; i < args.size(); ++i) {
    if (args[i] == "--json") json = true;
    else if (args[i] == "--config" && i + 1 < args.size()) config_file = args[++i];
    else if (args[i] == "--set" && i + 1 < args.size()) sets.push_back(args[++i]);
    else if (args[i] == "--steps" && i + 1 < args.size()) steps = cli::parse_integer("train-step: --steps", args[++i], 1, 1'000'000);
    else if (args[i] == "--warmup" && i + 1 < args.size()) warmup = cli::parse_integer("train-step: --warmup", args[++i], 0, 1'000'000);
    else if (args[i] == "--help" || args[i] == "-h") {
      std::fputs("usage: streetlight-bench train-step --config FILE.json [--set key=value ...] [--steps N] [--warmup N] [--json]\n"
                 "  Mean wall time of one training step of the config's stage, split into data (waiting for the batch),\n"
                 "  forward, renderer (stage 3's insertion), backward and optimizer, with the 95% interval of the mean and the\n"
                 "  fastest and slowest step. Default 20 steps after 2 warm-up steps. The decoded-sample cache\n"
                 "  (data.cache_mb) fills during the first epoch, so on a dataset larger than (warm-up + steps) x batch\n"
                 "  this times first-epoch steps; --set data.cache_mb=0 times every step's decoding.\n",
                 stdout);
      return 0;
    } else {
      fail("train-step: unknown option '", args[i], "' (try --help)");
    }
  }
  SL_CHECK(!config_file.empty(), "train-step: --config FILE.json is required");
  cli::Config config(train::default_train_config());
  config.merge_file(config_file);
  for (const auto& s : sets) config.set(s);
  train::check_train_config(config.tree());
  auto stage = train::make_stage(config.tree());
  stage->initialise();
  const double lr = config.tree().at("optim").at("lr").get<double>();
  stage->set_lr(lr);
  for (int64_t s = 0; s < warmup; ++s) stage->step(s);
  std::map<std::string, double> sum;
  std::vector<double> totals;
  for (int64_t s = 0; s < steps; ++s) {
    const auto t0 = std::chrono::steady_clock::now();
    const train::Metrics m = stage->step(warmup + s);
    totals.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    sum["total"] += totals.back();
    for (const char* k : {"time_data_ms", "time_forward_ms", "time_render_ms", "time_backward_ms", "time_optimizer_ms"})
      if (auto it = m.find(k); it != m.end()) sum[k] += it->second;
  }
  const double n = static_cast<double>(steps);
  auto get = [&](const char* k) { return sum.count(k) ? sum[k] / n : 0.0; };
  const double mean = get("total");
  double var = 0.0;
  for (double t : totals) var += (t - mean) * (t - mean);
  const double ci95 = steps > 1 ? 1.96 * std::sqrt(var / (n - 1) / n) : 0.0;
  const auto [lo, hi] = std::minmax_element(totals.begin(), totals.end());
  const int64_t batch = config.tree().at("train").at("batch_size").get<int64_t>();
  if (json) {
    std::printf("{\"bench\": \"train_step\", \"stage\": \"%s\", \"batch\": %lld, \"threads\": %d, \"steps\": %lld, "
                "\"ms\": %.1f, \"ms_ci95\": %.1f, \"ms_min\": %.1f, \"ms_max\": %.1f, \"data_ms\": %.1f, "
                "\"forward_ms\": %.1f, \"render_ms\": %.1f, \"backward_ms\": %.1f, \"optimizer_ms\": %.1f}\n",
                stage->name().c_str(), (long long)batch, omp_get_max_threads(), (long long)steps, mean,
                ci95, *lo, *hi, get("time_data_ms"), get("time_forward_ms"), get("time_render_ms"),
                get("time_backward_ms"), get("time_optimizer_ms"));
  } else {
    std::printf("%s step (batch %lld, %d threads, mean of %lld): %.1f ms ± %.1f (95%%; steps %.1f-%.1f) = data %.1f + "
                "forward %.1f + renderer %.1f + backward %.1f + optimizer %.1f (+ bookkeeping)\n",
                stage->name().c_str(), (long long)batch, omp_get_max_threads(), (long long)steps, mean,
                ci95, *lo, *hi, get("time_data_ms"), get("time_forward_ms"), get("time_render_ms"),
                get("time_backward_ms"), get("time_optimizer_ms"));
  }
  return 0;
}

const Registrar reg("train-step", "one training step of a config's stage, split by phase", &run_train_step);

}  // namespace
}  // namespace sl::bench
