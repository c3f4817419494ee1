// streetlight-bench predictor-step: one training step of the lighting predictor WITHOUT the
// renderer, for the side-by-side with PyTorch in scripts/compare_torch_train.py.
// The predictor is the default configuration (train/lighting_predictor.h, configs/README.md):
// ResNet-18 on 128×256 images, sky head + the FROZEN sky decoder (32×128 dome, d = 64), volume
// MLP + trilinear ×8 + UNet3D (base 8, depth 3, GroupNorm 4, LeakyReLU 0.2) on a 64×64×16 VSG.
// A step is: zero_grad, forward on a batch of 2 (image + RGBα volume), loss = mean(log_env²) +
// mean(vsg²), backward, AdamW. Best of 5 after a warm-up; peak tensor memory of one step.
#include <omp.h>

#include <cstdio>

#include "autodiff/ops.h"
#include "nn/optim.h"
#include "tools/bench/bench.h"
#include "tools/bench/timing.h"
#include "tools/common/cli.h"
#include "train/lighting_predictor.h"

namespace sl::bench {
namespace {

int run_predictor_step(const std::vector<std::string>& args) {
  bool json = false;
  int64_t batch = 2;
  for (size_t i = 0; i < args.size(); ++i) {
    if (args[i] == "--json") json = true;
    else if (args[i] == "--batch" && i + 1 < args.size()) batch = cli::parse_integer("predictor-step: --batch", args[++i], 1, 4096);
    else if (args[i] == "--help" || args[i] == "-h") {
      std::printf("usage: streetlight-bench predictor-step [--batch N] [--json]\n"
                  "  One AdamW training step of the default lighting predictor without the renderer.\n");
      return 0;
    } else {
      fail("predictor-step: unknown option '", args[i], "' (try --help)");
    }
  }
  SL_CHECK(batch >= 1, "predictor-step: --batch must be >= 1, got ", batch);
  train::LightingPredictor net{train::LightingPredictorOptions{}};
  net.set_training(true);
  nn::AdamOptions ao;
  ao.lr = 1e-4;
  ao.weight_decay = 1e-4;
  nn::AdamW opt(net.named_parameters(), ao);
  const auto& o = net.options();
  const Tensor image = Tensor::uniform({batch, 3, o.image_height, o.image_width}, 0, 1, 1);
  const Tensor rgba = Tensor::uniform({batch, 4, o.vsg_dims[0], o.vsg_dims[1], o.vsg_dims[2]}, 0, 1, 2);
  auto step = [&] {
    opt.zero_grad();
    const train::LightingPrediction p = net.predict(image, rgba);
    backward(add(mean(square(p.log_env)), mean(square(p.vsg))));
    opt.step();
  };
  step();
  Storage::reset_peak_bytes();
  const int64_t base = Storage::live_bytes();
  step();
  const double peak_mb = double(Storage::peak_bytes() - base) / (1 << 20);
  const double ms = best_ms(step, 5, 0);
  if (json)
    std::printf("{\"bench\": \"predictor_step\", \"batch\": %lld, \"threads\": %d, \"trainable_params\": %lld, "
                "\"ms\": %.1f, \"peak_tensor_mb\": %.1f}\n",
                (long long)batch, omp_get_max_threads(), (long long)net.parameter_count(true), ms, peak_mb);
  else
    std::printf("predictor training step (batch %lld): %.1f ms, peak tensors %.1f MB\n", (long long)batch, ms, peak_mb);
  return 0;
}

const Registrar reg("predictor-step", "one training step of the default lighting predictor (no renderer)",
                    &run_predictor_step);

}  // namespace
}  // namespace sl::bench
