// streetlight-bench sun-glare: trains the learned sun-glare detector (train/sun_glare.h) on crops of
// the TRAIN split and scores it, beside the hand-made cue (data/visible_sun.h), on crops of the
// VALIDATION split: how often it fires within 5° of a sun in view, how often it fires where no sun
// is in view, at several thresholds. Test is never read.
//
// Crops of the labelled LDR panoramas (256×128, horizontal fov uniform in [50°, 80°], roll 0,
// resampled in linear radiance as the benchmark's crops are):
// - a panorama with a visible sun: `aimed` crops with the sun in the middle 80% of the view, `near`
//   crops aimed 1.1-1.6 half-fovs beside it (the sun just out of view: the glare's spill without the
//   sun), and `random` crops (yaw uniform, pitch uniform in [−5°, 25°]); a crop's sun is in view when
//   it projects inside the image;
// - any other panorama (sun occluded or absent): `random` crops, none with a sun in view.
// Plus, with --hdr-data, the benchmark's own crops of the HDR skies (as streetlight-eval draws them).
// The validation score adds the benchmark's own crops of the validation LDR panoramas (8 each).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <numeric>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "autodiff/ops.h"
#include "data/image_io.h"
#include "data/panorama.h"
#include "data/sun_labels.h"
#include "data/visible_sun.h"
#include "nn/checkpoint.h"
#include "nn/optim.h"
#include "tools/bench/bench.h"
#include "tools/bench/ldr_panorama_radiance.h"
#include "tools/common/cli.h"
#include "train/metrics.h"
#include "train/real_sky_benchmark.h"
#include "train/sun_distribution.h"
#include "train/sun_glare.h"
#include "util/error.h"
#include "util/math.h"
#include "util/random.h"

namespace sl::bench {
namespace {

struct GlareCrop {
  Tensor input;  // glare_input of the crop
  Tensor ldr;    // the crop itself (validation only, for the disk test)
  render::Camera camera;
  std::optional<glm::dvec2> sun_pixel;  // in view
  glm::dvec3 sun{0.0, 1.0, 0.0};
  double weight = 1.0;
};

GlareCrop make_crop(const data::PerspectiveCrop& crop, bool visible, const glm::dvec3& sun, bool keep_ldr) {
  GlareCrop g;
  const Tensor ldr = data::to_ldr(crop.image, 1.0).contiguous();
  g.input = train::glare_input(ldr);
  if (keep_ldr) g.ldr = ldr;
  g.camera = crop.camera;
  g.sun = sun;
  if (visible) {
    const render::Projection pr = crop.camera.project(crop.camera.position() + 1e3 * sun);
    if (pr.in_image) g.sun_pixel = pr.pixel;
  }
  return g;
}

std::vector<GlareCrop> panorama_crops(const std::string& dir, const data::SunLabels& labels,
                                      const std::vector<std::string>& names, int aimed, int near, int random,
                                      uint64_t seed, bool keep_ldr) {
  std::vector<std::vector<GlareCrop>> per(names.size());
#pragma omp parallel for schedule(dynamic, 1)
  for (int64_t i = 0; i < int64_t(names.size()); ++i) {
    const data::PanoramaSunLabel* l = labels.find(names[size_t(i)]);
    if (!l) continue;
    const Tensor pano = read_ldr_panorama_radiance((std::filesystem::path(dir) / l->file).string());
    const bool visible = l->has_position && l->sun == data::SunVisibility::Visible;
    const glm::dvec3 d = l->has_position ? labels.direction(*l, int(pano.size(2)), int(pano.size(1))) : glm::dvec3(0, 1, 0);
    const double az = std::atan2(d.x, -d.z), el = std::asin(std::clamp(d.y, -1.0, 1.0));
    const uint64_t s = hash_counter(seed, std::hash<std::string>{}(l->file));
    const double w = l->confidence == data::LabelConfidence::Low ? 0.5 : 1.0;
    int k = 0;
    auto params = [&](double yaw_offset_halves, double pitch_offset_halves, bool at_sun) {
      data::PerspectiveCropParams cp;
      cp.horizontal_fov_rad = (50.0 + 30.0 * uniform01(s, uint64_t(k), 0)) * kDegToRad;
      const double half_h = 0.5 * cp.horizontal_fov_rad, half_v = std::atan(std::tan(half_h) * cp.height / cp.width);
      if (at_sun) {
        cp.yaw_rad = az + yaw_offset_halves * half_h;
        cp.pitch_rad = std::clamp(el + pitch_offset_halves * half_v, -1.2, 1.2);
      } else {
        cp.yaw_rad = 2.0 * kPi * uniform01(s, uint64_t(k), 1);
        cp.pitch_rad = (-5.0 + 30.0 * uniform01(s, uint64_t(k), 2)) * kDegToRad;
      }
      return cp;
    };
    if (visible) {
      for (int a = 0; a < aimed; ++a, ++k) {
        const auto cp = params(0.8 * (2.0 * uniform01(s, uint64_t(k), 1) - 1.0), 0.8 * (2.0 * uniform01(s, uint64_t(k), 2) - 1.0), true);
        per[size_t(i)].push_back(make_crop(data::crop_perspective(pano, cp), true, d, keep_ldr));
        per[size_t(i)].back().weight = w;
      }
      for (int a = 0; a < near; ++a, ++k) {
        const double side = uniform01(s, uint64_t(k), 3) < 0.5 ? -1.0 : 1.0;
        const auto cp = params(side * (1.1 + 0.5 * uniform01(s, uint64_t(k), 1)), 0.6 * (2.0 * uniform01(s, uint64_t(k), 2) - 1.0), true);
        per[size_t(i)].push_back(make_crop(data::crop_perspective(pano, cp), true, d, keep_ldr));
      }
    }
    for (int a = 0; a < random; ++a, ++k) {
      const auto cp = params(0, 0, false);
      per[size_t(i)].push_back(make_crop(data::crop_perspective(pano, cp), visible, d, keep_ldr));
      if (per[size_t(i)].back().sun_pixel) per[size_t(i)].back().weight = w;
    }
  }
  std::vector<GlareCrop> out;
  for (auto& v : per)
    for (auto& c : v) out.push_back(std::move(c));
  return out;
}

// The benchmark's own crops of a folder's split (LDR panoramas or HDR skies).
std::vector<GlareCrop> benchmark_crops(const std::string& dir, const std::string& split_file, const std::string& split,
                                       int crops, bool keep_ldr) {
  const bool ldr = train::is_ldr_panorama_folder(dir);
  const train::RealSkyFolder f =
      ldr ? train::load_ldr_panorama_folder(dir, (std::filesystem::path(dir) / "sun_labels.csv").string(), split_file, split, crops)
          : train::load_hdr_sky_folder(dir, split_file, split, crops);
  std::vector<GlareCrop> out;
  for (const train::RealSkyCrop& c : f.test) {
    if (c.sample.views.empty()) continue;
    const data::StreetView& v = c.sample.views[0];
    GlareCrop g;
    g.input = train::glare_input(v.ldr);
    if (keep_ldr) g.ldr = v.ldr;
    g.camera = v.camera;
    g.sun = c.sample.sun_direction;
    // An LDR panorama's occluded sun is not a glare in view.
    const bool glare = c.sun_known && c.sun_in_crop && (!ldr || c.label_sun == "visible");
    if (glare) {
      const render::Projection pr = v.camera.project(v.camera.position() + 1e3 * c.sample.sun_direction);
      if (pr.in_image) g.sun_pixel = pr.pixel;
    }
    out.push_back(std::move(g));
  }
  return out;
}

std::vector<std::string> split_list(const std::string& split_file, const std::string& split) {
  std::ifstream in(split_file);
  SL_CHECK(in.good(), "sun-glare: cannot read split file '", split_file, "'");
  const nlohmann::json j = nlohmann::json::parse(in, nullptr, false);
  SL_CHECK(!j.is_discarded() && j.contains(split) && j[split].is_array(), "sun-glare: '", split_file, "' has no list '",
           split, "'");
  std::vector<std::string> out;
  for (const auto& n : j[split]) out.push_back(n.get<std::string>());
  return out;
}

// x mirrored along dimension `dim` (data only, not recorded for gradients).
Tensor mirror(const Tensor& x, int64_t dim) {
  std::vector<int64_t> idx(size_t(x.size(dim)));
  for (size_t k = 0; k < idx.size(); ++k) idx[k] = int64_t(idx.size() - 1 - k);
  return index_select(x, dim, Tensor::from_indices(idx, {int64_t(idx.size())})).contiguous();
}

Tensor batch_logits(train::SunGlareDetector& net, const std::vector<GlareCrop>& crops, size_t begin, size_t end) {
  TensorList xs;
  for (size_t i = begin; i < end; ++i) xs.push_back(crops[i].input);
  return net.forward(stack(xs, 0));
}

// Scores of the detector (at several thresholds) and of the hand-made cue on one set of crops.
void score(train::SunGlareDetector& net, const std::vector<GlareCrop>& crops, const char* title, FILE* log) {
  std::vector<train::GlareReading> reads(crops.size());
  {
    NoGradGuard ng;
    net.eval();
    for (size_t b = 0; b < crops.size(); b += 64) {
      const size_t e = std::min(crops.size(), b + 64);
      const Tensor l = batch_logits(net, crops, b, e);
      for (size_t i = b; i < e; ++i)
        reads[i] = train::read_glare(select(l, 0, int64_t(i - b)), int(crops[i].camera.intrinsics().height),
                                     int(crops[i].camera.intrinsics().width));
    }
  }
  int in_view = 0, outside = 0;
  for (const GlareCrop& c : crops) (c.sun_pixel ? in_view : outside) += 1;
  std::fprintf(log, "%s: %zu crops, sun in view %d, not %d\n", title, crops.size(), in_view, outside);
  auto row = [&](const std::string& name, const std::function<std::optional<glm::dvec3>(size_t)>& fire) {
    int hit5 = 0, hit10 = 0, far = 0, false_fire = 0;
    for (size_t i = 0; i < crops.size(); ++i) {
      const auto d = fire(i);
      if (!d) continue;
      if (crops[i].sun_pixel) {
        const double e = train::angular_error_deg(*d, crops[i].sun);
        hit5 += e <= 5.0, hit10 += e <= 10.0, far += e > 10.0;
      } else {
        ++false_fire;
      }
    }
    std::fprintf(log, "  %-34s within 5 deg %4d, within 10 %4d of %4d, farther %3d; false fires %4d of %5d\n",
                 name.c_str(), hit5, hit10, in_view, far, false_fire, outside);
  };
  const bool have_ldr = !crops.empty() && crops[0].ldr.defined();
  auto hand = [&](size_t i) -> std::optional<glm::dvec3> {
    const data::VisibleSun s = data::find_visible_sun(crops[i].ldr, crops[i].camera);
    if (!s.found) return std::nullopt;
    return s.direction;
  };
  auto detector = [&](size_t i, double tau) -> std::optional<glm::dvec3> {
    if (reads[i].p_sun < tau) return std::nullopt;
    return crops[i].camera.ray(reads[i].pixel.x, reads[i].pixel.y).direction;
  };
  if (have_ldr) row("the disk test alone", hand);
  for (double tau : {0.5, 0.8, 0.9, 0.95, 0.98, 0.99}) {
    char name[64];
    std::snprintf(name, sizeof name, "detector p >= %.2f", tau);
    row(name, [&](size_t i) { return detector(i, tau); });
    if (!have_ldr) continue;
    // As LightingEstimator combines them: the disk test first, the detector where it finds nothing.
    row("  the disk test, else the detector", [&](size_t i) {
      const auto h = hand(i);
      return h ? h : detector(i, tau);
    });
  }
  std::fflush(log);
}

int run_sun_glare(const std::vector<std::string>& args) {
  std::string data_dir, split_file, hdr_dir, hdr_split, out, checkpoint;
  int64_t steps = 3000, batch = 32, aimed = 8, near = 3, random = 6, hdr_crops = 16, width = 24;
  double lr = 2e-3;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    auto value = [&]() -> std::string {
      SL_CHECK(i + 1 < args.size(), "sun-glare: ", a, " needs a value");
      return args[++i];
    };
    if (a == "--help" || a == "-h") {
      std::printf(
          "usage: streetlight-bench sun-glare --data DIR --split-file FILE [--hdr-data DIR --hdr-split-file FILE]\n"
          "                                  [--out CKPT | --checkpoint CKPT] [--steps N] [--batch B] [--lr X]\n"
          "                                  [--aimed K] [--near K] [--random K] [--hdr-crops K] [--width W]\n\n"
          "Trains the learned sun-glare detector (train/sun_glare.h) on crops of the TRAIN split of the labelled\n"
          "LDR panoramas DIR: per panorama with a visible sun, --aimed crops aimed at it, --near just beside it and\n"
          "--random at random (defaults 8, 3, 6); --random crops of every other panorama; with --hdr-data, the\n"
          "benchmark's crops of the HDR skies' train split (--hdr-crops each, default 16). Saves it to --out (width\n"
          "--width, default 24). With --checkpoint it loads a saved detector instead (its width from the file).\n"
          "Then scores it beside the visible-sun disk test on the same kinds of crops of the VAL split, and on the\n"
          "benchmark's own val crops: fires within 5 and 10 degrees of a sun in view and false fires, at thresholds\n"
          "0.5 to 0.99, alone and behind the disk test. Test is never read. scripts/train_sun_glare.sh has the\n"
          "released detector's flags.\n");
      return 0;
    }
    if (a == "--data") data_dir = value();
    else if (a == "--split-file") split_file = value();
    else if (a == "--hdr-data") hdr_dir = value();
    else if (a == "--hdr-split-file") hdr_split = value();
    else if (a == "--out") out = value();
    else if (a == "--checkpoint") checkpoint = value();
    else if (a == "--steps") steps = cli::parse_integer("sun-glare: --steps", value(), 0, 10000000);
    else if (a == "--batch") batch = cli::parse_integer("sun-glare: --batch", value(), 1, 4096);
    else if (a == "--aimed") aimed = cli::parse_integer("sun-glare: --aimed", value(), 0, 256);
    else if (a == "--near") near = cli::parse_integer("sun-glare: --near", value(), 0, 256);
    else if (a == "--random") random = cli::parse_integer("sun-glare: --random", value(), 0, 256);
    else if (a == "--hdr-crops") hdr_crops = cli::parse_integer("sun-glare: --hdr-crops", value(), 1, 1024);
    else if (a == "--width") width = cli::parse_integer("sun-glare: --width", value(), 1, 256);
    else if (a == "--lr") {
      const std::string v = value();
      char* end = nullptr;
      lr = std::strtod(v.c_str(), &end);
      SL_CHECK(end && *end == '\0' && std::isfinite(lr) && lr > 0.0, "sun-glare: --lr must be a positive number, got '", v, "'");
    } else SL_CHECK(false, "sun-glare: unknown option '", a, "' (try --help)");
  }
  SL_CHECK(!data_dir.empty() && !split_file.empty(), "sun-glare: --data DIR and --split-file FILE are required");
  SL_CHECK(hdr_dir.empty() == hdr_split.empty(), "sun-glare: --hdr-data and --hdr-split-file go together");
  SL_CHECK(out.empty() != checkpoint.empty(), "sun-glare: give exactly one of --out (train) and --checkpoint (score)");
  const data::SunLabels labels = data::read_sun_labels((std::filesystem::path(data_dir) / "sun_labels.csv").string());

  // Scoring a saved detector takes its width from the file (train::load_sun_glare).
  std::shared_ptr<train::SunGlareDetector> held =
      checkpoint.empty() ? std::make_shared<train::SunGlareDetector>(train::SunGlareOptions{.width = width, .seed = 1})
                         : train::load_sun_glare(checkpoint);
  train::SunGlareDetector& net = *held;
  if (checkpoint.empty()) {
    auto t0 = std::chrono::steady_clock::now();
    std::vector<GlareCrop> crops =
        panorama_crops(data_dir, labels, split_list(split_file, "train"), int(aimed), int(near), int(random), 0x676c617265ULL, false);
    if (!hdr_dir.empty())
      for (GlareCrop& c : benchmark_crops(hdr_dir, hdr_split, "train", int(hdr_crops), false)) crops.push_back(std::move(c));
    int pos = 0;
    for (const GlareCrop& c : crops) pos += bool(c.sun_pixel);
    std::fprintf(stderr, "sun-glare: %zu training crops (%d with the sun in view) in %.0f s\n", crops.size(), pos,
                 std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    std::vector<Tensor> targets(crops.size());
    for (size_t i = 0; i < crops.size(); ++i)
      targets[i] = train::glare_target(crops[i].sun_pixel, int(crops[i].camera.intrinsics().height),
                                       int(crops[i].camera.intrinsics().width));
    net.train();
    nn::Adam opt(net.named_parameters(), {.lr = lr});
    std::vector<size_t> order(crops.size());
    std::iota(order.begin(), order.end(), size_t(0));
    double running = 0.0;
    t0 = std::chrono::steady_clock::now();
    for (int64_t step = 0; step < steps; ++step) {
      // Cosine decay to zero over the run.
      opt.set_lr(lr * 0.5 * (1.0 + std::cos(kPi * double(step) / double(std::max<int64_t>(1, steps)))));
      TensorList xs, ts;
      std::vector<double> ws;
      for (int64_t b = 0; b < batch; ++b) {
        const size_t i = order[size_t(hash_counter(0x7374657073ULL, uint64_t(step), uint64_t(b)) % order.size())];
        Tensor x = crops[i].input, t = targets[i];
        // Mirror half the crops: the cells' columns and the image flip together.
        if (uniform01(0x666c6970ULL, uint64_t(step), uint64_t(b)) < 0.5) {
          x = mirror(x, 2);
          const Tensor cells = reshape(slice(t, 0, 1, train::kGlareOutputs), {train::kGlareRows, train::kGlareCols});
          t = concat({slice(t, 0, 0, 1), reshape(mirror(cells, 1), {train::kGlareRows * train::kGlareCols})}, 0);
        }
        xs.push_back(x);
        ts.push_back(t);
        ws.push_back(crops[i].weight);
      }
      const Tensor logits = net.forward(stack(xs, 0));
      const Tensor loss = train::sun_distribution_loss(logits, stack(ts, 0), Tensor::from_vector(ws, {batch}));
      opt.zero_grad();
      backward(loss);
      opt.step();
      running = step == 0 ? loss.item() : 0.98 * running + 0.02 * loss.item();
      if ((step + 1) % 200 == 0 || step + 1 == steps)
        std::fprintf(stderr, "sun-glare: step %lld/%lld loss %.4f (%.1f steps/s)\n", (long long)(step + 1), (long long)steps,
                     running, double(step + 1) / std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    }
    nlohmann::json cfg = {{"width", width}, {"steps", steps}, {"batch", batch}, {"lr", lr}, {"aimed", aimed},
                          {"near", near}, {"random", random}, {"hdr_crops", hdr_dir.empty() ? 0 : hdr_crops}};
    nn::save_checkpoint(out, net, nullptr, {.stage = "sun_glare", .step = steps, .config_json = cfg.dump()});
    std::fprintf(stderr, "sun-glare: saved %s\n", out.c_str());
  }
  // Validation.
  score(net, panorama_crops(data_dir, labels, split_list(split_file, "val"), int(aimed), int(near), int(random), 0x76616cULL, true),
        "val, generated crops (aimed, near, random)", stdout);
  score(net, benchmark_crops(data_dir, split_file, "val", 8, true), "val, the benchmark's LDR crops (8 per panorama)", stdout);
  if (!hdr_dir.empty())
    score(net, benchmark_crops(hdr_dir, hdr_split, "val", 8, true), "val, the benchmark's HDR crops (8 per sky)", stdout);
  return 0;
}

const Registrar reg("sun-glare", "trains and scores the learned sun-glare detector against the hand-made cue (train/val)",
                    &run_sun_glare);

}  // namespace
}  // namespace sl::bench
