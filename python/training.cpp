// streetlight.train: streetlight-train (tools/train.cpp) from Python: a JSON config file or a dict
// validated against train::default_train_config() (tools/common/config.h), run by
// train/trainer.h run_training(), resumable like the tool.
//
// Ctrl-C: run_training() installs its own SIGINT/SIGTERM handlers, which stop the run after the
// current step and save last.safetensors; this binding restores Python's handlers afterwards
// and raises KeyboardInterrupt. An exception raised by the progress callback stops the run the
// same way and is re-raised.
#include <csignal>
#include <cstdio>

#include <nlohmann/json.hpp>
#include <pybind11/stl.h>

#include "python/bindings.h"
#include "tools/common/config.h"
#include "train/distributed.h"
#include "train/train_config.h"
#include "train/trainer.h"

namespace sl::python {

namespace {

// Python's signal handlers, put back when run_training() returns or throws.
class SavedSignalHandlers {
 public:
  SavedSignalHandlers() {
    sigaction(SIGINT, nullptr, &int_);
    sigaction(SIGTERM, nullptr, &term_);
  }
  ~SavedSignalHandlers() {
    sigaction(SIGINT, &int_, nullptr);
    sigaction(SIGTERM, &term_, nullptr);
  }

 private:
  struct sigaction int_ {}, term_{};
};

nlohmann::json json_of(const py::handle& obj) {
  const std::string text = py::module_::import("json").attr("dumps")(obj).cast<std::string>();
  return nlohmann::json::parse(text);
}

py::dict train(const py::object& config, const std::optional<std::string>& out, const std::optional<std::string>& resume,
               const std::vector<std::string>& overrides, const py::object& progress) {
  cli::Config c(train::default_train_config());
  if (py::isinstance<py::str>(config)) {
    const std::string path = config.cast<std::string>();
    file_call({path}, [&] { c.merge_file(path); });
  } else {
    SL_CHECK(py::isinstance<py::dict>(config), "train: config must be a JSON file path or a dict, got ",
             std::string(py::str(config.get_type().attr("__name__"))));
    c.merge(json_of(config), "config dict");
  }
  for (const std::string& s : overrides) c.set(s);
  nlohmann::json cfg = c.tree();
  train::resolve_global_batch(cfg, 1);
  const std::string resume_path = resume.value_or("");
  std::unique_ptr<train::Stage> stage = file_call({resume_path}, [&] { return train::make_stage(cfg); });

  train::RunOptions run;
  run.out_dir = out.value_or("runs/" + stage->name());
  run.resume = resume_path;
  run.log = [](const std::string& line) { std::fprintf(stderr, "%s\n", line.c_str()); };
  bool callback_failed = false;
  const std::string stage_name = stage->name();
  if (!progress.is_none()) {
    run.on_step = [&](int64_t done, int64_t, const train::Metrics& losses) {
      py::gil_scoped_acquire gil;
      try {
        progress(stage_name, done, py::cast(losses));
      } catch (py::error_already_set& e) {
        e.restore();  // raised again once the run has stopped
        callback_failed = true;
        train::request_stop();
      }
    };
  }
  train::RunResult result;
  {
    SavedSignalHandlers handlers;
    train::request_stop(false);
    result = file_call({resume_path}, [&] {
      Compute compute;
      return train::run_training(*stage, cfg, run);
    });
  }
  if (callback_failed) throw py::error_already_set();
  if (result.interrupted) {
    PyErr_SetString(PyExc_KeyboardInterrupt, ("train: stopped at step " + std::to_string(result.steps_done) +
                                              "; resume from " + run.out_dir + "/last.safetensors")
                                                 .c_str());
    throw py::error_already_set();
  }
  py::dict summary;
  summary["stage"] = stage_name;
  summary["steps"] = result.steps_done;
  summary["seconds_per_step"] = result.seconds_per_step;
  summary["total_seconds"] = result.total_seconds;
  summary["out"] = run.out_dir;
  summary["train"] = py::cast(result.last_losses);
  summary["val"] = py::cast(result.last_validation);
  return summary;
}

}  // namespace

void bind_training(py::module_& m) {
  m.def("train", &train, py::arg("config"), py::kw_only(), py::arg("out") = py::none(), py::arg("resume") = py::none(),
        py::arg("overrides") = std::vector<std::string>{}, py::arg("progress") = py::none(),
        "Trains one stage as streetlight-train does (configs/README.md documents every key).\n"
        "  config: a JSON file path or a dict (merged over the defaults; unknown keys are errors)\n"
        "  out: the run folder (default runs/<stage>); resume: a checkpoint to continue bit-identically\n"
        "  overrides: 'key.path=value' strings, like --set\n"
        "  progress: called as progress(stage, step, losses) after every step\n"
        "Returns the run's summary (streetlight-train --json). Ctrl-C stops after the current step,\n"
        "saves last.safetensors and raises KeyboardInterrupt. Releases the GIL.");
}

}  // namespace sl::python
