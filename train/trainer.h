// The training loop shared by the three stages (Sec 3.4): schedule, checkpoints, resume,
// validation, metrics, image strips, signal handling and non-finite guards.
//
// Contract:
// - A Stage owns its model (everything the checkpoint holds), its optimiser and its data. Its
//   step(s) runs ONE optimisation step whose randomness is a pure function of (seed, s) and
//   whose data order is a pure function of (seed, epoch), so a run resumed at step s computes
//   exactly what an uninterrupted run computes (bit-identical with the same thread count).
// - run_training(): from step 0 (after stage.initialise(), which loads the checkpoint the stage
//   starts from) or from --resume (model, optimiser, step and best metric from the checkpoint).
//   Per step: lr from the schedule (warmup + cosine over optim.schedule_steps, train.steps when
//   0; the run stops at train.steps either way), stage.step(); every log_every steps a
//   JSON line appended to <out>/metrics.jsonl; every val_every steps validation (a JSON line
//   with "split": "val") and best.safetensors when the stage's best metric improved; every
//   checkpoint_every steps and at the end last.safetensors (atomic); every image_every steps
//   a PNG strip <out>/strip_<step>.png.
// - optim.ema_decay > 0 turns on the optimiser's weight averaging (nn/optim.h): validation runs
//   on the averaged weights, and best.safetensors holds them as the model (its "optim.average.*"
//   then holds the raw weights; resume from last.safetensors, which holds the raw ones).
// - SIGINT / SIGTERM: the handler only sets a flag; the loop checks it after each step, saves
//   last.safetensors and returns with interrupted = true.
// - A non-finite loss or gradient throws NonFiniteError naming the loss or parameter and the
//   step, before the optimiser touches the weights; checkpoints already written stay intact.
#pragma once
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>

#include <nlohmann/json.hpp>

#include "nn/module.h"
#include "nn/optim.h"

namespace sl::train {

using Metrics = std::map<std::string, double>;

// A run-time failure (not bad input): the train executable exits 1 with its message.
class NonFiniteError : public std::runtime_error {
 public:
  explicit NonFiniteError(const std::string& m) : std::runtime_error(m) {}
};

// Throws NonFiniteError naming `what` and the step when value is NaN or ±inf.
void check_finite_loss(const std::string& what, double value, int64_t step);
// Throws NonFiniteError naming the first parameter whose gradient has a NaN or ±inf.
void check_finite_gradients(const nn::NamedTensors& params, int64_t step);
// nn::clip_grad_norm with check_finite_gradients' guarantee, in one pass over the gradients where
// they are finite: the global norm is finite iff every gradient is (its sum of squares is taken in
// double), and only a non-finite norm, which leaves the gradients untouched, looks for the
// parameter to name. Returns the norm before clipping.
double clip_finite_gradients(const nn::NamedTensors& params, double max_norm, int64_t step);

class Stage {
 public:
  virtual ~Stage() = default;
  virtual std::string name() const = 0;
  virtual nn::Module& model() = 0;
  virtual nn::Optimizer& optimizer() = 0;
  // Loads what a fresh run starts from (the previous stage's checkpoint); not called on resume.
  virtual void initialise() {}
  // One optimisation step at the optimiser's current lr; returns the loss terms ("loss" = total).
  virtual Metrics step(int64_t step) = 0;
  virtual Metrics validate() = 0;
  // The validation metric to minimise for best.safetensors.
  virtual std::string best_metric() const = 0;
  virtual void write_strip(const std::string& path) = 0;
  // Called with the lr of the step; stages with a second optimiser scale theirs from it.
  virtual void set_lr(double lr) { optimizer().set_lr(lr); }
};

struct RunOptions {
  std::string out_dir = "runs/train";
  std::string resume;  // checkpoint path, or empty
  // Called after every step with the step count done, the total and the step's losses.
  std::function<void(int64_t done, int64_t total, const Metrics& losses)> on_step;
  std::function<void(const std::string& line)> log;  // human-readable messages (stderr)
};

struct RunResult {
  int64_t steps_done = 0;
  bool interrupted = false;
  Metrics last_losses;
  Metrics last_validation;
  double seconds_per_step = 0.0;  // stage.step() only (no validation, checkpoints, strips)
  double total_seconds = 0.0;
  int64_t peak_rss_kb = 0;
};

// Builds the stage the config names (stage key), validating the config first.
std::unique_ptr<Stage> make_stage(const nlohmann::json& config);

RunResult run_training(Stage& stage, const nlohmann::json& config, const RunOptions& options);

// Installs SIGINT/SIGTERM handlers that set the stop flag (run_training installs them too).
void install_stop_handlers();
bool stop_requested();
void request_stop(bool on = true);  // for tests

}  // namespace sl::train
