// streetlight-bench inference: lighting inference for one photo, part by part (issue 52 item 1).
//
// Loads a lighting checkpoint (default: the released model) into train::LightingEstimator and
// times, on one KITTI-size photo (../shared/data/street/kitti_000008 with lidar depth; a flat
// 1242×375 ground-plane photo when the data is absent), each part of what estimate() runs:
// the input resize, the RGBα unprojection, the ResNet backbone, the sky head, the sky decoder,
// the volume MLP (with its trilinear upsampling and the concatenation), the 3D UNet, the VSG
// activation, the flip pass (the mirrored photo through backbone and sky head), the visible-sun
// cue, and the whole estimate(). Each figure is the best of --runs calls after one warm-up, in
// wall time and process CPU time (all threads). The parts are timed one by one, under
// NoGradGuard as estimate() runs them; their sum need not equal the whole (allocation reuse,
// caches). The whole estimate is also timed against the plain path it replaced (the same calls
// in sequence), alternating run by run. --json prints one object per part.
#include <omp.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <functional>

#include "autodiff/ops.h"
#include "autodiff/tape.h"
#include "data/augment.h"
#include "data/visible_sun.h"
#include "nn/functional/upsample.h"
#include "render/vsg_volume.h"
#include "tools/bench/bench.h"
#include "tools/bench/kitti_frame.h"
#include "tools/bench/timing.h"
#include "tools/common/cli.h"
#include "train/inference.h"
#include "train/photo_input.h"
#include "train/photo_insertion.h"
#include "train/street_batch.h"
#include "train/unprojection.h"

namespace sl::bench {
namespace {

struct PartTime {
  double wall_ms = 0, cpu_ms = 0;
};

PartTime time_part(const std::function<void()>& f, int runs) {
  f();  // warm-up
  PartTime t{1e300, 1e300};
  for (int i = 0; i < runs; ++i) {
    const double w0 = now_ms(), c0 = cpu_now_ms();
    f();
    t.cpu_ms = std::min(t.cpu_ms, cpu_now_ms() - c0);
    t.wall_ms = std::min(t.wall_ms, now_ms() - w0);
  }
  return t;
}

train::Photo inference_photo(const std::string& data) {
  const std::string dir = data + "/street/kitti_000008";
  if (std::filesystem::exists(dir + "/000008.png")) return train::load_photo(kitti_000008(dir));
  train::Photo p;
  render::Intrinsics k;
  k.width = 1242;
  k.height = 375;
  k.fx = k.fy = 721.5;
  k.cx = 609.6;
  k.cy = 172.9;
  p.camera = render::Camera(k, render::rotation_from_yaw_pitch_roll(0, 0, 0), {0.0, 1.65, 0.0});
  p.depth = train::ground_plane_depth(p.camera);
  p.ldr = Tensor::full({3, 375, 1242}, 0.5);
  return p;
}

int run_inference(const std::vector<std::string>& args) {
  bool json = false;
  int runs = 5;
  std::string data = "../shared/data", checkpoint = "released";
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "--json") json = true;
    else if (a == "--runs" && i + 1 < args.size()) runs = int(cli::parse_integer("inference: --runs", args[++i], 1, 1000));
    else if (a == "--data" && i + 1 < args.size()) data = args[++i];
    else if (a == "--checkpoint" && i + 1 < args.size()) checkpoint = args[++i];
    else if (a == "--help" || a == "-h") {
      std::printf("usage: streetlight-bench inference [--checkpoint PATH|released] [--data DIR] [--runs N] [--json]\n"
                  "  Lighting inference for one KITTI-size photo, part by part (best of N after a warm-up;\n"
                  "  wall and process CPU time).\n");
      return 0;
    } else {
      fail("inference: unknown option '", a, "' (try --help)");
    }
  }
  if (checkpoint == "released") checkpoint = cli::released_model_path();
  train::LightingEstimator est(checkpoint);
  // As streetlight-insert: the released sun-glare detector behind the disk test, when present.
  if (const std::string glare = cli::released_sun_glare_path(); !glare.empty()) est.set_sun_glare(train::load_sun_glare(glare));
  train::LightingPredictor& net = est.predictor();
  const train::LightingPredictorOptions& po = net.options();
  const train::Photo photo = inference_photo(data);
  const train::InferenceView view{photo.ldr, photo.depth, photo.camera};
  std::fprintf(stderr, "inference bench: %s, photo %lldx%lld, %d threads\n", checkpoint.c_str(),
               (long long)photo.ldr.size(2), (long long)photo.ldr.size(1), omp_get_max_threads());

  NoGradGuard no_grad;
  const train::CanonicalFrame frame = train::canonical_frame(photo.camera);
  const render::Camera cam = frame.camera(photo.camera);
  render::VsgGrid grid = est.estimate({view}).grid;

  Tensor image, rgba, g, raw, coarse, unet_in, unet_out;
  train::SkyCode code;
  std::vector<std::pair<std::string, PartTime>> rows;
  auto part = [&](const std::string& name, const std::function<void()>& f) { rows.emplace_back(name, time_part(f, runs)); };
  part("resize", [&] { image = unsqueeze(train::resize_bilinear(photo.ldr, po.image_height, po.image_width), 0); });
  if (po.volume_branch)
    part("unprojection", [&] { rgba = unsqueeze(train::unproject_rgba(photo.ldr, photo.depth, cam, grid), 0); });
  part("backbone", [&] { g = net.backbone().forward_features(image).pooled; });
  const Tensor pair = concat({image, unsqueeze(data::flip_horizontal(select(image, 0, 0).contiguous()), 0)}, 0);
  part("backbone, N=2 (photo + mirror)", [&] { net.backbone().forward_features(pair); });
  {
    // The same backbone with its batch norms folded into the convs (nn/modules/batch_norm_folding.h).
    train::LightingEstimator folded(checkpoint);
    folded.predictor().backbone().fold_batch_norms();
    part("backbone, batch norms folded", [&] { folded.predictor().backbone().forward_features(image); });
    const double diff = max(abs(sub(folded.predictor().backbone().forward_features(image).pooled,
                                    net.backbone().forward_features(image).pooled))).item();
    const double scale = max(abs(net.backbone().forward_features(image).pooled)).item();
    std::fprintf(stderr, "backbone, batch norms folded: max |difference| of the pooled features %.3g (features up to %.3g)\n",
                 diff, scale);
  }
  if (po.sky_branch == "sky_decoder") {
    part("sky_head", [&] { code = train::sky_code_from_raw(net.child("sky_head")->forward(g)); });
    part("sky_decoder", [&] { net.sky_decoder()->decode(code); });
    part("flip_pass", [&] { net.predict_sky_code(unsqueeze(data::flip_horizontal(select(image, 0, 0).contiguous()), 0)); });
  }
  if (po.volume_branch) {
    const auto& c = po.vsg_dims;
    const int64_t s = po.coarse_scale;
    part("volume_mlp", [&] {
      coarse = reshape(net.child("volume_mlp")->forward(g), {1, po.coarse_channels, c[0] / s, c[1] / s, c[2] / s});
      if (s > 1) coarse = nn::upsample_trilinear3d(coarse, s);
      unet_in = concat({coarse, rgba.to(image.dtype())}, 1);
    });
    part("unet3d", [&] { unet_out = net.child("volume_unet")->forward(unet_in); });
    part("vsg_activate", [&] { render::vsg_activate(unet_out, 1); });
  }
  part("predict (network, N=1)", [&] { net.predict(image, rgba); });
  part("visible_sun", [&] { data::find_visible_sun(photo.ldr, photo.camera, est.visible_sun_params()); });
  if (est.sun_glare())
    part("sun_glare (where the disk test finds nothing)", [&] {
      est.sun_glare()->forward(unsqueeze(train::glare_input(photo.ldr), 0));
    });
  // The whole estimate against the plain path it replaced (the same calls in sequence, each op
  // with its own parallel loops, the photo's dome decoded and unread), alternating run by run so
  // that a load beside them weighs on both alike: best and median of --runs each.
  const auto plain = [&] {
    const Tensor im = unsqueeze(train::resize_bilinear(photo.ldr, po.image_height, po.image_width), 0);
    const Tensor r = po.volume_branch ? unsqueeze(train::unproject_rgba(photo.ldr, photo.depth, cam, grid), 0) : Tensor();
    const train::LightingPrediction p = net.predict(im, r);
    if (po.sky_branch == "sky_decoder") {
      if (est.flip_average()) net.predict_sky_code(unsqueeze(data::flip_horizontal(select(im, 0, 0).contiguous()), 0));
      if (est.visible_sun() && !data::find_visible_sun(photo.ldr, photo.camera, est.visible_sun_params()).found &&
          est.sun_glare())
        est.sun_glare()->forward(unsqueeze(train::glare_input(photo.ldr), 0));
      net.sky_decoder()->decode(p.code);
    }
  };
  const auto fast = [&] { est.estimate({view}); };
  plain();
  fast();
  std::vector<double> pw, pc, fw, fc;
  for (int i = 0; i < runs; ++i)
    for (int which = 0; which < 2; ++which) {
      const double w0 = now_ms(), c0 = cpu_now_ms();
      which == 0 ? plain() : fast();
      const double c = cpu_now_ms() - c0, w = now_ms() - w0;
      (which == 0 ? pw : fw).push_back(w);
      (which == 0 ? pc : fc).push_back(c);
    }
  const auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  const auto best = [](const std::vector<double>& v) { return *std::min_element(v.begin(), v.end()); };
  rows.emplace_back("plain path (before), best", PartTime{best(pw), best(pc)});
  rows.emplace_back("plain path (before), median", PartTime{median(pw), median(pc)});
  rows.emplace_back("estimate (all), best", PartTime{best(fw), best(fc)});
  rows.emplace_back("estimate (all), median", PartTime{median(fw), median(fc)});
  for (const auto& [name, t] : rows) {
    if (json)
      std::printf("{\"bench\": \"inference\", \"part\": \"%s\", \"threads\": %d, \"ms\": %.2f, \"cpu_ms\": %.2f}\n",
                  name.c_str(), omp_get_max_threads(), t.wall_ms, t.cpu_ms);
    else
      std::printf("%-32s %9.2f ms   (CPU %9.2f ms)\n", name.c_str(), t.wall_ms, t.cpu_ms);
  }
  return 0;
}

const Registrar reg("inference", "lighting inference for one KITTI-size photo, part by part", &run_inference);

}  // namespace
}  // namespace sl::bench
