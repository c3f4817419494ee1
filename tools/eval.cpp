// streetlight-eval: the paper's metrics (Sec 4.2, Tables 1-2) for one or more checkpoints on a
// generated street dataset (docs/DATASET.md) or a folder of real HDR panoramas.
//
//   lighting checkpoints: sun direction median/mean angular error (f̂_dir, or the peak of the
//     predicted dome for branches without a sky vector); novel-view LDR PSNR and si-PSNR (all
//     pixels, and pixels whose ray points into the upper hemisphere); on the generator's data,
//     insertion against the path-traced ground truth (PSNR over the object and its shadow
//     region, mean absolute shadow-ratio error); lighting inference time per image.
//   sky-autoencoder checkpoints: sky log-L2 = mean (ln(1 + L̂) − ln(1 + L))² of the
//     reconstructed exposure-normalised dome, and the sun angular error of f_dir.
// Error against run time (--out): the first lighting checkpoint is re-run at several insertion
// budgets (light samples of Eq. 2, shadow rays of Eq. 4); error_time.png plots its shadow-ratio
// error against the ground truth against lighting + insertion time in ms (one line per checkpoint).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "autodiff/ops.h"
#include "autodiff/tape.h"
#include "data/image_io.h"
#include "data/panorama.h"
#include "data/panorama_dataset.h"
#include "data/street_dataset.h"
#include "data/sun_extraction.h"
#include "nn/checkpoint.h"
#include "render/environment_map.h"
#include "render/gltf_loader.h"
#include "render/radiance_query.h"
#include "tools/common/cli.h"
#include "tools/common/plot.h"
#include "train/inference.h"
#include "train/losses.h"
#include "train/metrics.h"
#include "train/photo_insertion.h"
#include "train/sky_autoencoder.h"
#include "train/train_config.h"

namespace fs = std::filesystem;
using nlohmann::json;
using namespace sl;
using namespace sl::train;

namespace {

// PSNR / si-PSNR over the pixels where mask > 0.5 (mask [H, W] or empty for all).
struct MaskedPsnr {
  double psnr = 0, si_psnr = 0;
  bool valid = false;
};
MaskedPsnr masked_psnr(const Tensor& pred, const Tensor& truth, const std::vector<char>& mask) {
  const Tensor p = pred.detach().to(DType::F64).contiguous(), t = truth.detach().to(DType::F64).contiguous();
  const int64_t c = p.size(0), n = p.size(1) * p.size(2);
  const double *pp = p.data<double>(), *tp = t.data<double>();
  double pt = 0, pp2 = 0, err = 0, cnt = 0;
  for (int64_t ch = 0; ch < c; ++ch)
    for (int64_t i = 0; i < n; ++i) {
      if (!mask.empty() && !mask[i]) continue;
      const double a = pp[ch * n + i], b = tp[ch * n + i];
      pt += a * b, pp2 += a * a, err += (a - b) * (a - b), cnt += 1;
    }
  MaskedPsnr r;
  if (cnt == 0) return r;
  const double s = pp2 > 0 ? pt / pp2 : 1.0;
  double serr = 0;
  for (int64_t ch = 0; ch < c; ++ch)
    for (int64_t i = 0; i < n; ++i) {
      if (!mask.empty() && !mask[i]) continue;
      const double d = s * pp[ch * n + i] - tp[ch * n + i];
      serr += d * d;
    }
  r.psnr = 10 * std::log10(1.0 / std::max(err / cnt, 1e-10));
  r.si_psnr = 10 * std::log10(1.0 / std::max(serr / cnt, 1e-10));
  r.valid = true;
  return r;
}

// The predicted LDR of a world camera's view (radiance query, Eq. 1) and its upper-hemisphere mask.
std::pair<Tensor, std::vector<char>> render_view(const EstimatedLighting& l, const Camera& world_cam, int rows, int samples) {
  const double scale = static_cast<double>(rows) / world_cam.intrinsics().height;
  const Intrinsics k = world_cam.intrinsics().scaled(scale, scale);
  const Camera cam = l.frame.camera(Camera(k, world_cam.rotation(), world_cam.position()));
  std::vector<double> o, d;
  std::vector<char> upper;
  for (int r = 0; r < k.height; ++r)
    for (int c = 0; c < k.width; ++c) {
      const CameraRay ray = cam.pixel_ray(c, r);
      o.insert(o.end(), {ray.origin.x, ray.origin.y, ray.origin.z});
      d.insert(d.end(), {ray.direction.x, ray.direction.y, ray.direction.z});
      upper.push_back(ray.direction.y > 0);
    }
  const int64_t n = static_cast<int64_t>(upper.size());
  const Tensor origins = Tensor::from_vector(o, {n, 3}).to(DType::F32), dirs = Tensor::from_vector(d, {n, 3}).to(DType::F32);
  Tensor rad;
  if (l.vsg.defined()) {
    RadianceQueryOptions qo;
    qo.samples = samples;
    rad = radiance_query(l.vsg, l.env, origins, dirs, l.grid, qo).radiance;
  } else {
    rad = env_lookup(l.env, dirs);
  }
  return {permute(reshape(ldr_from_hdr(rad), {k.height, k.width, 3}), {2, 0, 1}).contiguous(), upper};
}

struct Budget {
  std::string name;
  PhotoInsertionOptions o;
};

std::vector<Budget> budgets() {
  std::vector<Budget> b;
  for (int s : {4, 16, 64}) {
    PhotoInsertionOptions o;
    o.aa_samples = s >= 16 ? 2 : 1;
    o.light_samples = s;
    o.shadow_rays = 2 * s;
    o.shadow_width = 80;
    o.shadow_height = 45;
    b.push_back({"light " + std::to_string(s) + " / shadow " + std::to_string(2 * s), o});
  }
  return b;
}

struct InsertionScore {
  double psnr = 0, shadow_ratio_error = 0, ms = 0;
  bool valid = false;
};

// Sec 4.3 measured: PSNR over the object ∪ shadow region of the ground truth, and the mean
// absolute error of the shadow ratio S on the region's background pixels.
InsertionScore score_insertion(const EstimatedLighting& l, const StreetSample& s, const Mesh& mesh,
                               const PhotoInsertionOptions& o) {
  const StreetView& v = s.views[0];
  ObjectPose pose{s.object_x, s.object_z, s.object_yaw_deg, s.object_scale};
  const PhotoInsertion ins = insert_into_photo(l, v.ldr, v.depth, v.camera, mesh, pose, o);
  const Tensor with = to_ldr(s.insert_with_object_hdr.contiguous(), s.exposure);
  const Tensor without = to_ldr(s.insert_without_object_hdr.defined() ? s.insert_without_object_hdr.contiguous()
                                                                      : v.hdr.contiguous(), s.exposure);
  const Tensor gm = s.insert_object_mask.contiguous(), sm = ins.shadow_map.contiguous();
  const int64_t n = with.size(1) * with.size(2);
  const float *wp = with.data<float>(), *np = without.data<float>(), *mp = gm.data<float>(), *sp = sm.data<float>();
  std::vector<char> region(n, 0);
  double ratio_err = 0;
  int64_t ratio_n = 0;
  for (int64_t i = 0; i < n; ++i) {
    double lw = 0, ln = 0;
    for (int c = 0; c < 3; ++c) lw += std::pow(wp[c * n + i], 2.2), ln += std::pow(np[c * n + i], 2.2);
    const double true_ratio = ln > 1e-6 ? std::min(lw / ln, 1.5) : 1.0;
    const bool object = mp[i] > 0.5 / 255.0;
    const bool shadow = !object && std::abs(true_ratio - 1.0) > 0.02;
    region[i] = object || shadow || sp[i] < 0.98;
    if (region[i] && !object) ratio_err += std::abs(static_cast<double>(sp[i]) - true_ratio), ++ratio_n;
  }
  InsertionScore r;
  const MaskedPsnr p = masked_psnr(ins.composite_ldr, with, region);
  r.valid = p.valid;
  r.psnr = p.psnr;
  r.shadow_ratio_error = ratio_n ? ratio_err / ratio_n : 0.0;
  r.ms = ins.render_ms;
  return r;
}

json eval_lighting(const std::string& ckpt, const std::string& data, const std::string& split, int64_t limit,
                   int view_rows, std::vector<cli::PlotPoint>* plot, const std::string& label) {
  LightingEstimator est(ckpt);
  std::vector<double> sun_err, ps, sps, ups, usps, ins_psnr, ins_ratio, ms;
  std::map<std::string, std::vector<double>> budget_err, budget_ms;
  const bool street = fs::exists(fs::path(data) / "index.json");
  size_t count = 0;
  if (street) {
    StreetDataset ds(data, split);
    count = limit > 0 ? std::min<size_t>(ds.size(), static_cast<size_t>(limit)) : ds.size();
    std::map<std::string, Mesh> meshes;
    cli::Progress progress("eval", static_cast<int64_t>(count));
    for (size_t i = 0; i < count; ++i) {
      const StreetSample s = ds.load(i);
      const StreetView& v0 = s.views[0];
      const EstimatedLighting l = est.estimate({{v0.ldr, v0.depth, v0.camera}});
      if (i > 0 || count == 1) ms.push_back(l.inference_ms);  // the first call also pays warm-up
      glm::dvec3 dir = l.sun_direction_canonical;
      if (!l.has_sky_code) dir = extract_sun(l.env.contiguous()).direction;
      sun_err.push_back(angular_error_deg(dir, l.frame.direction(s.sun_direction)));
      for (size_t k = 1; k < s.views.size(); ++k) {
        NoGradGuard ng;
        const auto [pred, upper] = render_view(l, s.views[k].camera, view_rows, est.volume_samples());
        const Tensor truth = resize_bilinear(s.views[k].ldr, pred.size(1), pred.size(2));
        const MaskedPsnr all = masked_psnr(pred, truth, {}), up = masked_psnr(pred, truth, upper);
        ps.push_back(all.psnr), sps.push_back(all.si_psnr);
        if (up.valid) ups.push_back(up.psnr), usps.push_back(up.si_psnr);
      }
      if (s.has_insertion && !s.object_glb.empty()) {
        auto it = meshes.find(s.object_glb);
        if (it == meshes.end()) it = meshes.emplace(s.object_glb, to_object_frame_mesh(load_gltf(s.object_glb))).first;
        PhotoInsertionOptions o;
        o.aa_samples = 2, o.light_samples = 32, o.shadow_rays = 64, o.shadow_width = 80, o.shadow_height = 45;
        o.volume_samples = est.volume_samples();
        try {
          const InsertionScore sc = score_insertion(l, s, it->second, o);
          if (sc.valid) ins_psnr.push_back(sc.psnr), ins_ratio.push_back(sc.shadow_ratio_error);
          if (plot)
            for (Budget b : budgets()) {
              b.o.volume_samples = est.volume_samples();
              const InsertionScore bs = score_insertion(l, s, it->second, b.o);
              if (!bs.valid) continue;
              budget_err[b.name].push_back(bs.shadow_ratio_error);
              budget_ms[b.name].push_back(bs.ms + l.inference_ms);
            }
        } catch (const Error& e) {
          std::fprintf(stderr, "eval: sample %s: insertion skipped (%s)\n", s.id.c_str(), e.what());
        }
      }
      progress.update(static_cast<int64_t>(i + 1));
    }
    progress.finish();
  } else {
    PanoramaDataset ds(data);
    count = limit > 0 ? std::min<size_t>(ds.size(), static_cast<size_t>(limit)) : ds.size();
    for (size_t i = 0; i < count; ++i) {
      const PanoramaItem item = ds.load(i, 0);
      const Camera cam = item.crop.crop.camera;
      const Intrinsics& k = cam.intrinsics();
      const EstimatedLighting l = est.estimate({{item.crop_ldr, Tensor::zeros({k.height, k.width}), cam}});
      ms.push_back(l.inference_ms);
      glm::dvec3 dir = l.has_sky_code ? l.sun_direction_canonical : extract_sun(l.env.contiguous()).direction;
      if (item.sun.found) sun_err.push_back(angular_error_deg(dir, l.frame.direction(item.sun.direction)));
      // A novel view: another seeded crop of the same rotated panorama.
      const RandomCrop other = random_perspective_crop(item.pano_hdr, 0, 1000 + i);
      NoGradGuard ng;
      const auto [pred, upper] = render_view(l, other.crop.camera, view_rows, est.volume_samples());
      const Tensor truth = resize_bilinear(to_ldr(other.crop.image.contiguous(), item.exposure), pred.size(1), pred.size(2));
      const MaskedPsnr all = masked_psnr(pred, truth, {}), up = masked_psnr(pred, truth, upper);
      ps.push_back(all.psnr), sps.push_back(all.si_psnr);
      if (up.valid) ups.push_back(up.psnr), usps.push_back(up.si_psnr);
    }
  }
  if (plot) {
    std::vector<std::pair<double, double>> line;
    for (const auto& [name, errs] : budget_err) line.emplace_back(mean_of(budget_ms[name]), mean_of(errs));
    std::sort(line.begin(), line.end());
    for (const auto& [t, e] : line) plot->push_back({label, t, e});
  }
  json r = {{"checkpoint", ckpt}, {"stage", est.stage()}, {"step", est.step()},
            {"sky_branch", est.predictor().options().sky_branch},
            {"volume_branch", est.predictor().options().volume_branch},
            {"images", count},
            {"sun_error_median_deg", median(sun_err)}, {"sun_error_mean_deg", mean_of(sun_err)},
            {"psnr", mean_of(ps)}, {"si_psnr", mean_of(sps)},
            {"psnr_upper", mean_of(ups)}, {"si_psnr_upper", mean_of(usps)},
            {"inference_ms", mean_of(ms)}};
  if (!ins_psnr.empty()) {
    r["insertion_psnr"] = mean_of(ins_psnr);
    r["shadow_ratio_error"] = mean_of(ins_ratio);
    r["insertion_samples"] = ins_psnr.size();
  }
  if (!budget_err.empty()) {
    json b = json::array();
    for (const auto& [name, errs] : budget_err)
      b.push_back({{"budget", name}, {"shadow_ratio_error", mean_of(errs)}, {"ms", mean_of(budget_ms[name])}});
    r["budgets"] = b;
  }
  return r;
}

json eval_sky(const std::string& ckpt, const std::string& data, const std::string& split, int64_t limit) {
  const nn::CheckpointInfo info = nn::read_checkpoint_info(ckpt);
  const json cfg = json::parse(info.config_json);
  SkyAutoencoder ae(sky_options(cfg));
  nn::load_checkpoint(ckpt, ae, nullptr);
  ae.eval();
  NoGradGuard ng;
  const auto& so = ae.options();
  std::vector<double> log_l2, sun_err, ms;
  auto score = [&](const Tensor& pano_ldr, const Tensor& true_hdr, const glm::dvec3& sun) {
    const Tensor in = unsqueeze(resize_area(pano_ldr.contiguous(), static_cast<int>(so.height), static_cast<int>(so.width)), 0);
    const auto t0 = std::chrono::steady_clock::now();
    const SkyAutoencoder::Output o = ae.run(in);
    ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    const Tensor truth = resize_area(true_hdr.contiguous(), static_cast<int>(so.height), static_cast<int>(so.width));
    const Tensor d = sub(log(add_scalar(select(o.sky.hdr, 0, 0), 1.0)), log(add_scalar(truth, 1.0)));
    log_l2.push_back(mean(mul(d, d)).item());
    const Tensor dir = o.code.dir.to(DType::F64).contiguous();
    sun_err.push_back(angular_error_deg({dir.data<double>()[0], dir.data<double>()[1], dir.data<double>()[2]}, sun));
  };
  size_t count = 0;
  if (fs::exists(fs::path(data) / "index.json")) {
    StreetDataset ds(data, split);
    count = limit > 0 ? std::min<size_t>(ds.size(), static_cast<size_t>(limit)) : ds.size();
    for (size_t i = 0; i < count; ++i) {
      const StreetSample s = ds.load(i);
      // The AE sees the full street panorama; its target is the true sky alone (exposure-normalised).
      score(s.pano_ldr, mul_scalar(s.sky_hdr.contiguous(), s.exposure), s.sun_direction);
    }
  } else {
    PanoramaDataset ds(data);
    count = limit > 0 ? std::min<size_t>(ds.size(), static_cast<size_t>(limit)) : ds.size();
    for (size_t i = 0; i < count; ++i) {
      const PanoramaItem item = ds.load(i, 0);
      score(to_ldr(item.pano_hdr.contiguous(), item.exposure), mul_scalar(item.pano_hdr.contiguous(), item.exposure),
            item.sun.direction);
    }
  }
  return {{"checkpoint", ckpt}, {"stage", info.stage}, {"step", info.step}, {"images", count},
          {"sky_log_l2", mean_of(log_l2)}, {"sun_error_median_deg", median(sun_err)},
          {"sun_error_mean_deg", mean_of(sun_err)}, {"inference_ms", mean_of(ms)}};
}

std::string fmt(const json& r, const char* key, int prec = 2) {
  if (!r.contains(key)) return "—";
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", prec, r.at(key).get<double>());
  return b;
}

std::string markdown(const std::vector<json>& rows, const std::vector<std::string>& names) {
  std::ostringstream md;
  bool any_light = false, any_sky = false;
  for (const auto& r : rows) (r.contains("sky_log_l2") ? any_sky : any_light) = true;
  if (any_light) {
    md << "| checkpoint | stage (step) | sun median ° | sun mean ° | PSNR | si-PSNR | PSNR upper | si-PSNR upper | "
          "insertion PSNR | shadow-ratio err | ms/image |\n|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (size_t i = 0; i < rows.size(); ++i) {
      const json& r = rows[i];
      if (r.contains("sky_log_l2")) continue;
      md << "| " << names[i] << " | " << r["stage"].get<std::string>() << " (" << r["step"].get<int64_t>() << ") | "
         << fmt(r, "sun_error_median_deg", 1) << " | " << fmt(r, "sun_error_mean_deg", 1) << " | " << fmt(r, "psnr")
         << " | " << fmt(r, "si_psnr") << " | " << fmt(r, "psnr_upper") << " | " << fmt(r, "si_psnr_upper") << " | "
         << fmt(r, "insertion_psnr") << " | " << fmt(r, "shadow_ratio_error", 3) << " | " << fmt(r, "inference_ms", 0)
         << " |\n";
    }
  }
  if (any_sky) {
    md << (any_light ? "\n" : "")
       << "| checkpoint | step | sky log-L2 | sun median ° | sun mean ° | ms/image |\n|---|---|---|---|---|---|\n";
    for (size_t i = 0; i < rows.size(); ++i) {
      const json& r = rows[i];
      if (!r.contains("sky_log_l2")) continue;
      md << "| " << names[i] << " | " << r["step"].get<int64_t>() << " | " << fmt(r, "sky_log_l2", 4) << " | "
         << fmt(r, "sun_error_median_deg", 1) << " | " << fmt(r, "sun_error_mean_deg", 1) << " | "
         << fmt(r, "inference_ms", 1) << " |\n";
    }
  }
  return md.str();
}

void write_text_atomic(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp);
    f << text;
    SL_CHECK(f.good(), "cannot write '", path, "'");
  }
  fs::rename(tmp, path);
}

int run(int argc, char** argv) {
  cli::Args a("streetlight-eval",
              "streetlight-eval --checkpoint CKPT [--checkpoint CKPT2 ...] --data DIR [--split test] [--out DIR] [--json]\n\n"
              "Evaluates checkpoints with the metrics of Wang et al. ECCV 2022 (Tables 1-2): sun direction angular\n"
              "error, novel-view LDR PSNR / si-PSNR (also upper hemisphere only), sky log-L2 (sky autoencoder),\n"
              "insertion error against the generator's path-traced ground truth, and inference time. DIR is a\n"
              "streetlight-datagen dataset or a folder of HDR panoramas (seeded random crops).",
              {{"--checkpoint", "CKPT", "checkpoint to evaluate (one table row each)", true},
               {"--name", "NAME", "row name for the matching --checkpoint (default: its file path)", true},
               {"--data", "DIR", "street dataset (index.json) or folder of .hdr/.exr panoramas"},
               {"--split", "NAME", "dataset split (default test)"},
               {"--limit", "N", "evaluate at most N images (default all)"},
               {"--view-rows", "N", "rows at which novel views are rendered (default 32)"},
               {"--no-budgets", "", "skip the error-against-time sweep"},
               {"--out", "DIR", "write results.json, results.md and error_time.png here"},
               {"--json", "", "print the results as one JSON object on stdout"}});
  if (!a.parse(argc, argv)) return 0;
  const auto ckpts = a.all("--checkpoint");
  SL_CHECK(!ckpts.empty(), "--checkpoint CKPT is required");
  SL_CHECK(a.has("--data"), "--data DIR is required");
  const std::string data = a.get("--data"), split = a.get("--split", "test");
  SL_CHECK(fs::is_directory(data), "--data '", data, "' is not a folder");
  std::vector<std::string> names = a.all("--name");
  SL_CHECK(names.empty() || names.size() == ckpts.size(), "give one --name per --checkpoint (", ckpts.size(),
           " checkpoints, ", names.size(), " names)");
  if (names.empty()) names = ckpts;
  const int64_t limit = a.integer("--limit", 0);
  const int rows = static_cast<int>(a.integer("--view-rows", 32));
  SL_CHECK(rows > 0, "--view-rows must be positive");
  for (const auto& c : ckpts) nn::read_checkpoint_info(c);  // fail early on a bad file
  std::vector<json> results;
  std::vector<cli::PlotPoint> plot;
  bool plotted = false;
  for (size_t i = 0; i < ckpts.size(); ++i) {
    const std::string stage = nn::read_checkpoint_info(ckpts[i]).stage;
    if (stage == kStageSky) {
      results.push_back(eval_sky(ckpts[i], data, split, limit));
    } else {
      const bool want_plot = !plotted && a.has("--out") && !a.has("--no-budgets");
      results.push_back(eval_lighting(ckpts[i], data, split, limit, rows, want_plot ? &plot : nullptr, names[i]));
      plotted = plotted || want_plot;
    }
    results.back()["name"] = names[i];
  }
  const std::string md = markdown(results, names);
  const json all = {{"data", data}, {"split", split}, {"results", results}};
  if (a.has("--out")) {
    const std::string out = a.get("--out");
    fs::create_directories(out);
    write_text_atomic((fs::path(out) / "results.json").string(), all.dump(2) + "\n");
    write_text_atomic((fs::path(out) / "results.md").string(), md);
    if (!plot.empty()) {
      ImageWriteOptions lin;
      lin.transfer = Transfer::Linear;
      write_image((fs::path(out) / "error_time.png").string(), cli::error_time_plot(plot), lin);
    }
  }
  if (a.has("--json")) std::cout << all.dump() << "\n";
  else std::cout << md;
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return sl::cli::run_main([&] { return run(argc, argv); });
}
