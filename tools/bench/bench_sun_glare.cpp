// streetlight-bench sun-glare: trains the learned sun-glare detector (train/sun_glare.h) on crops of
// the TRAIN split and scores it, beside the hand-made cue (data/visible_sun.h), on crops of the
// VALIDATION split: how often it fires within 5° of a sun in view, how often it fires where no sun
// is in view, at several thresholds. `--score-split train` scores on new crops of the training
// panoramas instead (how well it fits what it learned from). Test is never read.
//
// The crops (tools/bench/sun_glare_crops.h): per labelled LDR panorama with a visible sun, crops
// aimed at it, just beside it, level crops toward it, and random crops; random crops of every other
// panorama; with --hdr-data, the benchmark's own crops of the HDR skies (as streetlight-eval draws
// them) and, with --hdr-sun-crops, crops toward each hard HDR sun at many exposures. The validation
// score adds the benchmark's own crops of the validation LDR panoramas (8 each) and 32 level crops
// toward each validation sun.
// With --azimuth-bins, the detector's azimuth head (front and back) trains on the random crops of
// every panorama whose sun position is known (plus --azimuth-crops more of each) and on the HDR
// crops, and is scored on the val crops with a known sun: the share put in the right half, and how
// many of its hidden units are alive.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <numeric>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "autodiff/ops.h"
#include "data/hdri_split.h"
#include "data/image_io.h"
#include "data/panorama.h"
#include "data/sun_labels.h"
#include "data/visible_sun.h"
#include "nn/checkpoint.h"
#include "nn/optim.h"
#include "tools/bench/bench.h"
#include "tools/bench/sun_glare_crops.h"
#include "tools/common/cli.h"
#include "train/metrics.h"
#include "train/real_sky_benchmark.h"
#include "train/street_batch.h"
#include "train/sun_distribution.h"
#include "train/sun_glare.h"
#include "train/trainer.h"
#include "util/error.h"
#include "util/math.h"
#include "util/process_memory.h"
#include "util/random.h"

namespace sl::bench {
namespace {

std::vector<std::string> split_list(const std::string& split_file, const std::string& split) {
  return data::read_hdri_split(split_file).split_names(split);
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

// How many of the azimuth head's hidden units are positive on at least one of the inputs ([4, 64, 128]
// each), and how many it has.
std::pair<int, int> azimuth_units_alive(train::SunGlareDetector& net, const std::vector<Tensor>& inputs) {
  NoGradGuard ng;
  std::vector<bool> alive;
  for (size_t b = 0; b < inputs.size(); b += 64) {
    const TensorList xs(inputs.begin() + std::ptrdiff_t(b), inputs.begin() + std::ptrdiff_t(std::min(inputs.size(), b + 64)));
    const Tensor h = net.azimuth_hidden(stack(xs, 0)).to(DType::F64).contiguous();
    alive.resize(size_t(h.size(1)), false);
    const std::vector<double> v = h.to_vector();
    for (size_t i = 0; i < v.size(); ++i) alive[i % alive.size()] = alive[i % alive.size()] || v[i] > 0.0;
  }
  return {int(std::count(alive.begin(), alive.end(), true)), int(alive.size())};
}

// The azimuth head on the crops whose sun's azimuth is known (flip-averaged, as LightingEstimator
// reads it): the share in the right half (in front of the camera or behind it), against always
// answering the more common half; the median azimuth error of its most probable sector's centre.
void score_azimuth(train::SunGlareDetector& net, const std::vector<GlareCrop>& crops, FILE* log) {
  const int64_t a = net.options().azimuth_bins;
  int known = 0, right = 0, front = 0;
  std::vector<double> errors;
  NoGradGuard ng;
  net.eval();
  for (const GlareCrop& c : crops) {
    if (!c.azimuth) continue;
    // Flip-averaged, as the estimator reads it.
    const std::vector<double> q = train::read_glare_flip_averaged(net, c.input, 1, 1).azimuth;
    double p_front = 0.0;
    size_t best = 0;
    for (size_t j = 0; j < q.size(); ++j) {
      const double centre = -kPi + (double(j) + 0.5) * 2.0 * kPi / double(a);
      if (std::abs(centre) < 0.5 * kPi) p_front += q[j];
      if (q[j] > q[best]) best = j;
    }
    const bool truth_front = std::abs(*c.azimuth) < 0.5 * kPi;
    ++known;
    front += truth_front;
    right += (p_front >= 0.5) == truth_front;
    const double centre = -kPi + (double(best) + 0.5) * 2.0 * kPi / double(a);
    errors.push_back(std::abs(std::remainder(centre - *c.azimuth, 2.0 * kPi)) / kDegToRad);
  }
  if (known == 0) return;
  std::sort(errors.begin(), errors.end());
  // A head whose hidden units are all dead answers one constant, whatever the crop.
  std::vector<Tensor> inputs;
  for (const GlareCrop& c : crops)
    if (c.azimuth) inputs.push_back(c.input);
  const auto [alive, units] = azimuth_units_alive(net, inputs);
  std::fprintf(log, "  azimuth head: %d crops with a known sun; right half %.3f (the more common half alone %.3f); "
               "median azimuth error of the mode %.1f deg; hidden units alive %d of %d%s\n",
               known, double(right) / known, double(std::max(front, known - front)) / known, errors[errors.size() / 2], alive,
               units, alive == 0 ? " (DEAD: it answers one constant)" : "");
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
  if (net.has_azimuth()) score_azimuth(net, crops, log);
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
  std::string data_dir, split_file, hdr_dir, hdr_split, out, checkpoint, score_split = "val", train_split = "train";
  int64_t steps = 3000, batch = 32, aimed = 8, near = 3, random = 6, hdr_crops = 16, width = 24, level = 0;
  double aimed_span = 0.8, hdr_sun_exposure = 2.0, low_sun_weight = 1.0, low_sun_below = 30.0;
  int64_t hdr_sun_k = 0;
  int64_t azimuth_bins = 0, azimuth_crops = 0, checkpoint_every = 500, stop_at = 0;
  double lr = 2e-3, azimuth_loss = 1.0, azimuth_width = 20.0, azimuth_slope = 0.0;
  Jitter jitter;
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
          "                                  [--aimed K] [--near K] [--random K] [--level-aimed K] [--aimed-span X]\n"
          "                                  [--hdr-crops K] [--hdr-sun-crops K] [--hdr-sun-exposure S]\n"
          "                                  [--low-sun-weight W] [--low-sun-below DEG] [--width W]\n"
          "                                  [--azimuth-bins A] [--azimuth-crops K] [--azimuth-loss X] [--azimuth-width DEG]\n"
          "                                  [--score-split val|train] [--jitter-exposure S] [--jitter-white-balance S]\n"
          "                                  [--jitter-tone S] [--train-split train|train+val]\n"
          "                                  [--checkpoint-every N] [--stop-at STEP]\n\n"
          "Trains the learned sun-glare detector (train/sun_glare.h) on crops of the TRAIN split of the labelled\n"
          "LDR panoramas DIR: per panorama with a visible sun, --aimed crops aimed at it, --near just beside it and\n"
          "--random at random (defaults 8, 3, 6), and --level-aimed level crops toward it (default 0: the benchmark's\n"
          "pitch range, the sun anywhere across the view's width, edges included); --aimed-span X: the aimed crops\n"
          "put the sun within the middle X of the view's width and height (default 0.8; 1: up to the edges);\n"
          "--random crops of every other panorama; with --hdr-data, the benchmark's crops of the HDR skies' train\n"
          "split (--hdr-crops each, default 16). Saves it to --out (width --width, default 24). With --checkpoint it\n"
          "loads a saved detector instead (its width from the file).\n"
          "Then scores it beside the visible-sun disk test on the same kinds of crops of the VAL split, on the\n"
          "benchmark's own val crops and on 32 level crops toward each val sun: fires within 5 and 10 degrees of a\n"
          "sun in view and false fires, at thresholds\n"
          "0.5 to 0.99, alone and behind the disk test. --score-split train scores on new crops of the TRAIN split\n"
          "instead (how well it fits the panoramas it learned from). Test is never read. scripts/train_sun_glare.sh\n"
          "has the released detector's flags. --train-split train+val trains on the validation places too (a final\n"
          "model whose recipe is fixed; it is then scored with --score-split train).\n\n"
          "--azimuth-bins A (default 0: none) adds the azimuth head: where the sun is in azimuth, in view or not,\n"
          "trained on every crop whose sun position is known by cross-entropy (weight --azimuth-loss, default 1)\n"
          "against a Gaussian of --azimuth-width degrees (default 20), weighted by cos(elevation); --azimuth-crops K\n"
          "more random crops of each panorama with a known sun (default 0). Its score: the share of val crops put in\n"
          "the right half (in front of the camera or behind it), the median azimuth error of its mode, and how many of\n"
          "its hidden units are alive on those crops (none: the head answers one constant). Training logs the count\n"
          "on its batch and warns when it reaches 0. --azimuth-slope S (default 0: ReLU) gives the head's hidden\n"
          "layer a leaky ReLU of negative slope S, whose units keep a gradient and so cannot die for good.\n\n"
          "Low suns (the only suns the benchmark's level views show): --hdr-sun-crops K (default 0) adds K crops toward\n"
          "the sun of each training HDR sky whose sun is hard, alternately aimed at it and level, each at the\n"
          "benchmark's exposure times 2^s, s uniform in +-S stops (--hdr-sun-exposure, default 2); --low-sun-weight W\n"
          "(default 1) multiplies the loss weight of every training crop whose sun is in view below --low-sun-below\n"
          "degrees of elevation (default 30).\n\n"
          "--jitter-exposure, --jitter-white-balance, --jitter-tone S (stops, default 0: off) give each training crop\n"
          "its own exposure, white balance and tone curve, uniform in ±S (pixels clipped in every channel kept).\n\n"
          "Training is resumable: every --checkpoint-every steps (default 500), on SIGINT or SIGTERM and at\n"
          "--stop-at STEP, the detector and its optimiser are saved to OUT.partial.safetensors; the same command\n"
          "then continues from there, bit-identically (same thread count), and refuses other flags. The file is\n"
          "removed once OUT is written.\n");
      return 0;
    }
    if (a == "--data") data_dir = value();
    else if (a == "--split-file") split_file = value();
    else if (a == "--hdr-data") hdr_dir = value();
    else if (a == "--hdr-split-file") hdr_split = value();
    else if (a == "--out") out = value();
    else if (a == "--checkpoint") checkpoint = value();
    else if (a == "--score-split") {
      score_split = value();
      SL_CHECK(score_split == "val" || score_split == "train", "sun-glare: --score-split must be val or train, got '",
               score_split, "' (test is never read)");
    }
    else if (a == "--train-split") {
      train_split = value();
      SL_CHECK(train_split == "train" || train_split == "train+val", "sun-glare: --train-split must be train or train+val, got '",
               train_split, "'");
    }
    else if (a == "--steps") steps = cli::parse_integer("sun-glare: --steps", value(), 0, 10000000);
    else if (a == "--checkpoint-every") checkpoint_every = cli::parse_integer("sun-glare: --checkpoint-every", value(), 1, 10000000);
    else if (a == "--stop-at") stop_at = cli::parse_integer("sun-glare: --stop-at", value(), 1, 10000000);
    else if (a == "--batch") batch = cli::parse_integer("sun-glare: --batch", value(), 1, 4096);
    else if (a == "--aimed") aimed = cli::parse_integer("sun-glare: --aimed", value(), 0, 256);
    else if (a == "--level-aimed") level = cli::parse_integer("sun-glare: --level-aimed", value(), 0, 256);
    else if (a == "--aimed-span") aimed_span = cli::parse_number("sun-glare: --aimed-span", value(), 1e-3, 1.0);
    else if (a == "--hdr-sun-crops") hdr_sun_k = cli::parse_integer("sun-glare: --hdr-sun-crops", value(), 0, 1024);
    else if (a == "--hdr-sun-exposure") hdr_sun_exposure = cli::parse_number("sun-glare: --hdr-sun-exposure", value(), 0.0, 8.0);
    else if (a == "--low-sun-weight") low_sun_weight = cli::parse_number("sun-glare: --low-sun-weight", value(), 0.0, 100.0);
    else if (a == "--low-sun-below") low_sun_below = cli::parse_number("sun-glare: --low-sun-below", value(), 0.0, 90.0);
    else if (a == "--near") near = cli::parse_integer("sun-glare: --near", value(), 0, 256);
    else if (a == "--random") random = cli::parse_integer("sun-glare: --random", value(), 0, 256);
    else if (a == "--hdr-crops") hdr_crops = cli::parse_integer("sun-glare: --hdr-crops", value(), 1, 1024);
    else if (a == "--width") width = cli::parse_integer("sun-glare: --width", value(), 1, 256);
    else if (a == "--azimuth-bins") azimuth_bins = cli::parse_integer("sun-glare: --azimuth-bins", value(), 0, 360);
    else if (a == "--azimuth-crops") azimuth_crops = cli::parse_integer("sun-glare: --azimuth-crops", value(), 0, 256);
    else if (a == "--azimuth-loss") azimuth_loss = cli::parse_number("sun-glare: --azimuth-loss", value(), 1e-6, 1e6);
    else if (a == "--azimuth-slope") azimuth_slope = cli::parse_number("sun-glare: --azimuth-slope", value(), 0.0, 0.5);
    else if (a == "--azimuth-width") azimuth_width = cli::parse_number("sun-glare: --azimuth-width", value(), 1e-3, 360.0);
    else if (a == "--jitter-exposure") jitter.exposure = cli::parse_number("sun-glare: --jitter-exposure", value(), 0.0, 4.0);
    else if (a == "--jitter-white-balance")
      jitter.white_balance = cli::parse_number("sun-glare: --jitter-white-balance", value(), 0.0, 4.0);
    else if (a == "--jitter-tone") jitter.tone = cli::parse_number("sun-glare: --jitter-tone", value(), 0.0, 4.0);
    else if (a == "--lr") lr = cli::parse_number("sun-glare: --lr", value(), 1e-9, 10.0);
    else SL_CHECK(false, "sun-glare: unknown option '", a, "' (try --help)");
  }
  SL_CHECK(!data_dir.empty() && !split_file.empty(), "sun-glare: --data DIR and --split-file FILE are required");
  SL_CHECK(hdr_dir.empty() == hdr_split.empty(), "sun-glare: --hdr-data and --hdr-split-file go together");
  SL_CHECK(hdr_sun_k == 0 || !hdr_dir.empty(), "sun-glare: --hdr-sun-crops needs --hdr-data and --hdr-split-file");
  SL_CHECK(out.empty() != checkpoint.empty(), "sun-glare: give exactly one of --out (train) and --checkpoint (score)");
  SL_CHECK(train_split == "train" || score_split != "val",
           "sun-glare: --score-split val scores on panoramas that --train-split train+val trains on (use --score-split train)");
  const data::SunLabels labels = data::read_sun_labels((std::filesystem::path(data_dir) / "sun_labels.csv").string());

  // Scoring a saved detector takes its width from the file (train::load_sun_glare).
  std::shared_ptr<train::SunGlareDetector> held =
      checkpoint.empty() ? std::make_shared<train::SunGlareDetector>(
                               train::SunGlareOptions{.width = width, .azimuth_bins = azimuth_bins, .azimuth_slope = azimuth_slope, .seed = 1})
                         : train::load_sun_glare(checkpoint);
  train::SunGlareDetector& net = *held;
  if (checkpoint.empty()) {
    // Every flag that shapes the trained detector; a partial checkpoint resumes only under the same ones.
    nlohmann::json cfg = {{"width", width}, {"steps", steps}, {"batch", batch}, {"lr", lr}, {"aimed", aimed},
                          {"near", near}, {"random", random}, {"hdr_crops", hdr_dir.empty() ? 0 : hdr_crops}};
    if (jitter.on()) cfg["jitter"] = {{"exposure", jitter.exposure}, {"white_balance", jitter.white_balance}, {"tone", jitter.tone}};
    if (azimuth_bins > 0) {
      cfg["azimuth_bins"] = azimuth_bins;
      cfg["azimuth_crops"] = azimuth_crops;
      cfg["azimuth_loss"] = azimuth_loss;
      cfg["azimuth_width"] = azimuth_width;
      if (azimuth_slope > 0.0) cfg["azimuth_slope"] = azimuth_slope;
    }
    if (train_split != "train") cfg["train_split"] = train_split;
    if (level > 0) cfg["level_aimed"] = level;
    if (aimed_span != 0.8) cfg["aimed_span"] = aimed_span;
    if (hdr_sun_k > 0) cfg["hdr_sun"] = {{"crops", hdr_sun_k}, {"exposure_stops", hdr_sun_exposure}};
    if (low_sun_weight != 1.0) cfg["low_sun"] = {{"weight", low_sun_weight}, {"below_deg", low_sun_below}};
    // Resume: the crops are a pure function of the flags, each step's batch and rate of its index.
    const std::string partial = out + ".partial.safetensors";
    const bool resuming = std::filesystem::exists(partial);
    if (resuming) {
      const nlohmann::json saved = nlohmann::json::parse(nn::read_checkpoint_info(partial).config_json);
      for (const auto& [key, v] : cfg.items())
        SL_CHECK(saved.contains(key) && saved.at(key) == v, "sun-glare: ", partial, " was trained with ", key, " = ",
                 saved.contains(key) ? saved.at(key).dump() : std::string("(none)"), ", this command has ", v.dump(),
                 " (run the same command to resume, or remove the file)");
      for (const auto& [key, v] : saved.items())
        SL_CHECK(cfg.contains(key), "sun-glare: ", partial, " was trained with ", key, " = ", v.dump(),
                 ", this command has none (run the same command to resume, or remove the file)");
    }
    auto t0 = std::chrono::steady_clock::now();
    std::vector<GlareCrop> crops =
        panorama_crops(data_dir, labels, split_list(split_file, train_split), int(aimed), int(near), int(random), 0x676c617265ULL, false,
                       int(azimuth_crops), jitter, int(level), aimed_span);
    if (!hdr_dir.empty())
      for (GlareCrop& c : benchmark_crops(hdr_dir, hdr_split, train_split, int(hdr_crops), false, jitter)) crops.push_back(std::move(c));
    if (hdr_sun_k > 0) {
      const std::vector<GlareCrop> toward = hdr_sun_crops(hdr_dir, split_list(hdr_split, train_split), int(hdr_sun_k),
                                                          hdr_sun_exposure, 0x6864727375ULL, jitter);
      int shown = 0;
      for (const GlareCrop& c : toward) shown += bool(c.sun_pixel);
      std::fprintf(stderr, "sun-glare: %zu crops toward the suns of %zu hard HDR skies, %d with the sun in view\n", toward.size(),
                   toward.size() / size_t(hdr_sun_k), shown);
      crops.insert(crops.end(), toward.begin(), toward.end());
    }
    const int low = weigh_low_suns(crops, low_sun_weight, low_sun_below);
    std::fprintf(stderr, "sun-glare: %d training crops show a sun below %.0f deg (weight x%g)\n", low, low_sun_below, low_sun_weight);
    int pos = 0;
    for (const GlareCrop& c : crops) pos += bool(c.sun_pixel);
    // The decoded panoramas' pages, freed between the kept crops, go back to the system.
    release_free_heap();
    std::fprintf(stderr, "sun-glare: %zu training crops (%d with the sun in view) in %.0f s; %.1f GB resident\n", crops.size(),
                 pos, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), double(resident_bytes()) / 1e9);
    std::vector<Tensor> targets(crops.size()), azimuth_targets(crops.size());
    for (size_t i = 0; i < crops.size(); ++i) {
      targets[i] = train::glare_target(crops[i].sun_pixel, int(crops[i].camera.intrinsics().height),
                                       int(crops[i].camera.intrinsics().width));
      if (azimuth_bins > 0)
        azimuth_targets[i] = crops[i].azimuth ? Tensor::from_vector(train::azimuth_target(azimuth_bins, *crops[i].azimuth, azimuth_width),
                                                                    {azimuth_bins}).to(DType::F32)
                                              : Tensor::zeros({azimuth_bins}, DType::F32);
    }
    net.train();
    nn::Adam opt(net.named_parameters(), {.lr = lr});
    int64_t first = 0;
    if (resuming) {
      first = nn::load_checkpoint(partial, net, &opt).step;
      std::fprintf(stderr, "sun-glare: resuming from %s at step %lld\n", partial.c_str(), (long long)first);
    }
    auto save_partial = [&](int64_t done) {
      nn::save_checkpoint(partial, net, &opt, {.stage = "sun_glare_partial", .step = done, .config_json = cfg.dump()});
    };
    train::install_stop_handlers();
    std::vector<size_t> order(crops.size());
    std::iota(order.begin(), order.end(), size_t(0));
    double running = 0.0;
    t0 = std::chrono::steady_clock::now();
    for (int64_t step = first; step < steps; ++step) {
      // Cosine decay to zero over the run.
      opt.set_lr(lr * 0.5 * (1.0 + std::cos(kPi * double(step) / double(std::max<int64_t>(1, steps)))));
      TensorList xs, ts, azs;
      std::vector<double> ws, aws;
      for (int64_t b = 0; b < batch; ++b) {
        const size_t i = order[size_t(hash_counter(0x7374657073ULL, uint64_t(step), uint64_t(b)) % order.size())];
        Tensor x = crops[i].input, t = targets[i];
        // Mirror half the crops: the cells' columns and the image flip together.
        const bool mirrored = uniform01(0x666c6970ULL, uint64_t(step), uint64_t(b)) < 0.5;
        if (mirrored) {
          x = mirror(x, 2);
          const Tensor cells = reshape(slice(t, 0, 1, train::kGlareOutputs), {train::kGlareRows, train::kGlareCols});
          t = concat({slice(t, 0, 0, 1), reshape(mirror(cells, 1), {train::kGlareRows * train::kGlareCols})}, 0);
        }
        xs.push_back(x);
        ts.push_back(t);
        ws.push_back(crops[i].weight);
        if (azimuth_bins > 0) {
          azs.push_back(mirrored ? Tensor::from_vector(train::mirror_sectors(azimuth_targets[i].to_vector()), {azimuth_bins}).to(DType::F32)
                                 : azimuth_targets[i]);
          aws.push_back(crops[i].azimuth ? azimuth_loss * crops[i].azimuth_weight : 0.0);
        }
      }
      const train::GlareHeads heads = net.forward_heads(stack(xs, 0));
      Tensor loss = train::sun_distribution_loss(heads.glare, stack(ts, 0), Tensor::from_vector(ws, {batch}));
      if (azimuth_bins > 0)
        loss = add(loss, train::sun_distribution_loss(heads.azimuth, stack(azs, 0), Tensor::from_vector(aws, {batch})));
      opt.zero_grad();
      backward(loss);
      opt.step();
      running = step == first ? loss.item() : 0.98 * running + 0.02 * loss.item();
      if ((step + 1) % 200 == 0 || step + 1 == steps) {
        std::string units;
        if (azimuth_bins > 0) {
          const auto [alive, all] = azimuth_units_alive(net, std::vector<Tensor>(xs.begin(), xs.end()));
          units = "; azimuth units alive on the batch " + std::to_string(alive) + " of " + std::to_string(all);
          if (alive == 0) units += " (warning: the azimuth head is dead, it answers one constant)";
        }
        std::fprintf(stderr, "sun-glare: step %lld/%lld loss %.4f (%.1f steps/s)%s\n", (long long)(step + 1), (long long)steps,
                     running, double(step + 1 - first) / std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(),
                     units.c_str());
      }
      const bool stop = train::stop_requested() || step + 1 == stop_at;
      if (step + 1 < steps && (stop || (step + 1) % checkpoint_every == 0)) save_partial(step + 1);
      if (stop && step + 1 < steps) {
        std::fprintf(stderr, "sun-glare: stopped at step %lld; saved %s (run the same command to resume)\n",
                     (long long)(step + 1), partial.c_str());
        return train::stop_requested() ? 130 : 0;
      }
    }
    std::signal(SIGINT, SIG_DFL);  // scoring below stops at once
    std::signal(SIGTERM, SIG_DFL);
    nn::save_checkpoint(out, net, nullptr, {.stage = "sun_glare", .step = steps, .config_json = cfg.dump()});
    std::filesystem::remove(partial);
    std::fprintf(stderr, "sun-glare: saved %s\n", out.c_str());
  }
  // Validation (or, with --score-split train, new crops of the training panoramas: the seed differs from training's).
  const std::string& sp = score_split;
  score(net, panorama_crops(data_dir, labels, split_list(split_file, sp), int(aimed), int(near), int(random), 0x76616cULL, true),
        (sp + ", generated crops (aimed, near, random)").c_str(), stdout);
  score(net, benchmark_crops(data_dir, split_file, sp, 8, true), (sp + ", the benchmark's LDR crops (8 per panorama)").c_str(), stdout);
  score(net, panorama_crops(data_dir, labels, split_list(split_file, sp), 0, 0, 0, 0x76616cULL, true, 0, {}, 32),
        (sp + ", level crops toward each visible sun (32 per panorama; the benchmark's pitch range)").c_str(), stdout);
  if (!hdr_dir.empty())
    score(net, benchmark_crops(hdr_dir, hdr_split, sp, 8, true), (sp + ", the benchmark's HDR crops (8 per sky)").c_str(), stdout);
  return 0;
}

const Registrar reg("sun-glare", "trains and scores the learned sun-glare detector against the hand-made cue (train/val)",
                    &run_sun_glare);

}  // namespace
}  // namespace sl::bench
