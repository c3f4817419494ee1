// Stage 2: supervised hybrid lighting prediction (Sec 3.4). See lighting_stage.h.
#include "train/lighting_stage.h"

#include <chrono>
#include <cmath>
#include <future>
#include <limits>
#include <map>
#include <utility>

#include "autodiff/ops.h"
#include "data/augment.h"
#include "data/hdri_folder.h"
#include "data/hdri_split.h"
#include "data/panorama.h"
#include "data/sun_extraction.h"
#include "nn/checkpoint.h"
#include "nn/functional/gradient_reversal.h"
#include "nn/modules/mlp.h"
#include "nn/modules/mobilenet_v2_tflite.h"
#include "nn/safetensors.h"
#include "render/environment_map.h"
#include "render/radiance_query.h"
#include "train/adversarial_stage.h"
#include "train/image_statistics.h"
#include "train/image_strip.h"
#include "train/losses.h"
#include "train/metrics.h"
#include "train/phase_clock.h"
#include "train/predictor_warm_start.h"
#include "train/sun_distribution.h"
#include "train/sun_error_parts.h"
#include "train/train_config.h"
#include "train/distributed.h"
#include "train/gradient_allreduce.h"
#include "util/process_memory.h"
#include "util/random.h"

using sl::data::epoch_order;
using sl::data::extract_sun;
using sl::data::PanoramaSampleOptions;
using sl::data::StreetSample;
using sl::data::StreetView;
using sl::data::to_ldr;
using sl::render::Camera;
using sl::render::CameraRay;
using sl::render::env_lookup;
using sl::render::Intrinsics;
using sl::render::radiance_query;
using sl::render::RadianceQueryOptions;
using sl::render::RadianceQueryResult;

namespace sl::train {

namespace {

constexpr uint64_t kValSeed = 0x76616c5f726179ULL;

class LightingModel : public nn::Module {
 public:
  LightingModel() : nn::Module("LightingModel") {}
};

nn::NamedTensors trainable(const nn::Module& m) {
  nn::NamedTensors out;
  for (auto& [n, p] : m.named_parameters())
    if (p.requires_grad()) out.emplace_back(n, p);
  return out;
}

Tensor dvec_rows(const std::vector<glm::dvec3>& v) {
  std::vector<double> flat;
  for (const auto& d : v) flat.insert(flat.end(), {d.x, d.y, d.z});
  return Tensor::from_vector(flat, {static_cast<int64_t>(v.size()), 3});
}

glm::dvec3 row3(const Tensor& t, int64_t i) {
  const Tensor r = select(t.detach(), 0, i).to(DType::F64).contiguous();
  const double* p = r.data<double>();
  return {p[0], p[1], p[2]};
}

}  // namespace

LightingStage::LightingStage(const nlohmann::json& config, SampleSource train, SampleSource val)
    : config_(config), train_(std::move(train)), val_(std::move(val)) {
  adversarial_ = config.at("stage").get<std::string>() == kStageAdversarial;
  seed_ = config.at("seed").get<uint64_t>();
  batch_size_ = config.at("train").at("batch_size").get<int64_t>();
  clip_ = config.at("optim").at("clip_grad_norm").get<double>();
  best_metric_ = config.at("train").value("best_metric", std::string("val_loss"));
  flip_ = config.at("data").value("flip", false);
  SL_CHECK(train_.size > 0, "stage ", name(), ": the training split is empty");
  const LightingPredictorOptions po = predictor_options(config);
  batch_opt_ = StreetBatchOptions{.image_height = po.image_height,
                                  .image_width = po.image_width,
                                  .dome_height = po.sky.height,
                                  .dome_width = po.sky.width,
                                  .pano_rays = config.at("data").at("pano_rays").get<int64_t>(),
                                  .view_rays = config.at("data").at("view_rays").get<int64_t>(),
                                  .need_volume = po.volume_branch};
  grid_template_ = vsg_grid(config, 1.6);
  model_ = std::make_shared<LightingModel>();
  predictor_ = model_->register_module("predictor", std::make_shared<LightingPredictor>(po));
  if (po.sky_branch != "constant") {
    teacher_ = model_->register_module("teacher", std::make_shared<SkyAutoencoder>(po.sky));
    teacher_->freeze(true);
    teacher_->eval();
  }
  if (adversarial_ && config.at("loss").at("adversarial").get<double>() > 0) {
    const auto& d = config.at("model").at("discriminator");
    discriminator_ = model_->register_module(
        "discriminator", std::make_shared<nn::PatchDiscriminator>(nn::PatchDiscriminatorOptions{
                             .base_channels = d.at("base_channels").get<int64_t>(),
                             .layers = d.at("layers").get<int>(),
                             .norm = d.at("norm").get<std::string>(),
                             .seed = seed_ + 2}));
    discriminator_->init_parameters(seed_ + 2);
  }
  if (!adversarial_ && config.at("loss").at("domain_adversarial").get<double>() > 0)
    domain_head_ = model_->register_module(
        "domain_head", std::make_shared<nn::MLP>(nn::MlpOptions{.widths = {predictor_->feature_dim(), 64, 1}, .seed = seed_ + 3}));
  // train.freeze: parts of the predictor that keep their weights (and batch-norm statistics):
  // fine-tuning the heads on a new data mix over a fixed backbone (configs/README.md).
  for (const auto& part : config.at("train").value("freeze", nlohmann::json::array())) {
    const std::string name = part.get<std::string>();
    std::string known;
    std::shared_ptr<nn::Module> part_module;
    for (const auto& [n, child] : predictor_->children()) {
      known += (known.empty() ? "" : ", ") + n;
      if (n == name) part_module = child;
    }
    SL_CHECK(part_module != nullptr, "train.freeze: the predictor has no part '", name, "' (its parts: ", known, ")");
    part_module->freeze(true);
  }
  optim_ = std::make_unique<nn::AdamW>(trainable(*model_),
                                       nn::AdamOptions{.lr = config.at("optim").at("lr").get<double>(),
                                                       .weight_decay = config.at("optim").at("weight_decay").get<double>()});
  // The domain classifier starts afresh inside a model that may be fine-tuned at a small rate: it
  // learns at loss.domain_lr_scale times the stage's rate.
  if (domain_head_) optim_->set_lr_scale("domain_head.", config.at("loss").at("domain_lr_scale").get<double>());
}

void LightingStage::initialise() {
  const auto& init = config_.at("init");
  const std::string sky = init.at("sky_checkpoint").get<std::string>();
  const std::string prev = init.at("checkpoint").get<std::string>();
  if (!prev.empty()) {
    // Start from a stage-2 checkpoint: predictor and teacher (no discriminator, no optimiser).
    // An exported model (models/streetlight.safetensors) holds the predictor alone; its teacher
    // then comes from init.sky_checkpoint.
    const bool has_teacher = warm_start_predictor(prev, predictor_, teacher_);
    // init.reinitialise: parts that start afresh (the predictor's own initialisation for this
    // config's seed) while the rest comes from the checkpoint, e.g. a backbone trained from
    // scratch under the loaded frozen sky decoder.
    const auto& again = init.at("reinitialise");
    SL_CHECK(again.is_array(), "init.reinitialise must be a list of the predictor's parts, got ", again.dump());
    if (!again.empty()) {
      const LightingPredictor fresh(predictor_->options());
      for (const auto& part : again) {
        const std::string name = part.is_string() ? part.get<std::string>() : part.dump();
        std::string known;
        bool found = false;
        for (const auto& [n, child] : predictor_->children())
          if (n != "sky_decoder") known += (known.empty() ? "" : ", ") + n, found |= part.is_string() && n == name;
        SL_CHECK(found, "init.reinitialise: no part '", name, "' to start afresh (the predictor's parts but its frozen ",
                 "sky_decoder: ", known, ")");
        nn::StateDict state = fresh.child(name)->state_dict();
        for (auto& [n, t] : state) t = t.clone();
        predictor_->child(name)->load_state_dict(state);
      }
    }
    if (teacher_ && !has_teacher) {
      // Without pseudo-labels the teacher never runs, and may stay as initialised: a later stage
      // that needs it finds its decoder differs from the predictor's (below) and refuses.
      SL_CHECK(!sky.empty() || !teacher_pseudo_labels(), "stage ", name(), ": init.checkpoint '", prev,
               "' holds no teacher (an exported model); init.sky_checkpoint must name a stage-1 checkpoint, ",
               "or loss.sky_intensity and loss.sky_latent be 0");
      if (!sky.empty()) nn::load_checkpoint(sky, *teacher_, nullptr);
    }
  } else if (teacher_) {
    SL_CHECK(!sky.empty(), "stage ", name(), ": init.sky_checkpoint must name the stage-1 checkpoint");
    nn::load_checkpoint(sky, *teacher_, nullptr);
    if (predictor_->sky_decoder()) predictor_->sky_decoder()->load_state_dict(teacher_->decoder()->state_dict());
  }
  // init.sun_backbone_weights: ImageNet weights (a TFLite MobileNetV2) for the sun head's own
  // backbone, unless init.checkpoint brought one (a later run of the same model).
  const std::string sun_weights = init.at("sun_backbone_weights").get<std::string>();
  if (!sun_weights.empty()) {
    SL_CHECK(predictor_->sun_backbone() != nullptr, "init.sun_backbone_weights '", sun_weights,
             "' needs model.sun_backbone \"mobilenet_v2\"");
    bool brought = false;
    if (!prev.empty())
      for (const auto& [n, t] : nn::read_safetensors(prev).tensors) brought |= n.rfind("predictor.sun_backbone.", 0) == 0;
    if (!brought) nn::load_mobilenet_v2_tflite(*predictor_->sun_backbone(), sun_weights);
  }
  // The pseudo-labels f̃_int, f̃_lat live in the latent space of the teacher's decoder: they mean
  // something to the predictor only when that decoder is its own frozen one, bit for bit.
  if (teacher_ && predictor_->sky_decoder() && teacher_pseudo_labels()) {
    const nn::StateDict mine = predictor_->sky_decoder()->state_dict(), teachers = teacher_->decoder()->state_dict();
    bool same = mine.size() == teachers.size();
    for (const auto& [n, t] : mine) same = same && teachers.count(n) && teachers.at(n).to_vector() == t.to_vector();
    SL_CHECK(same, "stage ", name(), ": the teacher's decoder",
             prev.empty() ? "" : " (init.sky_checkpoint '" + sky + "')",
             " is not the predictor's frozen sky decoder, so its sky_intensity / sky_latent pseudo-labels ",
             "would be in another latent space: give the stage-1 checkpoint the predictor was trained with, ",
             "or set loss.sky_intensity and loss.sky_latent to 0");
  }
}

bool LightingStage::teacher_pseudo_labels() const {
  const auto& w = config_.at("loss");
  return w.at("sky_intensity").get<double>() != 0 || w.at("sky_latent").get<double>() != 0;
}

LightingStage::Batch LightingStage::make_batch(std::vector<StreetSample> samples, const std::vector<size_t>& views,
                                               uint64_t seed, uint64_t first_stream) const {
  Batch b;
  for (size_t i = 0; i < samples.size(); ++i)
    b.items.push_back(make_street_item(samples[i], views[i], grid_template_, batch_opt_, seed, first_stream + i));
  b.samples = std::move(samples);
  return b;
}

LightingStage::Forward LightingStage::run_predictor(Batch batch) {
  Forward f;
  TensorList images, rgba;
  for (const auto& it : batch.items) {
    images.push_back(it.image);
    if (batch_opt_.need_volume) rgba.push_back(it.rgba);
  }
  f.samples = std::move(batch.samples);
  f.items = std::move(batch.items);
  f.pred = predictor_->predict(stack(images, 0), rgba.empty() ? Tensor() : stack(rgba, 0));
  return f;
}

LightingStage::Batch LightingStage::train_batch(int64_t step) const {
  std::vector<StreetSample> samples;
  std::vector<size_t> views;
  const uint64_t n = train_.size;
  std::vector<size_t> order;
  uint64_t order_epoch = std::numeric_limits<uint64_t>::max();
  const uint64_t first = shard_first_index(step, batch_size_);  // this rank's shard (distributed.h)
  for (int64_t i = 0; i < batch_size_; ++i) {
    const uint64_t global = first + static_cast<uint64_t>(i);
    if (global / n != order_epoch) {
      order_epoch = global / n;
      order = epoch_order(n, seed_, order_epoch);
    }
    samples.push_back(train_.load(order[global % n], global));
    Rng rng(seed_, global);
    // Stage 3 inserts into view 0 (the view with the path-traced ground truth).
    views.push_back(adversarial_ ? 0 : static_cast<size_t>(rng.randint(static_cast<int64_t>(samples.back().views.size()))));
    // data.flip: the whole sample mirrored with probability 1/2 (stage 2 only: the mirrored
    // scene's object is not the .glb's, so stage 3's insertion keeps the world as it is).
    if (flip_ && !adversarial_ && rng.uniform() < 0.5) samples.back() = data::flip_sample(samples.back());
  }
  return make_batch(std::move(samples), views, seed_, first);
}

LightingStage::Forward LightingStage::forward_train(int64_t step) {
  const auto t0 = std::chrono::steady_clock::now();
  Batch batch;
  if (prefetch_.valid() && prefetch_step_ == step) {
    batch = prefetch_.get();
  } else {
    if (prefetch_.valid()) prefetch_.get();  // a stale prefetch (e.g. after a resume): drop it
    batch = train_batch(step);
  }
  last_data_ms_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  prefetch_step_ = step + 1;
  prefetch_ = std::async(std::launch::async, [this, next = step + 1] { return train_batch(next); });
  Forward f = run_predictor(std::move(batch));
  if (is_distributed()) {  // sky_ldr is a masked mean: normalise by the global batch's mask count
    double count = 0;
    for (const auto& it : f.items) count += 3.0 * sum(it.pano_mask_dome).item();
    f.sky_ldr_share = global_share(count);
  }
  return f;
}

LightingStage::Forward LightingStage::forward_val(size_t index) {
  return run_predictor(make_batch({val_.load(index, index)}, {0}, seed_ ^ kValSeed, index));
}

LightingStage::Query LightingStage::query(const Forward& f, size_t i, const Tensor& origins, const Tensor& directions) {
  const Tensor env = select(f.pred.env, 0, static_cast<int64_t>(i));
  Query q;
  if (f.pred.vsg.defined()) {
    const RadianceQueryOptions qo = volume_query_options(config_);
    const RadianceQueryResult r = radiance_query(select(f.pred.vsg, 0, static_cast<int64_t>(i)), env, origins,
                                                 directions, f.items[i].grid, qo);
    q.radiance = r.radiance;
    q.transmittance = r.transmittance;
    q.depth = r.depth;
  } else {
    q.radiance = env_lookup(env, directions);
  }
  return q;
}

Tensor LightingStage::supervised_loss(const Forward& f, Metrics& m) {
  const auto& w = config_.at("loss");
  const std::string branch = predictor_->options().sky_branch;
  const int64_t n = static_cast<int64_t>(f.items.size());
  Tensor total = Tensor::scalar(0.0);
  auto add_term = [&](const std::string& key, const Tensor& value) {
    const double weight = w.at(key).get<double>();
    m[key] = value.item();
    if (weight != 0) total = add(total, mul_scalar(value, weight));
  };
  // Sky branch (batched).
  TensorList pano, mask, known_dirs;
  std::vector<glm::dvec3> suns;
  for (size_t i = 0; i < f.items.size(); ++i) {
    pano.push_back(f.items[i].pano_ldr_dome);
    mask.push_back(f.items[i].pano_mask_dome);
    if (!f.samples[i].sun_known) continue;  // a soft or hidden sun is no direction label
    suns.push_back(f.items[i].sun_direction);
    if (f.pred.code.dir.defined()) known_dirs.push_back(select(f.pred.code.dir, 0, static_cast<int64_t>(i)));
  }
  const Tensor pano_b = stack(pano, 0), mask_b = stack(mask, 0);
  if (branch != "constant") {
    // The teacher runs only for a loss that reads it (with sky_intensity = sky_latent = 0 the
    // sky-decoder branch needs none of its pseudo-labels).
    SkyAutoencoder::Output teacher;
    const bool need_teacher = branch != "sky_decoder" || teacher_pseudo_labels();
    if (need_teacher) {
      NoGradGuard no_grad;
      teacher = teacher_->run(pano_b);
    }
    if (branch == "sky_decoder") {
      if (need_teacher) {
        add_term("sky_intensity", log_encoded_l2_from_log(f.pred.code.log_intensity, teacher.code.intensity()));
        add_term("sky_latent", l1(f.pred.code.latent, teacher.code.latent));
      }
      const bool split = w.at("sky_direction_form").get<std::string>() == "elevation_azimuth";
      // The sun as a distribution over the hemisphere (issue 53, train/sun_distribution.h):
      // cross-entropy against a soft target around the true sun, each label at its weight.
      if (f.pred.sun_logits.defined()) {
        const SunGrid& grid = predictor_->options().sun_grid;
        const double width = w.value("sun_distribution_width_deg", 8.0);
        const double low_sun = w.value("low_sun_weight", 0.0), low_below = w.value("low_sun_below_deg", 30.0);
        std::vector<double> targets, weights;
        for (size_t i = 0; i < f.items.size(); ++i) {
          const bool known = f.samples[i].sun_known;
          const std::vector<double> t =
              known ? soft_target(grid, f.items[i].sun_direction, width)
                    : std::vector<double>(static_cast<size_t>(grid.cells()), 1.0 / static_cast<double>(grid.cells()));
          targets.insert(targets.end(), t.begin(), t.end());
          // Low suns weighed up (loss.low_sun_weight, 0 = off): the training labels sit higher
          // than the skies the model meets.
          weights.push_back(known ? f.samples[i].sun_weight * low_sun_weight(f.items[i].sun_direction, low_sun, low_below)
                                  : 0.0);
        }
        const Tensor target_b = Tensor::from_vector(targets, {n, grid.cells()}), weight_b = Tensor::from_vector(weights, {n});
        add_term("sun_distribution", sun_distribution_loss(f.pred.sun_logits, target_b, weight_b));
        // The same on the two halves, front and back (computed only when weighed).
        if (w.at("sun_half").get<double>() != 0) add_term("sun_half", sun_half_loss(grid, f.pred.sun_logits, target_b, weight_b));
      }
      add_term("sky_direction",
               suns.empty() ? Tensor::scalar(0.0)
                            : mul_scalar(split ? elevation_azimuth_l1(stack(known_dirs, 0), dvec_rows(suns))
                                               : angular_l1(stack(known_dirs, 0), dvec_rows(suns)),
                                         static_cast<double>(suns.size()) / static_cast<double>(n)));
      // The sun's energy where the sky is HDR: the analytic lobe f_int·exp(λ(d·f_dir − 1)) holds
      // f_int·2π(1 − e^(−2λ))/λ over the sphere; its label is the true Σ L·Ω near the sun.
      TensorList log_int;
      std::vector<glm::dvec3> energy;
      for (size_t i = 0; i < f.items.size(); ++i)
        if (f.items[i].sun_energy_known) {
          log_int.push_back(select(f.pred.code.log_intensity, 0, static_cast<int64_t>(i)));
          energy.push_back(f.items[i].sun_energy);
        }
      const auto& so = predictor_->options().sky;
      const double lambda = sun_lobe_sharpness(so.height, so.sun_lobe_texels);
      const double log_lobe = std::log(2.0 * kPi * -std::expm1(-2.0 * lambda) / lambda);
      Tensor energy_term = Tensor::scalar(0.0);
      if (!energy.empty()) {
        const Tensor pred = add_scalar(stack(log_int, 0), log_lobe);
        energy_term = mul_scalar(log_encoded_l2_from_log(pred, dvec_rows(energy).to(pred.dtype())),
                                 static_cast<double>(energy.size()) / static_cast<double>(n));
      }
      add_term("sun_energy", energy_term);
      // Sunny LDR panoramas carry no energy label (their sun is clipped), only a plausible span:
      // outside loss.ldr_sun_energy_range the lobe's energy is pulled back to its nearest end.
      TensorList ldr_log_int;
      for (size_t i = 0; i < f.items.size(); ++i)
        if (f.samples[i].sun_known && !f.samples[i].hdr_sky)
          ldr_log_int.push_back(select(f.pred.code.log_intensity, 0, static_cast<int64_t>(i)));
      Tensor range_term = Tensor::scalar(0.0);
      if (!ldr_log_int.empty()) {
        const auto& range = w.at("ldr_sun_energy_range");
        range_term = mul_scalar(log_encoded_range_l2_from_log(add_scalar(stack(ldr_log_int, 0), log_lobe),
                                                              range.at(0).get<double>(), range.at(1).get<double>()),
                                static_cast<double>(ldr_log_int.size()) / static_cast<double>(n));
      }
      add_term("ldr_sun_energy", range_term);
    } else {
      add_term("sky_hdr", log_encoded_l2_from_log(f.pred.log_env, teacher.sky.hdr));
    }
    const Tensor sky_ldr = masked_l1(ldr_from_hdr(f.pred.env), pano_b, mask_b);
    add_term("sky_ldr", f.sky_ldr_share == 1.0 ? sky_ldr : mul_scalar(sky_ldr, f.sky_ldr_share));
  }
  // Volume branch: per sample, radiance-queried rays (Eq. 1).
  Tensor rad_sum = Tensor::scalar(0.0), depth_sum = Tensor::scalar(0.0), sep_sum = Tensor::scalar(0.0);
  for (size_t i = 0; i < f.items.size(); ++i) {
    const StreetItem& it = f.items[i];
    const Query q = query(f, i, it.origins, it.directions);
    rad_sum = add(rad_sum, radiance_l2(q.radiance, it.target_ldr));
    if (q.transmittance.defined()) {
      depth_sum = add(depth_sum, depth_consistency(q.depth, q.transmittance, it.target_distance));
      sep_sum = add(sep_sum, sky_separation_bce(q.transmittance, it.sky));
    }
  }
  add_term("radiance", mul_scalar(rad_sum, 1.0 / static_cast<double>(n)));
  if (f.pred.vsg.defined()) {
    add_term("depth", mul_scalar(depth_sum, 1.0 / static_cast<double>(n)));
    add_term("sky_separation", mul_scalar(sep_sum, 1.0 / static_cast<double>(n)));
  }
  m["loss"] = total.item();
  return total;
}

Tensor LightingStage::domain_loss(const Forward& f, Metrics& m) {
  const auto& w = config_.at("loss");
  const int64_t n = static_cast<int64_t>(f.samples.size());
  std::vector<double> real;
  for (const auto& s : f.samples) real.push_back(sample_origin(s.id) == SampleOrigin::Street ? 0.0 : 1.0);
  const Tensor g = nn::gradient_reversal(f.pred.features, w.at("domain_reversal").get<double>());
  const Tensor logits = reshape(domain_head_->forward(g), {n});
  const Tensor labels = Tensor::from_vector(real, {n}).to(logits.dtype());
  const Tensor loss = bce_with_logits(logits, labels);
  m["domain_adversarial"] = loss.item();
  const std::vector<double> z = logits.to_vector();
  double right = 0;
  for (size_t i = 0; i < z.size(); ++i) right += (z[i] >= 0) == (real[i] == 1.0) ? 1.0 : 0.0;
  m["domain_accuracy"] = right / static_cast<double>(n);
  return mul_scalar(loss, w.at("domain_adversarial").get<double>());
}

Metrics LightingStage::supervised_step(int64_t step) {
  predictor_->set_training(true);
  optim_->zero_grad();
  PhaseClock clock;
  const Forward f = forward_train(step);
  Metrics m;
  Tensor total = supervised_loss(f, m);
  if (domain_head_) total = add(total, domain_loss(f, m));
  const double forward_ms = clock.lap();
  for (const auto& [k, v] : m) check_finite_loss(k, v, step);
  backward(total);
  const double backward_ms = clock.lap();
  if (is_distributed()) {
    m["time_allreduce_ms"] = allreduce_gradients(optim_->params());
    clock.lap();  // not part of the optimiser's time
  }
  m["grad_norm"] = clip_finite_gradients(optim_->params(), clip_, step);
  optim_->step();
  // The share of this batch's labelled suns that the input view shows (issue 53: crops that
  // show the sun must be common enough to learn from).
  int in_view = 0, labelled = 0;
  for (size_t i = 0; i < f.items.size(); ++i) {
    if (!f.samples[i].sun_known) continue;
    ++labelled;
    const StreetItem& it = f.items[i];
    in_view += it.camera.project(it.camera.position() + 1e4 * it.sun_direction).in_image;
  }
  m["sun_in_view_share"] = labelled ? static_cast<double>(in_view) / labelled : 0.0;
  m["time_data_ms"] = last_data_ms_;
  m["time_forward_ms"] = forward_ms - last_data_ms_;
  m["time_render_ms"] = 0.0;
  m["time_backward_ms"] = backward_ms;
  m["time_optimizer_ms"] = clock.lap();
  return m;
}

Metrics LightingStage::step(int64_t step) { return supervised_step(step); }

Metrics LightingStage::validate() {
  NoGradGuard no_grad;
  predictor_->set_training(false);
  const size_t n = val_.size;
  Metrics sum_m;
  std::vector<double> sun_err, real_err, ldr_err, street_err, psnrs, si_psnrs;
  // Predicted and true suns per group (street, real HDR, LDR), for train/sun_error_parts.h.
  std::map<std::string, std::pair<std::vector<glm::dvec3>, std::vector<glm::dvec3>>> parts;
  const int64_t val_h = config_.at("data").at("val_view_height").get<int64_t>();
  for (size_t s = 0; s < n; ++s) {
    const Forward f = forward_val(s);
    Metrics m;
    supervised_loss(f, m);
    for (const auto& [k, v] : m) sum_m["val_" + k] += v / static_cast<double>(n);
    glm::dvec3 dir;
    if (f.pred.sun_logits.defined()) {  // the distribution's mode, as inference reads it
      dir = read_sun_distribution(predictor_->options().sun_grid,
                                  softmax_row(select(f.pred.sun_logits, 0, 0).to(DType::F64).contiguous().to_vector()))
                .direction;
    } else if (f.pred.code.dir.defined()) {
      dir = row3(f.pred.code.dir, 0);
    } else {
      dir = extract_sun(select(f.pred.env, 0, 0).contiguous().to(DType::F32)).direction;
    }
    if (f.samples[0].sun_known) {
      const double e = angular_error_deg(dir, f.items[0].sun_direction);
      sun_err.push_back(e);
      const SampleOrigin origin = sample_origin(f.samples[0].id);
      (origin == SampleOrigin::HdrCrop ? real_err : origin == SampleOrigin::LdrCrop ? ldr_err : street_err).push_back(e);
      const double len = glm::length(dir) * glm::length(f.items[0].sun_direction);
      if (std::isfinite(len) && len > 0.0) {  // sun_error_parts refuses a zero direction
        auto& group = parts[origin == SampleOrigin::HdrCrop ? "real" : origin == SampleOrigin::LdrCrop ? "ldr" : "street"];
        group.first.push_back(dir);
        group.second.push_back(f.items[0].sun_direction);
      }
    }
    // Novel views: every view but the input, rendered through the radiance query.
    for (size_t v = 1; v < f.samples[0].views.size(); ++v) {
      const StreetView& view = f.samples[0].views[v];
      const Camera world_cam = view.camera;
      const double scale = static_cast<double>(val_h) / world_cam.intrinsics().height;
      Intrinsics k = world_cam.intrinsics().scaled(scale, scale);
      const Camera cam = f.items[0].frame.camera(Camera(k, world_cam.rotation(), world_cam.position()));
      std::vector<double> o, d;
      for (int r = 0; r < k.height; ++r)
        for (int c = 0; c < k.width; ++c) {
          const CameraRay ray = cam.pixel_ray(c, r);
          o.insert(o.end(), {ray.origin.x, ray.origin.y, ray.origin.z});
          d.insert(d.end(), {ray.direction.x, ray.direction.y, ray.direction.z});
        }
      const int64_t rays = static_cast<int64_t>(k.width) * k.height;
      const Query q = query(f, 0, Tensor::from_vector(o, {rays, 3}), Tensor::from_vector(d, {rays, 3}));
      const Tensor pred = permute(reshape(ldr_from_hdr(q.radiance), {k.height, k.width, 3}), {2, 0, 1}).contiguous();
      const Tensor truth = resize_bilinear(view.ldr, k.height, k.width);
      psnrs.push_back(psnr(pred, truth));
      si_psnrs.push_back(si_psnr(pred, truth));
    }
  }
  sum_m["val_sun_error_median_deg"] = median(sun_err);
  sum_m["val_sun_error_mean_deg"] = mean_of(sun_err);
  if (!street_err.empty()) sum_m["val_street_sun_error_median_deg"] = median(street_err);
  if (!real_err.empty()) sum_m["val_real_sun_error_median_deg"] = median(real_err);
  if (!ldr_err.empty()) sum_m["val_ldr_sun_error_median_deg"] = median(ldr_err);
  // The error in parts per group: the share of suns in the wrong half (in front of the view or
  // behind it), the median elevation bias and, where defined, the median azimuth error.
  for (const auto& [group, dirs] : parts) {
    const SunErrorParts p = sun_error_parts(dirs.first, dirs.second);
    const std::string pre = "val_" + group + "_sun_";
    sum_m[pre + "wrong_half_share"] = static_cast<double>(p.front_back_wrong()) / static_cast<double>(p.count);
    sum_m[pre + "elevation_bias_deg"] = p.elevation_bias_median_deg;
    if (p.azimuth_count > 0) sum_m[pre + "azimuth_error_median_deg"] = p.azimuth_error_median_deg;
  }
  if (!psnrs.empty()) {
    sum_m["val_psnr"] = mean_of(psnrs);
    sum_m["val_si_psnr"] = mean_of(si_psnrs);
  }
  predictor_->set_training(true);
  return sum_m;
}

void LightingStage::write_strip(const std::string& path) {
  if (val_.size == 0) return;
  NoGradGuard no_grad;
  predictor_->set_training(false);
  const Forward f = forward_val(0);
  const StreetSample& s = f.samples[0];
  const Tensor true_sky = s.sky_hdr.defined() ? to_ldr(f.items[0].frame.panorama(s.sky_hdr.contiguous()), s.exposure)
                                              : f.items[0].pano_ldr_dome;
  const Tensor comp = strip_composite(f);
  train::write_strip(path, {f.items[0].image, true_sky, ldr_from_hdr(select(f.pred.env, 0, 0)), comp});
  predictor_->set_training(true);
}

PanoramaSampleOptions real_sample_options(const nlohmann::json& config) {
  const auto& d = config.at("data");
  PanoramaSampleOptions o;
  const LightingPredictorOptions po = predictor_options(config);
  const auto fov = d.at("real_fov_deg").get<std::vector<double>>();
  o.crop.fov_min_deg = fov.at(0);
  o.crop.fov_max_deg = fov.at(1);
  o.crop.pitch_range_deg = d.at("real_pitch_deg").get<double>();
  o.crop.width = static_cast<int>(po.image_width);
  o.crop.height = static_cast<int>(po.image_height);
  o.white_balance_stops = d.at("real_white_balance_stops").get<double>();
  o.exposure_stops = d.at("real_exposure_stops").get<double>();
  o.low_label_weight = d.value("ldr_low_label_weight", 1.0);
  o.tone_stops = d.value("real_tone_stops", 0.0);
  o.crop.sun_aim_share = d.value("sun_aim_share", 0.0);
  return o;
}

std::unique_ptr<Stage> make_lighting_stage(const nlohmann::json& config) {
  const auto& d = config.at("data");
  const std::string dir = d.at("dataset").get<std::string>();
  const uint64_t seed = config.at("seed").get<uint64_t>();
  const auto cache_bytes = static_cast<size_t>(d.at("cache_mb").get<int64_t>()) << 20;  // checked in train_config
  SampleSource train = dataset_source(dir, d.at("train_split").get<std::string>(), 0, cache_bytes);
  SampleSource val = dataset_source(dir, d.at("val_split").get<std::string>(),
                                    static_cast<size_t>(d.at("val_size").get<int64_t>()));
  // Mixing (configs/README.md): of a shuffled epoch, a share data.real_fraction is crops of the
  // real HDR panoramas, data.ldr_fraction crops of the real LDR panoramas, the rest generated
  // streets. The HDR share is taken first, relative to what the LDR share leaves.
  const double real = d.value("real_fraction", 0.0), ldr = d.value("ldr_fraction", 0.0);
  const PanoramaSampleOptions ro = real_sample_options(config);
  if (real > 0) {
    const auto paths = configured_hdri_paths(config, "hdri_train_split");
    SL_CHECK(!paths.empty(), "data.real_fraction > 0 but no real panoramas were found (data.hdri_dir, data.hdri_split)");
    train = mixed_source(std::move(train), panorama_source(paths, ro, seed, paths.size(), true), real / (1.0 - ldr));
  }
  if (ldr > 0) {
    const auto paths = configured_ldr_paths(config, "hdri_train_split");
    SL_CHECK(!paths.empty(), "data.ldr_fraction > 0 but no LDR panoramas were found (data.ldr_dir, data.ldr_split)");
    train = mixed_source(std::move(train),
                         ldr_panorama_source(paths, configured_ldr_labels(config), ro, seed, paths.size(), true,
                                             static_cast<int>(d.value("ldr_working_width", int64_t{1024})),
                                             configured_ldr_place_balance(config, paths)),
                         ldr);
  }
  // Validation: real crops of the validation panoramas whenever a split names them (also in a
  // stage that trains on streets alone, so stages 2 and 3 are selected on the same samples).
  PanoramaSampleOptions vo = ro;
  vo.flip = false;
  vo.white_balance_stops = 0.0;
  vo.exposure_stops = 0.0;
  vo.tone_stops = 0.0;
  vo.crop.sun_aim_share = 0.0;  // validation crops are the benchmark's
  vo.low_label_weight = 1.0;
  const auto hdr_crops = static_cast<size_t>(d.at("real_val_crops").get<int64_t>());
  if (hdr_crops > 0 && (real > 0 || !d.at("hdri_split").get<std::string>().empty())) {
    const auto val_paths = configured_hdri_paths(config, "hdri_val_split");
    if (!val_paths.empty())
      val = concat_sources(std::move(val), panorama_source(val_paths, vo, seed ^ kValSeed, val_paths.size() * hdr_crops, false));
  }
  const auto ldr_crops = static_cast<size_t>(d.at("ldr_val_crops").get<int64_t>());
  if (ldr_crops > 0 && !d.at("ldr_split").get<std::string>().empty()) {
    const auto val_paths = configured_ldr_paths(config, "hdri_val_split");
    if (!val_paths.empty())
      val = concat_sources(std::move(val), ldr_panorama_source(val_paths, configured_ldr_labels(config), vo,
                                                               seed ^ kValSeed, val_paths.size() * ldr_crops, false));
  }
  // The panoramas were decoded beside what is kept of them: give the freed pages back (the release
  // recipe's LDR and HDR panoramas: 6.9 GB resident before, 4.7 GB after).
  release_free_heap();
  if (config.at("stage").get<std::string>() == kStageAdversarial)
    return std::make_unique<AdversarialStage>(config, std::move(train), std::move(val));
  return std::make_unique<LightingStage>(config, std::move(train), std::move(val));
}

}  // namespace sl::train
