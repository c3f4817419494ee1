// The shared training loop. See trainer.h.
#include "train/trainer.h"

#include <chrono>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <sys/resource.h>

#include "autodiff/tape.h"
#include "nn/checkpoint.h"
#include "nn/lr_schedule.h"
#include "train/distributed.h"
#include "train/gradient_allreduce.h"
#include "util/file.h"

namespace sl::train {

namespace {

volatile std::sig_atomic_t g_stop = 0;

extern "C" void on_stop_signal(int) { g_stop = 1; }

int64_t peak_rss_kb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<int64_t>(u.ru_maxrss);
}

nlohmann::json metrics_json(const Metrics& m) {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& [k, v] : m) j[k] = std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
  return j;
}

void append_line(const std::string& path, const nlohmann::json& j) {
  std::ofstream f(path, std::ios::app);
  SL_CHECK(f.good(), "train: cannot append to ", path);
  f << j.dump() << "\n";
}

}  // namespace

void install_stop_handlers() {
  std::signal(SIGINT, on_stop_signal);
  std::signal(SIGTERM, on_stop_signal);
}
bool stop_requested() { return g_stop != 0; }
void request_stop(bool on) { g_stop = on ? 1 : 0; }

void check_finite_loss(const std::string& what, double value, int64_t step) {
  if (!std::isfinite(value))
    throw NonFiniteError(cat("loss '", what, "' is ", value, " at step ", step,
                             "; stopping (the last good checkpoint is unchanged)"));
}

void check_finite_gradients(const nn::NamedTensors& params, int64_t step) {
  for (const auto& [name, p] : params) {
    const Tensor& g = p.grad();
    if (!g.defined()) continue;
    const bool ok = SL_DISPATCH_FLOAT(g.dtype(), "check_finite_gradients", [&] {
      const Tensor c = g.contiguous();
      const scalar_t* d = c.data<scalar_t>();
      const int64_t n = c.numel();  // once: numel() walks the shape on every call
      bool finite = true;
      for (int64_t i = 0; i < n; ++i) finite &= static_cast<bool>(std::isfinite(d[i]));  // no early exit: vectorises
      return finite;
    });
    if (!ok)
      throw NonFiniteError(cat("gradient of parameter '", name, "' has NaN or Inf at step ", step,
                               "; stopping (the last good checkpoint is unchanged)"));
  }
}

double clip_finite_gradients(const nn::NamedTensors& params, double max_norm, int64_t step) {
  const double norm = nn::clip_grad_norm(params, max_norm);
  if (!std::isfinite(norm)) check_finite_gradients(params, step);  // throws, naming the parameter
  return norm;  // still not finite only when finite double gradients overflow the sum of squares
}

RunResult run_training(Stage& stage, const nlohmann::json& config, const RunOptions& options) {
  namespace fs = std::filesystem;
  const nlohmann::json& t = config.at("train");
  const nlohmann::json& o = config.at("optim");
  const int64_t total = t.at("steps").get<int64_t>();
  const int64_t log_every = t.at("log_every").get<int64_t>(), val_every = t.at("val_every").get<int64_t>();
  const int64_t ckpt_every = t.at("checkpoint_every").get<int64_t>(), image_every = t.at("image_every").get<int64_t>();
  // The schedule's length: train.steps unless optim.schedule_steps sets another, so that a run can
  // stop part-way through a longer schedule and a resume can change where it ends.
  const int64_t scheduled = o.value("schedule_steps", int64_t{0}) > 0 ? o.at("schedule_steps").get<int64_t>() : total;
  const int64_t warmup = std::min(o.at("warmup_steps").get<int64_t>(), std::max<int64_t>(scheduled - 1, 0));
  std::shared_ptr<const nn::LrSchedule> cosine = std::make_shared<nn::CosineLr>(
      o.at("lr").get<double>(), std::max<int64_t>(scheduled - warmup, 1), o.at("min_lr").get<double>());
  std::shared_ptr<const nn::LrSchedule> schedule =
      warmup > 0 ? std::make_shared<nn::WarmupLr>(warmup, cosine) : cosine;

  std::error_code ec;
  const bool root = is_root();  // data parallel: rank 0 alone writes (distributed.h)
  if (root) fs::create_directories(options.out_dir, ec);
  SL_CHECK(!ec, "train: cannot create the output folder ", options.out_dir, ": ", ec.message());
  const std::string last_path = (fs::path(options.out_dir) / "last.safetensors").string();
  const std::string best_path = (fs::path(options.out_dir) / "best.safetensors").string();
  const std::string metrics_path = (fs::path(options.out_dir) / "metrics.jsonl").string();
  auto log = [&](const std::string& s) {
    if (options.log && root) options.log(s);
  };
  // A trainer killed while writing a checkpoint leaves ".last.safetensors.tmp.<pid>.<n>" behind.
  if (const int swept = sweep_stale_temp_files(options.out_dir); swept > 0)
    log(cat("removed ", swept, " stale temporary file(s) of killed runs from ", options.out_dir));

  // Weight averaging (optim.ema_decay > 0, nn/optim.h): enabled before a resume loads its state.
  const double ema_decay = o.value("ema_decay", 0.0);
  if (ema_decay > 0 && !stage.optimizer().averaging()) stage.optimizer().enable_average(ema_decay);

  int64_t step = 0;
  double best = std::numeric_limits<double>::infinity();
  if (!options.resume.empty()) {
    const nn::CheckpointInfo info = nn::load_checkpoint(options.resume, stage.model(), &stage.optimizer());
    SL_CHECK(info.stage == stage.name(), "--resume ", options.resume, ": checkpoint is from stage '", info.stage,
             "', the config is stage '", stage.name(), "'");
    step = info.step;
    if (auto it = info.extra.find("best_metric"); it != info.extra.end()) best = std::stod(it->second);
    log(cat("resumed from ", options.resume, " at step ", step));
  } else {
    stage.initialise();
  }
  broadcast_parameters(stage.model());  // data parallel: every replica starts from rank 0's
  broadcast_buffers(stage.model());

  auto save = [&](const std::string& path) {
    nn::CheckpointInfo info;
    info.stage = stage.name();
    info.step = step;
    info.config_json = config.dump();
    if (std::isfinite(best)) {
      char buf[64];
      std::snprintf(buf, sizeof buf, "%.17g", best);
      info.extra["best_metric"] = buf;
    }
    if (is_distributed()) {
      info.extra["world_size"] = std::to_string(world().size());
      info.extra["global_batch"] = std::to_string(world().size() * t.at("batch_size").get<int64_t>());
    }
    nn::save_checkpoint(path, stage.model(), &stage.optimizer(), info);
  };

  install_stop_handlers();
  RunResult result;
  const auto t0 = std::chrono::steady_clock::now();
  const int64_t first = step;
  double step_seconds = 0.0;
  while (step < total) {
    stage.set_lr(schedule->lr(step));
    const auto s0 = std::chrono::steady_clock::now();
    result.last_losses = stage.step(step);
    average_metrics(result.last_losses, step);  // data parallel: the global batch's losses
    broadcast_buffers(stage.model());           // per-rank batch-norm statistics: rank 0's win
    step_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - s0).count();
    ++step;
    if (options.on_step) options.on_step(step, total, result.last_losses);
    if (root && (step % log_every == 0 || step == total)) {
      nlohmann::json line = metrics_json(result.last_losses);
      line["step"] = step;
      line["split"] = "train";
      line["lr"] = stage.optimizer().lr();
      append_line(metrics_path, line);
    }
    if (root && (step % val_every == 0 || step == total)) {
      // With weight averaging, validation and best.safetensors see the averaged weights.
      const bool averaged = stage.optimizer().averaging();
      if (averaged) stage.optimizer().swap_average();
      result.last_validation = stage.validate();
      nlohmann::json line = metrics_json(result.last_validation);
      line["step"] = step;
      line["split"] = "val";
      append_line(metrics_path, line);
      const auto it = result.last_validation.find(stage.best_metric());
      if (it != result.last_validation.end() && std::isfinite(it->second) && it->second < best) {
        best = it->second;
        save(best_path);
        log(cat("step ", step, ": new best ", stage.best_metric(), " = ", best, " -> ", best_path));
      }
      if (averaged) stage.optimizer().swap_average();
    }
    if (root && (step % image_every == 0 || step == total))
      stage.write_strip((fs::path(options.out_dir) / cat("strip_", step, ".png")).string());
    const bool stop = any_rank(stop_requested());
    if (step % ckpt_every == 0 || step == total || stop) {
      check_replicas(stage.model(), step);  // the checkpoint stands for every rank
      if (root) save(last_path);
    }
    if (stop) {
      result.interrupted = true;
      log(cat("stopped by signal at step ", step, "; saved ", last_path, " (resume with --resume ", last_path, ")"));
      break;
    }
  }
  request_stop(false);
  result.steps_done = step;
  result.total_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  result.seconds_per_step = step > first ? step_seconds / static_cast<double>(step - first) : 0.0;
  result.peak_rss_kb = peak_rss_kb();
  return result;
}

}  // namespace sl::train
