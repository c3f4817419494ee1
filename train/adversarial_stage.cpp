// Stage 3 (Sec 3.4): see adversarial_stage.h. D and the predictor share one AdamW; a step only
// touches parameters with gradients.
// Data parallel (distributed.h): both updates average their gradients over ranks; the
// adversarial and hinge losses are means over the GLOBAL batch's insertable samples (each rank
// scales its shard's mean by global_share), and whether the discriminator steps at all is decided
// by the global count, so every rank runs the same collectives.
#include <cmath>

#include "autodiff/ops.h"
#include "data/panorama.h"
#include "render/gltf_loader.h"
#include "render/object_insertion.h"
#include "train/adversarial_stage.h"
#include "train/distributed.h"
#include "train/gradient_allreduce.h"
#include "train/losses.h"
#include "train/phase_clock.h"
#include "train/train_config.h"
#include "util/math.h"
#include "util/random.h"

using sl::data::resize_area;
using sl::data::StreetSample;
using sl::data::StreetView;
using sl::data::to_ldr;
using sl::render::insert_objects;
using sl::render::InsertionInputs;
using sl::render::load_gltf;
using sl::render::Mesh;
using sl::render::place_object;
using sl::render::Placement;

namespace sl::train {

namespace {
constexpr uint64_t kRealSeed = 0x7265616C5F696D67ULL;  // the real composites' own samples
}  // namespace

const Mesh& AdversarialStage::object_mesh(const std::string& path) {
  auto it = meshes_.find(path);
  if (it == meshes_.end()) it = meshes_.emplace(path, load_gltf(path)).first;
  return it->second;
}

Tensor AdversarialStage::composite(const Forward& f, size_t i, uint64_t seed) {
  const Tensor vsg = f.pred.vsg.defined() ? select(f.pred.vsg, 0, static_cast<int64_t>(i)) : Tensor();
  return composite_under(f, i, select(f.pred.env, 0, static_cast<int64_t>(i)), vsg, seed);
}

Tensor AdversarialStage::composite_under(const Forward& f, size_t i, const Tensor& env, const Tensor& vsg,
                                         uint64_t seed) {
  const StreetSample& s = f.samples[i];
  const StreetItem& it = f.items[i];
  const StreetView& view = s.views[0];
  SL_CHECK(s.has_insertion && !s.object_glb.empty(), "stage adversarial: sample '", s.id,
           "' has no insertion ground truth (object_glb)");
  InsertionInputs in;
  in.background = pow_scalar(view.ldr.contiguous(), kLdrGamma);  // linearised LDR: exposure-normalised radiance
  in.depth = view.depth;
  in.camera = it.camera;
  in.env = env;
  in.vsg = vsg;
  in.grid = it.grid;
  const glm::dvec3 pos = it.frame.point({s.object_x, 0.0, s.object_z});
  Placement p;
  p.x_m = pos.x;
  p.z_m = pos.z;
  p.yaw_deg = it.frame.object_yaw_deg(s.object_yaw_deg);
  p.scale = s.object_scale;
  in.objects.push_back(place_object(object_mesh(s.object_glb), p, it.camera, view.depth));
  return insert_objects(in, training_insertion_options(config_, seed)).composite;
}

Tensor AdversarialStage::ground_truth_env(const Forward& f, size_t i) const {
  const StreetSample& s = f.samples[i];
  SL_CHECK(s.pano_hdr.defined(), "stage adversarial: sample '", s.id, "' has no HDR panorama (pano_hdr)");
  const Tensor pano = f.items[i].frame.panorama(mul_scalar(s.pano_hdr.contiguous(), s.exposure).contiguous());
  return resize_area(pano.contiguous(), static_cast<int>(batch_opt_.dome_height), static_cast<int>(batch_opt_.dome_width))
      .to(f.pred.env.dtype());
}

Tensor AdversarialStage::real_composite_ldr(const Forward& f, size_t i, uint64_t seed) {
  const StreetSample& s = f.samples[i];
  const std::string kind = config_.at("insertion").value("real", std::string("renderer"));
  if (kind == "path_traced") {
    SL_CHECK(s.insert_with_object_hdr.defined(), "stage adversarial: sample '", s.id, "' has no insert_with_object_hdr");
    return to_ldr(s.insert_with_object_hdr.contiguous(), s.exposure);
  }
  NoGradGuard no_grad;
  return ldr_from_hdr(composite_under(f, i, ground_truth_env(f, i), Tensor(), seed)).contiguous();
}

AdversarialStage::AdversarialStage(const nlohmann::json& config, SampleSource train, SampleSource val)
    : LightingStage(config, std::move(train), std::move(val)) {
  SL_CHECK(config.at("stage").get<std::string>() == kStageAdversarial, "AdversarialStage: the config's stage is '",
           config.at("stage").get<std::string>(), "', expected '", kStageAdversarial, "'");
}

Tensor AdversarialStage::strip_composite(const Forward& f) {
  const StreetSample& s = f.samples[0];
  const bool centre_in_view =
      f.items[0].camera.project(f.items[0].frame.point({s.object_x, 0.0, s.object_z})).in_image;
  return s.has_insertion && centre_in_view ? ldr_from_hdr(composite(f, 0, seed_)).detach() : Tensor();
}

Metrics AdversarialStage::step(int64_t step) {
  predictor_->set_training(true);
  optim_->zero_grad();
  PhaseClock clock;
  const Forward f = forward_train(step);
  Metrics m;
  Tensor total = supervised_loss(f, m);
  const double forward_ms = clock.lap() - last_data_ms_;
  auto record_times = [&](double render_ms, double backward_ms) {
    m["time_data_ms"] = last_data_ms_;
    m["time_forward_ms"] = forward_ms;
    m["time_render_ms"] = render_ms;
    m["time_backward_ms"] = backward_ms;
  };
  // place_object() needs the footprint centre inside view 0; the generator only guarantees
  // that some of the object is visible, so samples whose centre falls outside get no composite.
  std::vector<size_t> insertable;
  for (size_t i = 0; i < f.items.size(); ++i) {
    const StreetSample& s = f.samples[i];
    if (s.has_insertion && f.items[i].camera.project(f.items[i].frame.point({s.object_x, 0.0, s.object_z})).in_image)
      insertable.push_back(i);
  }
  const double global_insertable = sum_over_ranks(static_cast<double>(insertable.size()));
  if (!discriminator_ || global_insertable == 0) {  // the no-adversarial ablation: the same steps without D
    for (const auto& [k, v] : m) check_finite_loss(k, v, step);
    backward(total);
    record_times(0.0, clock.lap());
    if (is_distributed()) {
      m["time_allreduce_ms"] = allreduce_gradients(optim_->params());
      clock.lap();
    }
    m["grad_norm"] = clip_finite_gradients(optim_->params(), clip_, step);
    optim_->step();
    m["time_optimizer_ms"] = clock.lap();
    return m;
  }
  const double share = global_share(static_cast<double>(insertable.size()));  // collective: before branching
  if (insertable.empty()) return step_without_samples(step, total, m, forward_ms);
  TensorList fakes, reals;
  for (size_t i : insertable) {
    fakes.push_back(ldr_from_hdr(composite(f, i, hash_counter(seed_, static_cast<uint64_t>(step), i))));
    reals.push_back(real_composite_ldr(f, i, hash_counter(seed_ ^ kRealSeed, static_cast<uint64_t>(step), i)));
  }
  const Tensor fake = stack(fakes, 0), real = stack(reals, 0);
  const double render_ms = clock.lap();
  // (1) Predictor: supervised + w_adv · (−D(fake)), D frozen so only the predictor gets gradients.
  discriminator_->freeze(true);
  Tensor adv = generator_adversarial(discriminator_->forward(fake));
  if (share != 1.0) adv = mul_scalar(adv, share);
  m["adversarial"] = adv.item();
  total = add(total, mul_scalar(adv, config_.at("loss").at("adversarial").get<double>()));
  m["loss"] = total.item();
  for (const auto& [k, v] : m) check_finite_loss(k, v, step);
  backward(total);
  record_times(render_ms, clock.lap());
  discriminator_->freeze(false);
  if (is_distributed()) {
    m["time_allreduce_ms"] = allreduce_gradients(optim_->params());
    clock.lap();
  }
  m["grad_norm"] = clip_finite_gradients(optim_->params(), clip_, step);
  optim_->set_lr(lr_);
  optim_->step();
  // (2) Discriminator: hinge on real vs the detached composite.
  optim_->zero_grad();
  Tensor d_loss = discriminator_hinge(discriminator_->forward(real), discriminator_->forward(fake.detach()));
  if (share != 1.0) d_loss = mul_scalar(d_loss, share);
  m["d_loss"] = d_loss.item();
  check_finite_loss("d_loss", m["d_loss"], step);
  backward(d_loss);
  double optimizer_ms = 0.0;
  if (is_distributed()) {
    optimizer_ms = clock.lap();
    m["time_allreduce_ms"] += allreduce_gradients(optim_->params());
    clock.lap();
  }
  clip_finite_gradients(optim_->params(), clip_, step);
  const double base = config_.at("optim").at("lr").get<double>();
  optim_->set_lr(lr_ * config_.at("optim").at("discriminator_lr").get<double>() / base);
  optim_->step();
  optim_->set_lr(lr_);
  m["time_optimizer_ms"] = optimizer_ms + clock.lap();  // both optimiser steps and the discriminator's own pass
  return m;
}

// Data parallel, a rank whose shard has no insertable sample while others have: it takes part in
// both updates with its supervised gradients and no discriminator gradient (zeros in the mean).
Metrics AdversarialStage::step_without_samples(int64_t step, const Tensor& total, Metrics& m, double forward_ms) {
  m["adversarial"] = 0.0;
  m["d_loss"] = 0.0;
  for (const auto& [k, v] : m) check_finite_loss(k, v, step);
  PhaseClock clock;
  backward(total);
  m["time_data_ms"] = last_data_ms_;
  m["time_forward_ms"] = forward_ms;
  m["time_render_ms"] = 0.0;
  m["time_backward_ms"] = clock.lap();
  m["time_allreduce_ms"] = allreduce_gradients(optim_->params());
  clock.lap();
  m["grad_norm"] = clip_finite_gradients(optim_->params(), clip_, step);
  optim_->set_lr(lr_);
  optim_->step();
  optim_->zero_grad();
  const double optimizer_ms = clock.lap();
  m["time_allreduce_ms"] += allreduce_gradients(optim_->params());
  clock.lap();
  clip_finite_gradients(optim_->params(), clip_, step);
  const double base = config_.at("optim").at("lr").get<double>();
  optim_->set_lr(lr_ * config_.at("optim").at("discriminator_lr").get<double>() / base);
  optim_->step();
  optim_->set_lr(lr_);
  m["time_optimizer_ms"] = optimizer_ms + clock.lap();
  return m;
}

}  // namespace sl::train
