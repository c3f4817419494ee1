// Lighting inference, sun editing and multi-view fusion. See inference.h.
#include "train/inference.h"

#include "render/equirect.h"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <exception>

#include "autodiff/ops.h"
#include "autodiff/tape.h"
#include "data/augment.h"
#include "data/panorama.h"
#include "nn/checkpoint.h"
#include "nn/init.h"
#include "render/equirect.h"
#include "train/train_config.h"
#include "train/unprojection.h"
#include "util/math.h"
#include "util/parallel.h"

using sl::data::rotate_azimuth;
using sl::data::rotate_direction_azimuth;
using sl::render::Intrinsics;
using sl::render::RadianceQueryOptions;
using sl::render::VsgGrid;

namespace sl::train {

namespace {

std::vector<double> to_doubles(const Tensor& t) {
  const Tensor c = t.detach().to(DType::F64).contiguous();
  return std::vector<double>(c.data<double>(), c.data<double>() + c.numel());
}

// The visible sun of the view with the highest score (data/visible_sun.h); direction in world.
struct VisibleSunCue {
  bool found = false, learned = false;
  int view = -1;
  data::VisibleSun sun;
};
VisibleSunCue find_visible_sun_cue(const std::vector<InferenceView>& views, const data::VisibleSunParams& params) {
  VisibleSunCue cue;
  for (size_t k = 0; k < views.size(); ++k) {
    const data::VisibleSun s = data::find_visible_sun(views[k].ldr, views[k].camera, params);
    if (s.found && (!cue.found || s.score > cue.sun.score)) cue = {true, false, static_cast<int>(k), s};
  }
  return cue;
}

// The learned glare detector's reading of each view (train/sun_glare.h), flip-averaged; with `map`
// its glare map too.
std::vector<GlareReading> read_sun_glare(const std::vector<InferenceView>& views, SunGlareDetector& glare, bool map) {
  std::vector<GlareReading> out;
  for (const InferenceView& v : views)
    out.push_back(read_glare_flip_averaged(glare, glare_input(v.ldr), int(v.camera.intrinsics().height),
                                           int(v.camera.intrinsics().width), map));
  return out;
}

// Where the disk test found nothing: the view the detector is surest of, when it reaches the threshold.
VisibleSunCue glare_cue(const std::vector<InferenceView>& views, const std::vector<GlareReading>& reads, double threshold) {
  VisibleSunCue cue;
  for (size_t k = 0; k < reads.size(); ++k) {
    const GlareReading& r = reads[k];
    if (r.p_sun < threshold || (cue.found && r.p_sun <= cue.sun.score)) continue;
    cue = {true, true, static_cast<int>(k), data::VisibleSun{}};
    cue.sun.found = true;
    cue.sun.pixel = r.pixel;
    cue.sun.direction = views[k].camera.ray(r.pixel.x, r.pixel.y).direction;
    cue.sun.score = r.p_sun;
  }
  return cue;
}

}  // namespace

glm::dvec3 direction_from_azimuth_elevation_deg(double azimuth_deg, double elevation_deg) {
  const double az = azimuth_deg * kPi / 180.0, el = elevation_deg * kPi / 180.0;
  // φ = atan2(d.x, −d.z), θ = asin(d.y) (render/equirect.h).
  return {std::cos(el) * std::sin(az), std::sin(el), -std::cos(el) * std::cos(az)};
}
double azimuth_deg_of(const glm::dvec3& d) { return std::atan2(d.x, -d.z) * 180.0 / kPi; }
double elevation_deg_of(const glm::dvec3& d) {
  return std::asin(std::clamp(d.y / std::max(glm::length(d), 1e-12), -1.0, 1.0)) * 180.0 / kPi;
}

double sun_scale_for_shadow_ratio(const EstimatedLighting& l, double shadow_ratio, double sun_cone_deg) {
  SL_CHECK(std::isfinite(shadow_ratio), "sun_scale_for_shadow_ratio: shadow ratio ", shadow_ratio, " is not finite");
  SL_CHECK(l.env.defined() && l.env.dim() == 3 && l.env.size(0) == 3, "sun_scale_for_shadow_ratio: the lighting has no [3, H, W] dome");
  const Tensor env = l.env.to(DType::F64).contiguous();
  const int H = static_cast<int>(env.size(1)), W = static_cast<int>(env.size(2));
  const double* e = env.data<double>();
  const glm::dvec3 sun = glm::normalize(l.sun_direction_canonical);
  const double cos_cone = std::cos(sun_cone_deg * kPi / 180.0);
  double e_sun = 0.0, e_sky = 0.0;
  for (int i = 0; i < H; ++i) {
    const double omega = render::equirect::pixel_solid_angle(i, W, H);
    for (int j = 0; j < W; ++j) {
      const render::equirect::Dir d = render::equirect::uv_to_direction(j + 0.5, i + 0.5, W, H);
      if (d.y <= 0.0) continue;
      const size_t k = static_cast<size_t>(i) * W + j, plane = static_cast<size_t>(H) * W;
      const double lum = 0.2126 * e[k] + 0.7152 * e[plane + k] + 0.0722 * e[2 * plane + k];
      if (!std::isfinite(lum) || lum <= 0.0) continue;
      const double irr = lum * d.y * omega;
      (d.x * sun.x + d.y * sun.y + d.z * sun.z >= cos_cone ? e_sun : e_sky) += irr;
    }
  }
  if (!(e_sun > 0.0) || !(e_sky > 0.0)) return 1.0;
  const double r = std::clamp(shadow_ratio, 0.05, 0.95);
  return std::clamp(e_sky * (1.0 - r) / (r * e_sun), 1e-3, 1e4);
}

ShadowSunLighting estimate_with_shadow_sun(LightingEstimator& est, const InferenceView& view, SunEdit edit,
                                           const data::ShadowSunOptions& options) {
  ShadowSunLighting r;
  r.fit = data::fit_sun_from_shadows(view.ldr, view.depth, view.camera, options);
  if (r.fit.found) {
    edit.azimuth_deg = r.fit.azimuth_deg;
    edit.elevation_deg = r.fit.elevation_deg;
  }
  r.lighting = est.estimate({view}, edit);
  if (r.fit.found) {
    r.intensity_scale = sun_scale_for_shadow_ratio(r.lighting, r.fit.shadow_ratio);
    edit.intensity_scale *= r.intensity_scale;
    r.lighting = est.estimate({view}, edit);
  }
  return r;
}

glm::dvec3 EstimatedLighting::world_direction(const glm::dvec3& c) const {
  return rotate_direction_azimuth(c, frame.yaw_rad);
}
glm::dvec3 EstimatedLighting::world_point(const glm::dvec3& c) const {
  const glm::dvec3 r = rotate_direction_azimuth(c, frame.yaw_rad);
  return {r.x + frame.camera_world.x, r.y, r.z + frame.camera_world.z};
}
Tensor EstimatedLighting::env_world() const {
  return frame.yaw_rad == 0.0 ? env : rotate_azimuth(env.contiguous(), frame.yaw_rad);
}

LightingEstimator::LightingEstimator(const std::string& path) : path_(path) {
  const nn::CheckpointInfo info = nn::read_checkpoint_info(path);
  stage_ = info.stage;
  step_ = info.step;
  SL_CHECK(stage_ == kStageLighting || stage_ == kStageAdversarial, "checkpoint '", path, "' holds stage '", stage_,
           "'; lighting inference needs a '", kStageLighting, "' or '", kStageAdversarial, "' checkpoint");
  try {
    config_ = nlohmann::json::parse(info.config_json);
  } catch (const std::exception& e) {
    SL_CHECK(false, "checkpoint '", path, "': its config metadata is not JSON (", e.what(), ")");
  }
  const LightingPredictorOptions po = predictor_options(config_);
  {
    // Every parameter is loaded below, and load_state_dict refuses a missing one: random values
    // drawn now would all be overwritten (nn/init.h, SkipInitGuard).
    const nn::SkipInitGuard loaded_next;
    predictor_ = std::make_shared<LightingPredictor>(po);
  }
  // Load predictor.* only: the checkpoint also holds the teacher and maybe a discriminator,
  // which load_checkpoint would report as unexpected, so read the tensors by name.
  const nn::SafetensorsFile file = nn::read_safetensors(path);
  nn::StateDict state;
  for (const auto& [name, t] : file.tensors)
    if (name.rfind("predictor.", 0) == 0) state.emplace(name.substr(10), t);
  SL_CHECK(!state.empty(), "checkpoint '", path, "' holds no predictor.* tensors");
  try {
    predictor_->load_state_dict(state);
  } catch (const Error& e) {
    SL_CHECK(false, "checkpoint '", path, "' does not match its stored config: ", e.what());
  }
  predictor_->set_training(false);
  grid_template_ = vsg_grid(config_, 1.6);
}

RadianceQueryOptions LightingEstimator::volume_query() const { return volume_query_options(config_); }

namespace {
// The angle between two nonzero directions in degrees (atan2 form: exact near 0° and 180°).
// The centred crop of crop averaging: `scale` of the image's height and width, with margins equal
// on both sides (the crop's size keeps the image's parity), so the crop of the mirror image is the
// mirror image of the crop and flip averaging stays exact.
Tensor centred_crop(const Tensor& ldr, double scale) {
  const int64_t H = ldr.size(1), W = ldr.size(2);
  const int64_t y0 = std::min<int64_t>((H - 1) / 2, std::lround(H * (1.0 - scale) / 2.0)),
                x0 = std::min<int64_t>((W - 1) / 2, std::lround(W * (1.0 - scale) / 2.0));
  return slice(slice(ldr, 1, y0, H - y0), 2, x0, W - x0).contiguous();
}

double angle_deg(const glm::dvec3& a, const glm::dvec3& b) {
  return std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b)) * 180.0 / kPi;
}
}  // namespace

void LightingEstimator::set_sun_glare(std::shared_ptr<SunGlareDetector> detector, double threshold, double azimuth_weight,
                                      double map_weight) {
  SL_CHECK(threshold > 0.0 && threshold <= 1.0, "set_sun_glare: the threshold must be in (0, 1], got ", threshold);
  SL_CHECK(std::isfinite(azimuth_weight) && azimuth_weight >= 0.0,
           "set_sun_glare: the azimuth weight must be finite and >= 0, got ", azimuth_weight);
  SL_CHECK(std::isfinite(map_weight) && map_weight >= 0.0, "set_sun_glare: the map weight must be finite and >= 0, got ",
           map_weight);
  if (detector) detector->eval();
  sun_glare_ = std::move(detector);
  sun_glare_threshold_ = threshold;
  sun_glare_azimuth_weight_ = azimuth_weight;
  sun_glare_map_weight_ = map_weight;
}

void LightingEstimator::set_crop_scales(std::vector<double> scales) {
  for (const double s : scales)
    SL_CHECK(std::isfinite(s) && s > 0.0 && s < 1.0, "crop averaging: a crop scale must lie in (0, 1), got ", s);
  crop_scales_ = std::move(scales);
}

LightingEstimator::Single LightingEstimator::prepare_view(const InferenceView& v) const {
  const LightingPredictorOptions& po = predictor_->options();
  SL_CHECK(v.ldr.defined() && v.ldr.dim() == 3 && v.ldr.size(0) == 3, "lighting inference: expected an LDR image [3, H, W], got ",
           v.ldr.defined() ? v.ldr.describe() : std::string("undefined"));
  const Intrinsics& k = v.camera.intrinsics();
  SL_CHECK(v.ldr.size(1) == k.height && v.ldr.size(2) == k.width, "lighting inference: image ", v.ldr.describe(),
           " does not match the camera's ", k.width, "x", k.height);
  if (po.volume_branch)
    SL_CHECK(v.depth.defined() && v.depth.dim() == 2 && v.depth.size(0) == k.height && v.depth.size(1) == k.width,
             "lighting inference: the volume branch needs a depth map [", k.height, ", ", k.width, "], got ",
             v.depth.defined() ? v.depth.describe() : std::string("undefined"));
  Single s;
  s.frame = canonical_frame(v.camera);
  s.camera = s.frame.camera(v.camera);
  s.grid = grid_template_;
  s.grid.center = s.camera.position();
  return s;
}

Tensor LightingEstimator::unproject_view(const InferenceView& v, const Single& s) const {
  return unsqueeze(unproject_rgba(v.ldr, v.depth, s.camera, s.grid), 0);
}

Tensor LightingEstimator::network_input(const Tensor& ldr) const {
  const LightingPredictorOptions& po = predictor_->options();
  return unsqueeze(resize_bilinear(ldr, po.image_height, po.image_width), 0);
}

SkyPrediction LightingEstimator::mirror_sky(const Tensor& input) {
  return predictor_->predict_sky(unsqueeze(data::flip_horizontal(select(input, 0, 0).contiguous()), 0));
}

void LightingEstimator::average_sun(const InferenceView& v, Single& s, const SkyPrediction& mirror_pass) {
  if (s.pred.sun_logits.defined()) {
    sun_from_distribution(v, s, mirror_pass);
    return;
  }
  const SkyCode& mirror = mirror_pass.code;
  // The sun of one network input, averaged with its mirror image's under flip averaging (the
  // flipped pass's direction mirrored back: (x, y, z) → (−x, y, z), exact for a level camera).
  // Returns the direction (not normalised) and, flipped, the mirror pass's log intensity.
  const auto sun_of = [&](const SkyCode& own, const SkyCode* m, std::vector<double>* mirror_log_i, double* spread_deg) {
    const std::vector<double> d = to_doubles(own.dir);
    glm::dvec3 dir(d[0], d[1], d[2]);
    if (!flip_average_) return dir;
    const std::vector<double> md = to_doubles(m->dir);
    const glm::dvec3 mirrored(-md[0], md[1], md[2]);
    if (spread_deg && glm::length(dir) > 1e-12 && glm::length(mirrored) > 1e-12)
      *spread_deg = angle_deg(dir, mirrored);
    if (mirror_log_i) *mirror_log_i = to_doubles(m->log_intensity);
    return dir + mirrored;
  };
  std::vector<double> mirror_log_i;
  glm::dvec3 dir = sun_of(s.pred.code, &mirror, &mirror_log_i, &s.flip_spread_deg);
  if (!crop_scales_.empty()) {
    // Crop averaging: the centred crops, each estimated as the photo is, vote with unit weight.
    const glm::dvec3 photo = glm::length(dir) > 1e-12 ? glm::normalize(dir) : glm::dvec3(0.0, 1.0, 0.0);
    glm::dvec3 sum = photo;
    s.crop_spread_deg = 0.0;
    for (const double scale : crop_scales_) {
      const Tensor input = network_input(centred_crop(v.ldr, scale));
      const SkyCode own = predictor_->predict_sky_code(input);
      const SkyCode m = flip_average_ ? mirror_sky(input).code : SkyCode{};
      glm::dvec3 c = sun_of(own, &m, nullptr, nullptr);
      if (glm::length(c) <= 1e-12) continue;
      c = glm::normalize(c);
      s.crop_spread_deg = std::max(s.crop_spread_deg, angle_deg(photo, c));
      sum += c;
    }
    dir = sum;
  }
  if ((flip_average_ || !crop_scales_.empty()) && glm::length(dir) > 1e-9) {
    dir = glm::normalize(dir);
    s.pred.code.dir = Tensor::from_vector({dir.x, dir.y, dir.z}, {1, 3}).to(s.pred.code.dir.dtype());
  }
  if (!mirror_log_i.empty()) {
    std::vector<double> li = to_doubles(s.pred.code.log_intensity);
    for (size_t i = 0; i < li.size(); ++i) li[i] = 0.5 * (li[i] + mirror_log_i[i]);
    s.pred.code.log_intensity =
        Tensor::from_vector(li, s.pred.code.log_intensity.shape()).to(s.pred.code.log_intensity.dtype());
  }
}

void LightingEstimator::sun_from_distribution(const InferenceView& v, Single& s, const SkyPrediction& photo_mirror) {
  // The sun's distribution (train/sun_distribution.h), averaged over the photo's pass and the
  // mirror image of the mirrored photo's pass (flip averaging) and over the centred crops (crop
  // averaging), then read at its mode: probabilities are averaged, never directions, so two
  // passes that disagree keep two peaks instead of meeting between them.
  const LightingPredictorOptions& po = predictor_->options();
  const SunGrid& grid = po.sun_grid;
  const auto probs_of = [&](const Tensor& logits) { return softmax_row(select(logits, 0, 0).to_vector()); };
  std::vector<double> log_i = to_doubles(s.pred.code.log_intensity);
  std::vector<double> p = probs_of(s.pred.sun_logits);
  double passes = 1.0;
  // input: a crop's network input, or undefined for the photo itself (whose own and mirror passes
  // are done: s.pred and photo_mirror).
  const auto add_input = [&](const Tensor& input, const std::vector<double>* own, bool keep_intensity) {
    std::vector<double> q = own ? *own : probs_of(predictor_->predict_sky(input).sun_logits);
    if (!own) {
      for (size_t k = 0; k < p.size(); ++k) p[k] += q[k];
      passes += 1.0;
    }
    if (!flip_average_) return q;
    const SkyPrediction m = input.defined() ? mirror_sky(input) : photo_mirror;
    const std::vector<double> mq = mirror_cells(grid, probs_of(m.sun_logits));
    for (size_t k = 0; k < p.size(); ++k) p[k] += mq[k];
    passes += 1.0;
    if (keep_intensity) {
      const std::vector<double> ml = to_doubles(m.code.log_intensity);
      for (size_t i = 0; i < log_i.size(); ++i) log_i[i] = 0.5 * (log_i[i] + ml[i]);
      s.flip_spread_deg = angle_deg(read_sun_distribution(grid, q).direction, read_sun_distribution(grid, mq).direction);
    }
    return q;
  };
  const std::vector<double> own = p;
  add_input(Tensor(), &own, true);
  if (!crop_scales_.empty()) {
    const glm::dvec3 photo = read_sun_distribution(grid, p).direction;
    s.crop_spread_deg = 0.0;
    for (const double scale : crop_scales_) {
      const std::vector<double> q = add_input(network_input(centred_crop(v.ldr, scale)), nullptr, false);
      s.crop_spread_deg = std::max(s.crop_spread_deg, angle_deg(photo, read_sun_distribution(grid, q).direction));
    }
  }
  for (double& x : p) x /= passes;
  // The glare detector's azimuth head, when there is one, as a second opinion on the azimuth.
  if (!s.glare_azimuth.empty() && sun_glare_azimuth_weight_ > 0.0) {
    p = weigh_by_azimuth(grid, p, s.glare_azimuth, sun_glare_azimuth_weight_);
    s.glare_azimuth_used = true;
  }
  // Its glare map, below the threshold: where in view a sun is likelier (or, mostly, that none is).
  if (!s.glare_cells.empty() && sun_glare_map_weight_ > 0.0) {
    p = weigh_by_cells(grid, p, glare_sky_factor(grid, s.camera, s.glare_cells), sun_glare_map_weight_);
    s.glare_map_used = true;
  }
  const SunReadout r = read_sun_distribution(grid, p);
  s.sun_probability = r.confidence;
  s.pred.code.dir = Tensor::from_vector({r.direction.x, r.direction.y, r.direction.z}, {1, 3}).to(s.pred.code.dir.dtype());
  s.pred.code.log_intensity = Tensor::from_vector(log_i, s.pred.code.log_intensity.shape()).to(s.pred.code.log_intensity.dtype());
}

EstimatedLighting LightingEstimator::estimate(const std::vector<InferenceView>& views, const SunEdit& edit) {
  SL_CHECK(!views.empty(), "lighting inference: no views");
  NoGradGuard no_grad;
  // Every loop outside the team below runs on this thread: the fusion and the decoding are a few
  // milliseconds, and each parallel loop could cost a scheduler tick on a loaded machine.
  const SerialLoops serial;
  const auto t0 = std::chrono::steady_clock::now();
  // The parts of an estimate are independent until the fusion below: each view's unprojection,
  // the visible-sun cue, each view's backbone pass and its mirror image's, and each view's 3D
  // UNet once its unprojection is done. They run as OpenMP tasks in ONE team, each on one thread
  // (parallel.h opens no nested team), instead of one parallel region per op: on a loaded
  // machine every parallel op could wait a scheduler slice for a descheduled thread
  // (docs/benchmarks-inference.md). Every value is computed as on one thread, by the same calls
  // on the same shapes (one image per pass), so the estimate does not depend on the thread count
  // or on which thread ran what, and equals the plain sequential path bit for bit.
  std::vector<Single> singles;
  for (const auto& v : views) singles.push_back(prepare_view(v));  // checks throw here, outside the team
  const LightingPredictorOptions& po = predictor_->options();
  const bool sky_code_branch = po.sky_branch == "sky_decoder";
  const bool want_cue = visible_sun_ && sky_code_branch;
  const size_t n = views.size();
  VisibleSunCue cue;
  std::vector<Tensor> images(n), rgba(n), g(n);
  std::vector<SkyPrediction> mirror(n);
  for (size_t k = 0; k < n; ++k) images[k] = network_input(views[k].ldr);
  std::vector<std::exception_ptr> errors(3 * n + 3);
  std::vector<GlareReading> glare_reads;
  const auto guarded = [](std::exception_ptr& error, auto&& f) {
    try {
      const NoGradGuard no_grad_here;  // grad mode is per thread; a task may run on any
      f();
    } catch (...) {
      error = std::current_exception();
    }
  };
#pragma omp parallel if (!omp_in_parallel())
#pragma omp single
  {
    if (po.volume_branch)
      for (size_t k = 0; k < n; ++k) {
        Tensor* r = &rgba[k];
#pragma omp task firstprivate(k, r) shared(views, singles, errors, guarded) depend(out : r[0])
        guarded(errors[k], [&] { *r = unproject_view(views[k], singles[k]); });
      }
    if (sky_code_branch && flip_average_)
      for (size_t k = 0; k < n; ++k) {
#pragma omp task firstprivate(k) shared(images, mirror, errors, guarded)
        guarded(errors[n + k], [&] { mirror[k] = mirror_sky(images[k]); });
      }
    guarded(errors[3 * n + 1], [&] {
      if (!sky_code_branch) return;
      for (size_t k = 0; k < n; ++k) {
        g[k] = predictor_->features(images[k]);
        singles[k].pred.code = predictor_->sky_code(g[k]);
        singles[k].pred.sun_logits = predictor_->sun_logits(g[k], images[k]);
      }
    });
    if (sky_code_branch && po.volume_branch && !errors[3 * n + 1])
      for (size_t k = 0; k < n; ++k) {
        Tensor* r = &rgba[k];
#pragma omp task firstprivate(k, r) shared(singles, g, errors, guarded) depend(in : r[0])
        guarded(errors[2 * n + k], [&] {
          if (r->defined()) singles[k].pred.vsg = predictor_->volume(g[k], *r);
        });
      }
    // The cue last: the team takes tasks in the order they are made, so each view's UNet, which
    // waits on this thread's backbone pass, starts before the cue instead of after it. With one
    // view on 2 threads: this thread runs the backbone pass and the UNet, the other the
    // unprojection, the mirror pass and the cue (perf, KITTI 000008: one thread idle 20 ms
    // at the end when the cue went first).
    if (want_cue) {
#pragma omp task shared(cue, views, errors, guarded)
      guarded(errors[3 * n], [&] { cue = find_visible_sun_cue(views, visible_sun_params_); });
    }
    // The glare detector apart from the disk test, so that the thread done first runs it (its
    // answer is used only where the disk test finds nothing).
    if (want_cue && sun_glare_) {
#pragma omp task shared(glare_reads, views, errors, guarded)
      guarded(errors[3 * n + 2], [&] { glare_reads = read_sun_glare(views, *sun_glare_, sun_glare_map_weight_ > 0.0); });
    }
  }
  for (const std::exception_ptr& e : errors)
    if (e) std::rethrow_exception(e);
  if (want_cue && !cue.found && sun_glare_) cue = glare_cue(views, glare_reads, sun_glare_threshold_);
  if (sky_code_branch)
    for (size_t k = 0; k < n; ++k) {
      if (k < glare_reads.size()) {
        singles[k].glare_azimuth = glare_reads[k].azimuth;
        if (sun_glare_map_weight_ > 0.0) singles[k].glare_cells = glare_reads[k].cells;
      }
      average_sun(views[k], singles[k], mirror[k]);
    }
  if (!sky_code_branch) {
    // No sky vector (ablations): the predictor's own dome is the estimate; no flip, crops or cue.
    for (size_t k = 0; k < n; ++k) singles[k].pred = predictor_->predict(images[k], rgba[k]);
  }
  const Single& ref = singles[0];
  EstimatedLighting out;
  for (const Single& s : singles) {
    out.sun_flip_spread_deg = std::fmax(out.sun_flip_spread_deg, s.flip_spread_deg);
    out.sun_crop_spread_deg = std::fmax(out.sun_crop_spread_deg, s.crop_spread_deg);
  }
  out.network_sun_flip_spread_deg = out.sun_flip_spread_deg;
  for (const Single& s : singles)
    if (std::isfinite(s.sun_probability))
      out.sun_probability = std::isfinite(out.sun_probability) ? std::min(out.sun_probability, s.sun_probability)
                                                               : s.sun_probability;
  out.network_sun_probability = out.sun_probability;
  for (const Single& s : singles) {
    out.glare_azimuth_used = out.glare_azimuth_used || s.glare_azimuth_used;
    out.glare_map_used = out.glare_map_used || s.glare_map_used;
  }
  out.network_sun_crop_spread_deg = out.sun_crop_spread_deg;
  out.frame = ref.frame;
  out.camera = ref.camera;
  out.grid = ref.grid;
  const bool has_code = ref.pred.code.dir.defined();
  SL_CHECK(!edit.active() || has_code, "sun editing needs the 'sky_decoder' sky branch; checkpoint '", path_,
           "' uses '", predictor_->options().sky_branch, "'");
  if (has_code) {
    // Sec 4.1: max-pool intensity and latent, average the directions rotated into view 0's frame.
    std::vector<double> log_i = to_doubles(ref.pred.code.log_intensity), latent = to_doubles(ref.pred.code.latent);
    glm::dvec3 dir_sum(0.0);
    for (const Single& s : singles) {
      const std::vector<double> li = to_doubles(s.pred.code.log_intensity), la = to_doubles(s.pred.code.latent),
                                d = to_doubles(s.pred.code.dir);
      for (size_t i = 0; i < log_i.size(); ++i) log_i[i] = std::max(log_i[i], li[i]);
      for (size_t i = 0; i < latent.size(); ++i) latent[i] = std::max(latent[i], la[i]);
      const glm::dvec3 world = rotate_direction_azimuth({d[0], d[1], d[2]}, s.frame.yaw_rad);
      dir_sum += ref.frame.direction(world);
    }
    glm::dvec3 dir = glm::length(dir_sum) > 1e-12 ? glm::normalize(dir_sum) : glm::dvec3(0.0, 1.0, 0.0);
    out.sun_hedge = std::clamp(dir.y, 0.0, 1.0);
    // The visible sun fills the direction fields the caller's edit leaves unset.
    SunEdit sun = edit;
    if (want_cue) {
      if (cue.found) {
        out.visible_sun_found = true;
        out.visible_sun_learned = cue.learned;
        out.visible_sun_view = cue.view;
        out.visible_sun_pixel = cue.sun.pixel;
        out.visible_sun_score = cue.sun.score;
        if (!sun.azimuth_deg) sun.azimuth_deg = azimuth_deg_of(cue.sun.direction);
        if (!sun.elevation_deg) sun.elevation_deg = elevation_deg_of(cue.sun.direction);
        if (!edit.azimuth_deg && !edit.elevation_deg)
          out.sun_flip_spread_deg = 0.0, out.sun_crop_spread_deg = 0.0, out.sun_hedge = 0.0,
          out.sun_probability = std::isfinite(out.sun_probability) ? 1.0 : out.sun_probability;
      }
    }
    // Sec 3.2: edit the sky vector before decoding.
    if (sun.azimuth_deg || sun.elevation_deg) {
      const glm::dvec3 world = out.world_direction(dir);
      const double az = sun.azimuth_deg.value_or(azimuth_deg_of(world));
      const double el = sun.elevation_deg.value_or(elevation_deg_of(world));
      dir = ref.frame.direction(direction_from_azimuth_elevation_deg(az, el));
    }
    SL_CHECK(std::isfinite(sun.intensity_scale) && sun.intensity_scale > 0, "sun intensity scale ",
             sun.intensity_scale, " must be positive");
    for (double& v : log_i) v += std::log(sun.intensity_scale);
    SkyCode code;
    const int64_t d_lat = static_cast<int64_t>(latent.size());
    code.log_intensity = Tensor::from_vector(log_i, {1, 3}).to(DType::F32);
    code.latent = Tensor::from_vector(latent, {1, d_lat}).to(DType::F32);
    code.dir = Tensor::from_vector({dir.x, dir.y, dir.z}, {1, 3}).to(DType::F32);
    out.env = select(predictor_->sky_decoder()->decode(code).hdr, 0, 0).contiguous();
    out.has_sky_code = true;
    out.sky_code = code;
    out.sun_direction_canonical = dir;
    out.sun_intensity_rgb = {std::exp(log_i[0]), std::exp(log_i[1]), std::exp(log_i[2])};
  } else {
    // No sky vector (ablations): fuse the domes by the per-texel maximum after rotation.
    Tensor env = select(ref.pred.env, 0, 0).contiguous();
    for (size_t k = 1; k < singles.size(); ++k) {
      const Tensor other = rotate_azimuth(select(singles[k].pred.env, 0, 0).contiguous(),
                                          singles[k].frame.yaw_rad - ref.frame.yaw_rad);
      env = maximum(env, other);
    }
    out.env = env.contiguous();
  }
  if (ref.pred.vsg.defined()) {
    if (singles.size() == 1) {
      out.vsg = select(ref.pred.vsg, 0, 0).contiguous();
    } else {
      // Alpha-weighted fusion on view 0's grid.
      const Tensor first = select(ref.pred.vsg, 0, 0).contiguous();
      const int64_t voxels = first.numel() / 8;
      std::vector<double> acc(static_cast<size_t>(first.numel()), 0.0), wsum(voxels, 0.0), amax(voxels, 0.0);
      for (const Single& s : singles) {
        const Tensor r = resample_vsg(select(s.pred.vsg, 0, 0).contiguous(), s.grid, s.frame, out.grid, out.frame);
        const std::vector<double> v = to_doubles(r);
        for (int64_t i = 0; i < voxels; ++i) {
          const double a = v[7 * voxels + i], w = a + 1e-6;
          for (int c = 0; c < 7; ++c) acc[c * voxels + i] += w * v[c * voxels + i];
          wsum[i] += w;
          amax[i] = std::max(amax[i], a);
        }
      }
      for (int64_t i = 0; i < voxels; ++i) {
        for (int c = 0; c < 7; ++c) acc[c * voxels + i] /= wsum[i];
        acc[7 * voxels + i] = amax[i];
      }
      out.vsg = Tensor::from_vector(acc, first.shape()).to(DType::F32);
    }
  }
  out.inference_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

Tensor resample_vsg(const Tensor& vsg, const VsgGrid& from_grid, const CanonicalFrame& from_frame,
                    const VsgGrid& to_grid, const CanonicalFrame& to_frame) {
  SL_CHECK(vsg.dim() == 4 && vsg.size(0) == 8, "resample_vsg: expected [8, X, Y, Z], got ", vsg.describe());
  const Tensor src = vsg.detach().to(DType::F32).contiguous();
  const float* s = src.data<float>();
  const auto& fd = from_grid.dims;
  const auto& td = to_grid.dims;
  const int64_t n_from = fd[0] * fd[1] * fd[2], n_to = td[0] * td[1] * td[2];
  Tensor out = Tensor::zeros({8, td[0], td[1], td[2]});
  float* o = out.data<float>();
  // to-frame → world → from-frame.
  auto to_world_dir = [&](const glm::dvec3& d) { return rotate_direction_azimuth(d, to_frame.yaw_rad); };
  auto from_to_world_dir = [&](const glm::dvec3& d) { return rotate_direction_azimuth(d, from_frame.yaw_rad); };
  for (int64_t x = 0; x < td[0]; ++x)
    for (int64_t y = 0; y < td[1]; ++y)
      for (int64_t z = 0; z < td[2]; ++z) {
        const glm::dvec3 p_to = to_grid.to_world({x + 0.5, y + 0.5, z + 0.5});
        const glm::dvec3 r = to_world_dir(p_to);
        const glm::dvec3 world(r.x + to_frame.camera_world.x, r.y, r.z + to_frame.camera_world.z);
        const glm::dvec3 p_from = from_frame.point(world);
        if (!from_grid.contains(p_from)) continue;
        const glm::dvec3 vox = from_grid.to_voxel(p_from);
        const int64_t i = std::clamp<int64_t>(static_cast<int64_t>(vox.x), 0, fd[0] - 1);
        const int64_t j = std::clamp<int64_t>(static_cast<int64_t>(vox.y), 0, fd[1] - 1);
        const int64_t k = std::clamp<int64_t>(static_cast<int64_t>(vox.z), 0, fd[2] - 1);
        const int64_t si = (i * fd[1] + j) * fd[2] + k, ti = (x * td[1] + y) * td[2] + z;
        for (int c = 0; c < 8; ++c) o[c * n_to + ti] = s[c * n_from + si];
        // Lobe axis: from-frame → world → to-frame.
        const glm::dvec3 axis(s[3 * n_from + si], s[4 * n_from + si], s[5 * n_from + si]);
        const glm::dvec3 a = to_frame.direction(from_to_world_dir(axis));
        o[3 * n_to + ti] = static_cast<float>(a.x);
        o[4 * n_to + ti] = static_cast<float>(a.y);
        o[5 * n_to + ti] = static_cast<float>(a.z);
      }
  return out;
}

}  // namespace sl::train
