// streetlight-eval's evaluation core (evaluation.h): moved from tools/eval.cpp unchanged, so the
// tool and the Python module's streetlight.evaluate score alike. tools/eval.cpp's header comment
// describes the metrics.
#include "tools/common/evaluation.h"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <sstream>

#include <glm/gtc/matrix_transform.hpp>
#include <nlohmann/json.hpp>

#include "autodiff/ops.h"
#include "autodiff/tape.h"
#include "data/hdri_split.h"
#include "data/image_io.h"
#include "data/panorama.h"
#include "data/panorama_dataset.h"
#include "data/panorama_sample.h"
#include "data/street_dataset.h"
#include "data/sun_extraction.h"
#include "data/sun_labels.h"
#include "nn/checkpoint.h"
#include "render/environment_map.h"
#include "render/equirect.h"
#include "render/gltf_loader.h"
#include "render/radiance_query.h"
#include "tools/common/cli.h"
#include "tools/common/eval_baselines.h"
#include "tools/common/eval_report.h"
#include "tools/common/eval_sun_stats.h"
#include "tools/common/insertion_score.h"
#include "tools/common/plot.h"
#include "train/bootstrap.h"
#include "train/inference.h"
#include "train/losses.h"
#include "train/metrics.h"
#include "train/photo_insertion.h"
#include "train/real_sky_benchmark.h"
#include "train/street_batch.h"
#include "train/sun_confidence.h"
#include "train/sun_error_parts.h"
#include "train/sky_autoencoder.h"
#include "train/train_config.h"
#include "util/file.h"

using sl::data::extract_sun;
using sl::data::ImageWriteOptions;
using sl::data::PerspectiveCropParams;
using sl::data::read_hdri_split;
using sl::data::resize_area;
using sl::data::sample_bilinear;
using sl::data::StreetDataset;
using sl::data::StreetSample;
using sl::data::StreetView;
using sl::data::to_ldr;
using sl::data::to_object_frame;
using sl::data::Transfer;
using sl::data::write_image;
using sl::render::Camera;
using sl::render::CameraRay;
using sl::render::env_lookup;
using sl::render::Intrinsics;
using sl::render::load_gltf;
using sl::render::Mesh;
using sl::render::Placement;
using sl::render::radiance_query;
using sl::render::RadianceQueryOptions;

namespace fs = std::filesystem;
using nlohmann::json;
using namespace sl;
using namespace sl::train;
using sl::cli::ci_json;
using sl::cli::Confidence;
using sl::cli::Grouped;
using sl::cli::InsertionScore;
using sl::cli::interval_json;
using sl::cli::LdrSunSplits;
using sl::cli::not_scored_json;
using sl::cli::PartScores;
using sl::cli::real_sky_baseline_json;
using sl::cli::score_insertion;
using sl::cli::street_baseline;
using sl::cli::street_baseline_json;
using sl::cli::StreetBaseline;
using sl::cli::sun_parts_json;
using sl::cli::sun_stats_json;

namespace {

// The predicted LDR of a world camera's view (radiance query, Eq. 1) and its upper-hemisphere mask.
std::pair<Tensor, std::vector<char>> render_view(const EstimatedLighting& l, const Camera& world_cam, int rows,
                                                 const RadianceQueryOptions& qo) {
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

constexpr double kHalfPi = 1.57079632679489661923;

using RealSkyData = RealSkyFolder;  // train/real_sky_benchmark.h

std::string labels_file_for(const std::string& dir, const std::string& sun_labels) {
  return sun_labels.empty() ? (fs::path(dir) / "sun_labels.csv").string() : sun_labels;
}

// The LDR a camera at the panorama's centre sees (bilinear, render/equirect.h convention).
Tensor render_truth(const Tensor& pano_hdr, const Camera& cam, double exposure) {
  const Tensor p = pano_hdr.contiguous();
  const int h = static_cast<int>(p.size(1)), w = static_cast<int>(p.size(2));
  const Intrinsics& k = cam.intrinsics();
  Tensor out = Tensor::empty({3, k.height, k.width});
  float* o = out.data<float>();
  const int64_t plane = static_cast<int64_t>(k.height) * k.width;
  for (int r = 0; r < k.height; ++r)
    for (int c = 0; c < k.width; ++c) {
      const glm::dvec3 d = cam.pixel_ray(c, r).direction;
      const auto uv = render::equirect::direction_to_uv(d.x, d.y, d.z, w, h);
      float rgb[3];
      sample_bilinear(p.data<float>(), 3, h, w, uv.u, uv.v, rgb);
      for (int ch = 0; ch < 3; ++ch) o[ch * plane + static_cast<int64_t>(r) * k.width + c] = rgb[ch];
    }
  return to_ldr(out, exposure);
}

// The predicted sky's sun strength: the share of its Σ L·Ω within 8° of its brightest direction
// (data/panorama_sample.h sun_hardness; the measure of docs/RESULTS.md, "faint shadows"). A weak
// predicted sun is a candidate confidence signal, recorded per image beside the flip spread.
double predicted_sun_share(const EstimatedLighting& l) {
  return sl::data::sun_hardness(l.env.to(DType::F32).contiguous(), 8.0, 0.25).share;
}

// The learned glare detector's file ("" none) and its two weights (LightingEstimator::set_sun_glare).
struct GlareUse {
  std::string path;
  double azimuth_weight = 0.0, map_weight = 0.0;
};

json eval_lighting(const std::string& ckpt, const std::string& data, const std::string& split, int64_t limit,
                   int view_rows, std::vector<cli::PlotPoint>* plot, const std::string& label, const RealSkyData* real,
                   bool oracle, bool flip_average, bool visible_sun, const GlareUse& glare, const std::vector<double>& crop_scales,
                   const std::function<void()>& on_image) {
  LightingEstimator est(ckpt);
  est.set_flip_average(flip_average);
  est.set_crop_scales(crop_scales);
  est.set_visible_sun(visible_sun);
  if (visible_sun && !glare.path.empty())
    est.set_sun_glare(train::load_sun_glare(glare.path), train::kGlareThreshold, glare.azimuth_weight, glare.map_weight);
  // Every score carries its group for the bootstrap: the street's id, or the real crop's panorama.
  Grouped sun_err, sun_in, sun_out, ps, sps, ups, usps, ins_psnr, ins_ratio, oracle_psnr, oracle_ratio;
  // One entry per image with a sun label: which image, the error and both directions (in the
  // input camera's canonical frame), so failures can be found and looked at.
  json per_image = json::array();
  Confidence confidence{"sun_flip_spread_deg"}, confidence_hedge{"sun_hedge"}, confidence_crop{"sun_crop_spread_deg"};
  // The sun head's probability near its mode (train/inference.h sun_probability; larger is more
  // confident), ranked as 1 − p so that, as for the spreads, smaller ranks first.
  Confidence confidence_probability{"sun_doubt"};
  std::vector<glm::dvec3> parts_predicted, parts_truth;  // for train/sun_error_parts.h
  const auto add_image = [&](const std::string& id, const glm::dvec3& predicted, const glm::dvec3& truth, double e,
                             const EstimatedLighting& l) {
    parts_predicted.push_back(predicted);
    parts_truth.push_back(truth);
    const double spread = l.sun_flip_spread_deg, hedge = l.sun_hedge, crop = l.sun_crop_spread_deg;
    per_image.push_back({{"id", id}, {"sun_error_deg", e}, {"predicted", {predicted.x, predicted.y, predicted.z}},
                         {"truth", {truth.x, truth.y, truth.z}},
                         {"sun_flip_spread_deg", std::isfinite(spread) ? json(spread) : json()},
                         {"sun_hedge", std::isfinite(hedge) ? json(hedge) : json()},
                         {"sun_crop_spread_deg", std::isfinite(crop) ? json(crop) : json()},
                         {"sun_probability", std::isfinite(l.sun_probability) ? json(l.sun_probability) : json()},
                         {"sun_doubt", std::isfinite(l.sun_probability) ? json(1.0 - l.sun_probability) : json()}});
    const std::string group = id.substr(0, id.find('#'));  // a real crop's group is its panorama
    confidence.add(spread, e, group);
    confidence_hedge.add(hedge, e, group);
    confidence_crop.add(crop, e, group);
    confidence_probability.add(1.0 - l.sun_probability, e, group);
  };
  std::vector<double> ms;
  size_t sun_unknown = 0;  // samples whose sun label is not usable (soft sun): no sun error
  std::map<std::string, std::vector<double>> budget_err, budget_ms;
  int64_t oracle_probes = 0;  // oracle samples lit by the light probe at the object
  PartScores ins_parts, oracle_parts;
  LdrSunSplits ldr_splits;
  size_t cue_all = 0, cue_in = 0, cue_out = 0;  // scored images on which the visible-sun cue fired
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
      // As on real skies (and in training), a soft sun's direction is no label.
      if (s.sun_known) {
        const glm::dvec3 truth = l.frame.direction(s.sun_direction);
        const double e = angular_error_deg(dir, truth);
        sun_err.add(e, s.id);
        add_image(s.id, dir, truth, e, l);
        per_image.back()["visible_sun_found"] = l.visible_sun_found;
        per_image.back()["visible_sun_learned"] = l.visible_sun_learned;
        per_image.back()["glare_azimuth_used"] = l.glare_azimuth_used;
        per_image.back()["glare_map_used"] = l.glare_map_used;
        per_image.back()["predicted_sun_share"] = predicted_sun_share(l);
        cue_all += l.visible_sun_found;
      } else {
        ++sun_unknown;
      }
      for (size_t k = 1; k < s.views.size(); ++k) {
        NoGradGuard ng;
        const auto [pred, upper] = render_view(l, s.views[k].camera, view_rows, est.volume_query());
        const Tensor truth = resize_bilinear(s.views[k].ldr, pred.size(1), pred.size(2));
        const PsnrScores all = masked_psnr(pred, truth, {}), up = masked_psnr(pred, truth, upper);
        ps.add(all.psnr, s.id), sps.add(all.si_psnr, s.id);
        if (up.valid) ups.add(up.psnr, s.id), usps.add(up.si_psnr, s.id);
      }
      if (s.has_insertion && !s.object_glb.empty()) {
        auto it = meshes.find(s.object_glb);
        if (it == meshes.end()) it = meshes.emplace(s.object_glb, to_object_frame(load_gltf(s.object_glb))).first;
        // What streetlight-insert ships: PhotoInsertionOptions' defaults (STREETLIGHT_EVAL_AA
        // overrides the primary samples, for the part-by-part study of docs/RESULTS.md).
        PhotoInsertionOptions o;
        if (const char* aa = std::getenv("STREETLIGHT_EVAL_AA")) o.aa_samples = std::max(1, std::atoi(aa));
        o.volume_query = est.volume_query();
        try {
          const InsertionScore sc = score_insertion(l, s, it->second, o);
          if (sc.valid) ins_psnr.add(sc.psnr, s.id), ins_ratio.add(sc.shadow_ratio_error, s.id), ins_parts.add(sc);
          if (oracle) {
            // Oracle lighting: the same renderer and options under the generator's own HDR
            // panorama (distant light, exposure-normalised, in the canonical frame): the light
            // probe at the object when the dataset has one (datagen insertion.light_probe), else
            // the panorama at the camera. What is left is the renderer's error, not the lighting's.
            EstimatedLighting truth = l;
            const bool probe = s.insert_light_probe_hdr.defined();
            truth.env = l.frame.panorama(mul_scalar((probe ? s.insert_light_probe_hdr : s.pano_hdr).contiguous(), s.exposure))
                            .contiguous();
            truth.vsg = Tensor();
            const InsertionScore oc = score_insertion(truth, s, it->second, o);
            if (oc.valid) oracle_psnr.add(oc.psnr, s.id), oracle_ratio.add(oc.shadow_ratio_error, s.id),
                  oracle_probes += probe, oracle_parts.add(oc);
          }
          if (plot)
            for (Budget b : budgets()) {
              b.o.volume_query = est.volume_query();
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
      if (on_image) on_image();
    }
    progress.finish();
  } else {
    SL_CHECK(real != nullptr, "eval: internal: no real-sky crops for '", data, "'");
    count = real->test.size();
    cli::Progress progress("eval", static_cast<int64_t>(count));
    for (size_t i = 0; i < count; ++i) {
      const RealSkyCrop& c = real->test[i];
      const StreetView& v = c.sample.views[0];
      const EstimatedLighting l = est.estimate({{v.ldr, v.depth, v.camera}});
      if (i > 0 || count == 1) ms.push_back(l.inference_ms);
      const glm::dvec3 dir = l.has_sky_code ? l.sun_direction_canonical : extract_sun(l.env.contiguous()).direction;
      if (c.sun_known) {
        const double e = angular_error_deg(dir, c.sun_canonical);
        sun_err.add(e, c.panorama);
        (c.sun_in_crop ? sun_in : sun_out).add(e, c.panorama);
        add_image(cat(c.panorama, "#", i), dir, c.sun_canonical, e, l);
        per_image.back()["sun_in_crop"] = c.sun_in_crop;
        per_image.back()["visible_sun_found"] = l.visible_sun_found;
        per_image.back()["visible_sun_learned"] = l.visible_sun_learned;
        per_image.back()["glare_azimuth_used"] = l.glare_azimuth_used;
        per_image.back()["glare_map_used"] = l.glare_map_used;
        per_image.back()["predicted_sun_share"] = predicted_sun_share(l);
        cue_all += l.visible_sun_found;
        (c.sun_in_crop ? cue_in : cue_out) += l.visible_sun_found;
        if (real->ldr) {
          ldr_splits.add(c, e, 1.0 - l.sun_probability);
          per_image.back()["label"] = c.label_sun;
          per_image.back()["confidence"] = c.label_confidence;
          per_image.back()["scene"] = c.scene;
        }
      } else {
        ++sun_unknown;
      }
      // A novel view: the same panorama seen 90° to the right of the input crop.
      NoGradGuard ng;
      const Camera novel(v.camera.intrinsics(), v.camera.rotation() * glm::dmat3(glm::rotate(glm::dmat4(1.0), -kHalfPi, glm::dvec3(0, 1, 0))),
                         v.camera.position());
      PerspectiveCropParams cp;
      cp.width = v.camera.intrinsics().width, cp.height = v.camera.intrinsics().height;
      const auto [pred, upper] = render_view(l, novel, view_rows, est.volume_query());
      const Tensor truth_full = render_truth(c.sample.pano_hdr, novel, c.sample.exposure);
      const Tensor truth = resize_bilinear(truth_full, pred.size(1), pred.size(2));
      const PsnrScores all = masked_psnr(pred, truth, {}), up = masked_psnr(pred, truth, upper);
      ps.add(all.psnr, c.panorama), sps.add(all.si_psnr, c.panorama);
      if (up.valid) ups.add(up.psnr, c.panorama), usps.add(up.si_psnr, c.panorama);
      progress.update(static_cast<int64_t>(i + 1));
      if (on_image) on_image();
    }
    progress.finish();
  }
  if (plot) {
    std::vector<std::pair<double, double>> line;
    for (const auto& [name, errs] : budget_err) line.emplace_back(mean_of(budget_ms[name]), mean_of(errs));
    std::sort(line.begin(), line.end());
    for (const auto& [t, e] : line) plot->push_back({label, t, e});
  }
  json r = {{"checkpoint", ckpt}, {"stage", est.stage()}, {"step", est.step()}, {"flip_average", flip_average},
            {"visible_sun", visible_sun}, {"sun_glare", visible_sun ? glare.path : std::string()},
            {"glare_azimuth_weight", visible_sun && !glare.path.empty() ? glare.azimuth_weight : 0.0},
            {"glare_map_weight", visible_sun && !glare.path.empty() ? glare.map_weight : 0.0}, {"crop_scales", crop_scales},
            {"sky_branch", est.predictor().options().sky_branch},
            {"volume_branch", est.predictor().options().volume_branch},
            {"images", count}, {"sun_unknown", sun_unknown},
            {"sun_error_median_deg", median(sun_err.v)}, {"sun_error_mean_deg", mean_of(sun_err.v)},
            {"sun", sun_stats_json(sun_err, sun_in, sun_out, real != nullptr)},
            {"psnr", mean_of(ps.v)}, {"si_psnr", mean_of(sps.v)},
            {"psnr_upper", mean_of(ups.v)}, {"si_psnr_upper", mean_of(usps.v)},
            {"inference_ms", mean_of(ms)}, {"sun_per_image", per_image}};
  r["sun"]["all"]["visible_sun_fired"] = cue_all;
  if (real) r["sun"]["sun_in_crop"]["visible_sun_fired"] = cue_in, r["sun"]["sun_outside_crop"]["visible_sun_fired"] = cue_out;
  if (real && real->ldr) ldr_splits.write(r);
  r["sun_parts"] = sun_parts_json(sl::train::sun_error_parts(parts_predicted, parts_truth));
  r["sun_confidence"] = confidence.to_json();
  r["sun_confidence_hedge"] = confidence_hedge.to_json();
  r["sun_confidence_crop"] = confidence_crop.to_json();
  r["sun_confidence_probability"] = confidence_probability.to_json();
  json ci = {{"sun_error_median_deg", ci_json(sun_err.v, sun_err.g, Statistic::Median)},
             {"sun_error_mean_deg", ci_json(sun_err.v, sun_err.g, Statistic::Mean)},
             {"psnr", ci_json(ps.v, ps.g, Statistic::Mean)}, {"si_psnr", ci_json(sps.v, sps.g, Statistic::Mean)},
             {"psnr_upper", ci_json(ups.v, ups.g, Statistic::Mean)},
             {"si_psnr_upper", ci_json(usps.v, usps.g, Statistic::Mean)}};
  if (!oracle_psnr.v.empty())
    r["oracle"] = {{"insertion_psnr", mean_of(oracle_psnr.v)}, {"shadow_ratio_error", mean_of(oracle_ratio.v)},
                   {"ci95", {{"insertion_psnr", ci_json(oracle_psnr.v, oracle_psnr.g, Statistic::Mean)},
                             {"shadow_ratio_error", ci_json(oracle_ratio.v, oracle_ratio.g, Statistic::Mean)}}},
                   {"insertion_samples", oracle_psnr.v.size()}, {"insertion_psnr_parts", oracle_parts.to_json()},
                   {"light", oracle_probes == static_cast<int64_t>(oracle_psnr.v.size()) ? "probe at the object"
                             : oracle_probes == 0                                      ? "panorama at the camera"
                                                                                       : "mixed"}};
  if (!ins_psnr.v.empty()) {
    r["insertion_psnr"] = mean_of(ins_psnr.v);
    r["shadow_ratio_error"] = mean_of(ins_ratio.v);
    r["insertion_samples"] = ins_psnr.v.size();
    r["insertion_psnr_parts"] = ins_parts.to_json();
    ci["insertion_psnr"] = ci_json(ins_psnr.v, ins_psnr.g, Statistic::Mean);
    ci["shadow_ratio_error"] = ci_json(ins_ratio.v, ins_ratio.g, Statistic::Mean);
  }
  r["ci95"] = ci;
  if (!budget_err.empty()) {
    json b = json::array();
    for (const auto& [name, errs] : budget_err)
      b.push_back({{"budget", name}, {"shadow_ratio_error", mean_of(errs)}, {"ms", mean_of(budget_ms[name])}});
    r["budgets"] = b;
  }
  return r;
}

json eval_sky(const std::string& ckpt, const std::string& data, const std::string& split, int64_t limit,
             const RealSkyData* real, const std::function<void()>& on_image) {
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
    if (true_hdr.defined()) {  // LDR panoramas have no HDR truth: no log-L2
      const Tensor truth = resize_area(true_hdr.contiguous(), static_cast<int>(so.height), static_cast<int>(so.width));
      const Tensor d = sub(log(add_scalar(select(o.sky.hdr, 0, 0), 1.0)), log(add_scalar(truth, 1.0)));
      log_l2.push_back(mean(mul(d, d)).item());
    }
    const Tensor dir = o.code.dir.to(DType::F64).contiguous();
    sun_err.push_back(angular_error_deg({dir.data<double>()[0], dir.data<double>()[1], dir.data<double>()[2]}, sun));
    if (on_image) on_image();
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
    SL_CHECK(real != nullptr, "eval: internal: no real-sky panoramas for '", data, "'");
    for (const auto& c : real->test) {  // the whole (rotated) panorama of every crop with a known sun
      if (!c.sun_known) continue;
      score(c.sample.pano_ldr, real->ldr ? Tensor() : mul_scalar(c.sample.pano_hdr.contiguous(), c.sample.exposure),
            c.sample.sun_direction);
      ++count;
    }
  }
  return {{"checkpoint", ckpt}, {"stage", info.stage}, {"step", info.step}, {"images", count},
          {"sky_log_l2", log_l2.empty() ? json() : json(mean_of(log_l2))}, {"sun_error_median_deg", median(sun_err)},
          {"sun_error_mean_deg", mean_of(sun_err)}, {"inference_ms", mean_of(ms)}};
}

}  // namespace

namespace sl::cli {

void check_eval_options(const EvalOptions& o) {
  SL_CHECK(!o.data.empty(), "--data DIR is required");
  const size_t checkpoints = o.checkpoints.empty() ? 1 : o.checkpoints.size();
  SL_CHECK(o.names.empty() || o.names.size() == checkpoints, "give one --name per --checkpoint (", checkpoints,
           " checkpoints, ", o.names.size(), " names)");
  SL_CHECK(o.view_rows > 0, "--view-rows must be positive");
  SL_CHECK(o.crops > 0, "--crops must be positive, got ", o.crops);
  for (double s : o.crop_scales)
    SL_CHECK(s > 0.0 && s < 1.0, "--crop-scales: expected numbers in (0, 1), got ", s);
}

EvalReport evaluate(const EvalOptions& o) {
  check_eval_options(o);
  std::vector<std::string> ckpts = o.checkpoints;
  std::vector<std::string> names = o.names;
  if (ckpts.empty()) {
    ckpts.push_back(cli::released_model_path());
    if (names.empty()) names.push_back("released model");
  }
  const std::vector<std::string>& datas = o.data;
  const std::string& split = o.split;
  const std::string& hdri_split = o.hdri_split;
  for (const auto& d : datas) SL_CHECK(fs::is_directory(d), "--data '", d, "' is not a folder");
  if (names.empty()) names = ckpts;
  const int64_t limit = o.limit;
  const int rows = o.view_rows;
  const std::vector<double>& crop_scales = o.crop_scales;
  const int crops = o.crops;
  if (!hdri_split.empty()) (void)read_hdri_split(hdri_split);  // fail early on a bad file
  const std::string& ldr_split = o.ldr_split;
  const std::string& sun_labels = o.sun_labels;
  if (!ldr_split.empty()) (void)read_hdri_split(ldr_split);
  if (!sun_labels.empty()) (void)data::read_sun_labels(sun_labels);
  for (const auto& c : ckpts) nn::read_checkpoint_info(c);     // fail early on a bad file
  const std::string& baseline_data = o.baseline_data;
  if (!baseline_data.empty()) {
    SL_CHECK(fs::exists(fs::path(baseline_data) / "index.json"), "--baseline-data '", baseline_data,
             "' is not a street dataset (no index.json)");
    SL_CHECK(street_baseline(baseline_data).has, "--baseline-data '", baseline_data,
             "' has no train sample with a hard sun to average");
  }
  EvalReport report;
  json datasets = json::array();
  std::string& md = report.markdown;
  std::vector<cli::PlotPoint>& plot = report.plot;
  bool plotted = false;
  for (const auto& data : datas) {
    const bool street = fs::exists(fs::path(data) / "index.json");
    const bool ldr = !street && is_ldr_panorama_folder(data);
    std::unique_ptr<RealSkyData> real;
    if (ldr)
      real = std::make_unique<RealSkyData>(
          load_ldr_panorama_folder(data, labels_file_for(data, sun_labels), ldr_split, split, crops, limit));
    else if (!street)
      real = std::make_unique<RealSkyData>(load_hdr_sky_folder(data, hdri_split, split, crops, limit));
    std::vector<json> results;
    bool oracle_done = false;
    for (size_t i = 0; i < ckpts.size(); ++i) {
      const std::string stage = nn::read_checkpoint_info(ckpts[i]).stage;
      if (stage == kStageSky) {
        results.push_back(eval_sky(ckpts[i], data, split, limit, real.get(), o.on_image));
      } else {
        const bool want_plot = street && !plotted && o.budgets;
        // The oracle row depends only on the data: computed with the first lighting checkpoint.
        const bool want_oracle = street && !oracle_done;
        results.push_back(eval_lighting(ckpts[i], data, split, limit, rows, want_plot ? &plot : nullptr, names[i],
                                        real.get(), want_oracle, o.flip_average, o.visible_sun, GlareUse{o.sun_glare, o.glare_azimuth_weight, o.glare_map_weight}, crop_scales,
                                        o.on_image));
        oracle_done = oracle_done || want_oracle;
        plotted = plotted || want_plot;
      }
      results.back()["name"] = names[i];
    }
    json entry = {{"data", data}, {"kind", street ? "street" : ldr ? "ldr_panoramas" : "real_panoramas"}, {"split", split},
                  {"results", results}};
    json baseline;
    if (street) {
      const StreetBaseline b = street_baseline(baseline_data.empty() ? data : baseline_data);
      if (b.has) baseline = entry["baseline"] = street_baseline_json(b, data, split, limit);
    }
    if (real) {
      if (ldr) {
        entry["ldr_split"] = ldr_split;
        entry["sun_labels"] = real->labels;
        json not_scored = json::array();
        for (const auto& l : real->not_scored) not_scored.push_back(not_scored_json(l));
        entry["panoramas"] = {{"scored", real->scored}, {"not_scored", not_scored},
                              {"low_confidence", real->low_confidence}};
      } else {
        entry["hdri_split"] = hdri_split;
      }
      entry["crops_per_panorama"] = crops;
      if (real->has_baseline) baseline = entry["baseline"] = real_sky_baseline_json(*real);
    }
    const std::string& split_file = ldr ? ldr_split : hdri_split;
    md += "## " + data + (street ? " (generated streets, split " + split + ")\n\n"
                                 : std::string(ldr ? " (real LDR panoramas" : " (real panoramas") +
                                       (split_file.empty() ? std::string() : ", " + split_file + " split " + split) +
                                       ", " + std::to_string(crops) + " crops each)\n\n");
    md += cli::eval_markdown(results, names, street ? baseline : json());
    if (street && baseline.is_null()) md += "\n(no baseline row: the data has no train split; give --baseline-data)\n";
    if (ldr) {
      md += cli::ldr_markdown(results, baseline, *real);
      if (baseline.is_null()) md += "\n(no baseline row: give --ldr-split with a \"train\" list)\n";
    } else if (real) {
      md += "\nSun direction on real skies (crops whose sun is hard):\n\n" + cli::real_sky_markdown(results, baseline);
      if (baseline.is_null()) md += "\n(no baseline row: give --hdri-split with a \"train\" list)\n";
    }
    md += cli::sun_parts_markdown(results);
    md += cli::confidence_markdown(results);
    md += "\n";
    datasets.push_back(entry);
  }
  // The first data set's fields stay at the top level for single-data callers.
  json all = {{"data", datas[0]}, {"split", split}, {"results", datasets[0]["results"]}, {"datasets", datasets}};
  const json pooled = cli::pooled_sun_in_crop(datasets, names);
  if (!pooled.empty()) {
    all["sun_in_crop_pooled"] = pooled;
    md += cli::pooled_markdown(pooled, datasets);
  }
  report.results = std::move(all);
  return report;
}

void write_eval_report(const EvalReport& r, const std::string& out) {
  fs::create_directories(out);
  write_file_atomic((fs::path(out) / "results.json").string(), r.results.dump(2) + "\n");
  write_file_atomic((fs::path(out) / "results.md").string(), r.markdown);
  if (!r.plot.empty()) {
    ImageWriteOptions lin;
    lin.transfer = Transfer::Linear;
    write_image((fs::path(out) / "error_time.png").string(), cli::error_time_plot(r.plot), lin);
  }
}

}  // namespace sl::cli
