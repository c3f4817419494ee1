// streetlight-export: turns a lighting checkpoint (stage 2 or 3) into released inference weights:
// only the predictor's tensors (predictor.*, with its frozen sky decoder), F16 by default, with
// the stage, step and config metadata that LightingEstimator (train/inference.h) needs, plus
// free-form --meta key=value notes (e.g. the commit). The teacher and optimiser state are
// dropped, and so is the discriminator unless --with-discriminator keeps it (discriminator.*,
// for streetlight-insert --refine, train/lighting_refinement.h). The output is written
// atomically and checked by loading it back. --blend B --blend-t T writes the weight-space
// interpolation (1 − T)·CKPT + T·B of two checkpoints of one model (nn/weight_blend.h).
#include <cstdio>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "nn/checkpoint.h"
#include "nn/safetensors.h"
#include "nn/weight_blend.h"
#include "tools/common/cli.h"
#include "train/inference.h"
#include "train/lighting_refinement.h"
#include "train/train_config.h"
#include "util/file.h"

namespace {

using namespace sl;

int run(int argc, char** argv) {
  cli::Args a("streetlight-export",
              "streetlight-export --checkpoint CKPT --out FILE.safetensors [--f32] [--with-discriminator] [--meta KEY=VALUE ...]\n"
              "streetlight-export --checkpoint CKPT --blend CKPT2 --blend-t T --out FILE.safetensors\n"
              "streetlight-export --checkpoint CKPT --info\n\n"
              "Writes the released-weights form of a lighting checkpoint: predictor.* only, F16 unless --f32,\n"
              "with its stage, step and config, so streetlight-insert and streetlight-eval can load it.\n"
              "With --blend, the weights are (1 - T) * CKPT + T * CKPT2, tensor by tensor (WiSE-FT); the\n"
              "stage, step and config are CKPT's.",
              {{"--checkpoint", "CKPT", "a lighting or adversarial stage checkpoint (streetlight-train)"},
               {"--out", "FILE", "output .safetensors file"},
               {"--f32", "", "keep float32 (default: float16, half the size)"},
               {"--with-discriminator", "", "also keep the stage-3 discriminator (discriminator.*) for streetlight-insert --refine"},
               {"--meta", "KEY=VALUE", "extra metadata entry", true},
               {"--blend", "CKPT2", "a second checkpoint of the same model to interpolate with"},
               {"--blend-t", "T", "the weight of CKPT2 in [0, 1] (default 0.5)"},
               {"--info", "", "print the checkpoint's metadata as JSON on stdout and exit (no --out needed)"}});
  if (!a.parse(argc, argv)) return 0;
  if (a.has("--info")) {
    SL_CHECK(a.has("--checkpoint"), "--info needs --checkpoint CKPT");
    const nn::SafetensorsFile f = nn::read_safetensors(a.get("--checkpoint"));
    std::printf("%s\n", nlohmann::json(f.metadata).dump().c_str());
    return 0;
  }
  SL_CHECK(a.has("--checkpoint") && a.has("--out"), "--checkpoint CKPT and --out FILE are required");
  const std::string in = a.get("--checkpoint"), out = a.get("--out");
  // Only lighting and adversarial checkpoints hold a predictor to release (or blend).
  const auto check_stage = [](const std::string& path, const char* verb) {
    const nn::CheckpointInfo info = nn::read_checkpoint_info(path);
    SL_CHECK(info.stage == train::kStageLighting || info.stage == train::kStageAdversarial, "checkpoint '", path,
             "' holds stage '", info.stage, "'; only lighting and adversarial checkpoints can be ", verb);
  };
  check_stage(in, "exported");
  const bool with_d = a.has("--with-discriminator");
  // The released tensors of one checkpoint: predictor.*, and discriminator.* with --with-discriminator.
  size_t d_tensors = 0;
  const auto released = [&](const std::string& path, const nn::SafetensorsFile& file) {
    nn::StateDict kept;
    for (const auto& [name, t] : file.tensors)
      if (name.rfind("predictor.", 0) == 0) kept.emplace(name, t);
    SL_CHECK(!kept.empty(), "checkpoint '", path, "' holds no predictor.* tensors");
    if (with_d) {
      d_tensors = 0;
      for (const auto& [name, t] : file.tensors)
        if (name.rfind("discriminator.", 0) == 0) d_tensors += kept.emplace(name, t).second;
      SL_CHECK(d_tensors > 0, "--with-discriminator: checkpoint '", path, "' holds no discriminator.* tensors (only a",
               " stage-3 checkpoint trained with loss.adversarial > 0 has one)");
    }
    return kept;
  };
  const nn::SafetensorsFile file = nn::read_safetensors(in);
  nn::StateDict kept = released(in, file);
  nn::Metadata meta = file.metadata;
  SL_CHECK(!a.has("--blend-t") || a.has("--blend"), "--blend-t needs --blend CKPT2");
  if (a.has("--blend")) {
    const std::string other = a.get("--blend");
    const double t = a.number("--blend-t", 0.5);
    SL_CHECK(t >= 0.0 && t <= 1.0, "--blend-t must be in [0, 1], got '", a.get("--blend-t"), "'");
    check_stage(other, "blended (--blend)");
    try {
      kept = nn::blend_states(kept, released(other, nn::read_safetensors(other)), t);
    } catch (const Error& e) {
      fail("--blend: checkpoint '", other, "' does not blend with '", in, "': ", e.what());
    }
    meta["blended_with"] = std::filesystem::path(other).filename().string();
    meta["blend_t"] = a.get("--blend-t", "0.5");
  }
  for (auto it = meta.begin(); it != meta.end();) it = it->first.rfind("best", 0) == 0 ? meta.erase(it) : std::next(it);
  meta["exported_from"] = std::filesystem::path(in).filename().string();
  for (const auto& kv : a.all("--meta")) {
    const auto eq = kv.find('=');
    SL_CHECK(eq != std::string::npos && eq > 0, "--meta expects KEY=VALUE, got '", kv, "'");
    meta[kv.substr(0, eq)] = kv.substr(eq + 1);
  }
  const auto parent = std::filesystem::path(out).parent_path();
  if (!parent.empty()) std::filesystem::create_directories(parent);
  // Written and checked under a temporary name, renamed over `out` only once it loads back, so a
  // failed check leaves no file (and an existing `out` untouched).
  const std::string tmp = temp_sibling(out, /*keep_extension=*/true);
  struct RemoveUnlessRenamed {
    const std::string& path;
    ~RemoveUnlessRenamed() { std::error_code ec; std::filesystem::remove(path, ec); }
  } guard{tmp};
  nn::write_safetensors(tmp, kept, meta, {.f32_as_f16 = !a.has("--f32")});
  train::LightingEstimator check(tmp);  // loads back exactly as the tools will
  SL_CHECK(!with_d || train::load_discriminator(tmp), "export '", out, "': the discriminator did not load back");
  std::filesystem::rename(tmp, out);
  std::fprintf(stderr, "export: %zu tensors (%zu of the discriminator), stage %s step %lld -> %s (%.1f MB)\n",
               kept.size(), d_tensors, check.stage().c_str(),
               static_cast<long long>(check.step()), out.c_str(),
               static_cast<double>(std::filesystem::file_size(out)) / 1e6);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return sl::cli::run_main([&] { return run(argc, argv); });
}
