// streetlight-train: trains one stage of the method (Sec 3.4) from a JSON config.
//
//   streetlight-train --config FILE.json [--set key=value ...] [--resume CKPT] [--out DIR] [--json]
//
// Stages (the config's "stage" key): sky_autoencoder, lighting (starts from the frozen stage-1
// model named by init.sky_checkpoint), adversarial (starts from init.checkpoint of stage 2).
// Every key and default: configs/README.md. Progress on stderr (a bar on a terminal, plain
// lines otherwise); metrics as JSON lines in DIR/metrics.jsonl; checkpoints DIR/last.safetensors
// and DIR/best.safetensors; PNG strips DIR/strip_<step>.png. SIGINT/SIGTERM saves and exits 0.
// Exit codes: 0 done (or stopped by a signal), 2 bad input, 1 failure at run time (NaN/Inf).
// Data parallel (docs/DISTRIBUTED.md): `mpirun -np N streetlight-train ...` in a build with MPI
// trains on N ranks (train/distributed.h); rank 0 alone prints progress and writes outputs, and
// an error on any rank aborts the whole job with that rank's exit code.
#include <cstdio>
#include <iostream>
#include <sstream>

#include "nn/checkpoint.h"
#include "tools/common/cli.h"
#include "tools/common/config.h"
#include "train/distributed.h"
#include "train/mpi_communicator.h"
#include "train/train_config.h"
#include "train/trainer.h"

namespace {

std::string short_metrics(const sl::train::Metrics& m) {
  std::ostringstream os;
  os.precision(4);
  int shown = 0;
  for (const char* k : {"loss", "direction", "hdr", "radiance", "adversarial", "d_loss"}) {
    const auto it = m.find(k);
    if (it == m.end()) continue;
    os << (shown++ ? " " : "") << k << " " << it->second;
  }
  return os.str();
}

int run(int argc, char** argv) {
  sl::cli::Args args("streetlight-train",
                     "streetlight-train --config FILE.json [--set key=value ...] [--resume CKPT] [--out DIR]\n\n"
                     "Trains one stage (sky_autoencoder, lighting, adversarial) of the lighting model of\n"
                     "Wang et al. ECCV 2022, Sec 3.4. Every config key is documented in configs/README.md.",
                     {{"--config", "FILE", "JSON config (validated; unknown keys name the nearest valid key)"},
                      {"--set", "KEY=VALUE", "override one config key, e.g. --set train.steps=100", true},
                      {"--resume", "CKPT", "continue bit-identically from a checkpoint of this stage"},
                      {"--out", "DIR", "output folder (default runs/<stage>)"},
                      {"--json", "", "print the run summary as one JSON object on stdout"}});
  if (!args.parse(argc, argv)) return 0;
  sl::train::set_world(sl::train::mpi_communicator_if_launched(&argc, &argv));
  const bool root = sl::train::is_root();
  sl::cli::Config config(sl::train::default_train_config());
  const std::string resume = args.get("--resume");
  if (args.has("--config")) {
    config.merge_file(args.get("--config"));
  } else if (!resume.empty()) {
    config.merge(nlohmann::json::parse(sl::nn::read_checkpoint_info(resume).config_json),
                 "checkpoint '" + resume + "'");
  } else {
    sl::fail("--config FILE.json is required (or --resume CKPT to continue with the checkpoint's config)");
  }
  for (const auto& s : args.all("--set")) config.set(s);
  nlohmann::json cfg = config.tree();
  sl::train::resolve_global_batch(cfg, sl::train::world().size());
  auto stage = sl::train::make_stage(cfg);

  sl::train::RunOptions run;
  run.out_dir = args.get("--out", "runs/" + stage->name());
  run.resume = resume;
  run.log = [](const std::string& line) { std::fprintf(stderr, "%s\n", line.c_str()); };
  const int64_t total = cfg.at("train").at("steps").get<int64_t>();
  sl::cli::Progress progress("train " + stage->name(), total);
  run.on_step = [&](int64_t done, int64_t, const sl::train::Metrics& m) {
    if (root) progress.update(done, short_metrics(m));
  };
  if (root && sl::train::is_distributed())
    std::fprintf(stderr, "data parallel: %d ranks x batch %lld = global batch %lld\n", sl::train::world().size(),
                 static_cast<long long>(cfg.at("train").at("batch_size").get<int64_t>()),
                 static_cast<long long>(sl::train::world().size() * cfg.at("train").at("batch_size").get<int64_t>()));
  sl::train::RunResult result;
  try {
    result = sl::train::run_training(*stage, cfg, run);
  } catch (const sl::train::NonFiniteError& e) {
    std::fprintf(stderr, "\nerror: %s\n", e.what());
    return 1;
  }
  if (!root) return 0;
  progress.finish(short_metrics(result.last_losses));
  nlohmann::json summary = {{"stage", stage->name()},
                            {"steps", result.steps_done},
                            {"interrupted", result.interrupted},
                            {"seconds_per_step", result.seconds_per_step},
                            {"total_seconds", result.total_seconds},
                            {"peak_rss_mb", static_cast<double>(result.peak_rss_kb) / 1024.0},
                            {"out", run.out_dir}};
  if (sl::train::is_distributed()) summary["ranks"] = sl::train::world().size();
  for (const auto& [k, v] : result.last_losses) summary["train"][k] = v;
  for (const auto& [k, v] : result.last_validation) summary["val"][k] = v;
  if (args.has("--json")) {
    std::cout << summary.dump() << "\n";
  } else {
    std::fprintf(stderr, "%s %lld steps, %.3f s/step, peak memory %.0f MB -> %s\n", stage->name().c_str(),
                 static_cast<long long>(result.steps_done), result.seconds_per_step,
                 static_cast<double>(result.peak_rss_kb) / 1024.0, run.out_dir.c_str());
    for (const auto& [k, v] : result.last_validation) std::fprintf(stderr, "  %s %.5g\n", k.c_str(), v);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const int code = sl::cli::run_main([&] { return run(argc, argv); });
  // Data parallel: the other ranks would wait for this one forever; stop them all.
  if (code != 0 && sl::train::is_distributed()) sl::train::world().abort(code);
  sl::train::set_world(nullptr);  // finalises MPI
  return code;
}
