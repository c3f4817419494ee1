// Stage 1: sky autoencoder. See sky_stage.h.
#include "train/sky_stage.h"

#include "train/phase_clock.h"
#include "train/sample_source.h"

#include "autodiff/ops.h"
#include "data/panorama.h"
#include "train/image_strip.h"
#include "train/losses.h"
#include "train/metrics.h"
#include "train/train_config.h"
#include "train/distributed.h"
#include "train/gradient_allreduce.h"

using sl::data::to_ldr;

namespace sl::train {

namespace {

constexpr uint64_t kValStream = 0x76616c6964ULL;  // validation samples never collide with training

Tensor dvec_rows(const std::vector<glm::dvec3>& v) {
  std::vector<double> flat;
  for (const auto& d : v) flat.insert(flat.end(), {d.x, d.y, d.z});
  return Tensor::from_vector(flat, {static_cast<int64_t>(v.size()), 3});
}

nn::NamedTensors trainable(const nn::Module& m) {
  nn::NamedTensors out;
  for (auto& [n, p] : m.named_parameters())
    if (p.requires_grad()) out.emplace_back(n, p);
  return out;
}

}  // namespace

SkyStage::SkyStage(const nlohmann::json& config) : config_(config) {
  seed_ = config.at("seed").get<uint64_t>();
  batch_size_ = config.at("train").at("batch_size").get<int64_t>();
  clip_ = config.at("optim").at("clip_grad_norm").get<double>();
  const SkyAutoencoderOptions so = sky_options(config);
  const auto& d = config.at("data");
  data_ = std::make_unique<SkyDataSource>(SkyDataOptions{
      .height = so.height,
      .width = so.width,
      .hdri_dir = d.at("hdri_dir").get<std::string>(),
      .hdri_paths = configured_hdri_paths(config, "hdri_train_split"),
      .hdri_fraction = d.at("hdri_fraction").get<double>(),
      .ldr_key = d.at("ldr_key").get<double>(),
      .exposure_stops = d.at("exposure_stops").get<double>()});
  model_ = std::make_shared<SkyAutoencoder>(so);
  optim_ = std::make_unique<nn::AdamW>(trainable(*model_),
                                       nn::AdamOptions{.lr = config.at("optim").at("lr").get<double>(),
                                                       .weight_decay = config.at("optim").at("weight_decay").get<double>()});
}

SkyStage::Batch SkyStage::make_batch(uint64_t seed, uint64_t first_index, int64_t count) const {
  TensorList ldr, hdr;
  std::vector<glm::dvec3> dirs, ints;
  for (int64_t i = 0; i < count; ++i) {
    const SkySample s = data_->sample(seed, first_index + static_cast<uint64_t>(i));
    ldr.push_back(s.ldr);
    hdr.push_back(s.hdr);
    dirs.push_back(s.sun_direction);
    ints.push_back(s.sun_intensity);
  }
  return Batch{stack(ldr, 0), stack(hdr, 0), dvec_rows(dirs), dvec_rows(ints)};
}

Metrics SkyStage::losses(const Batch& b, const SkyAutoencoder::Output& out, Tensor* total) const {
  const auto& w = config_.at("loss");
  const Tensor l_dir = angular_l1(out.code.dir, b.sun_dir);
  const Tensor l_int = log_encoded_l2_from_log(out.code.log_intensity, b.sun_intensity);
  const Tensor l_hdr = log_encoded_l2_from_log(out.sky.log_hdr, b.hdr);
  const Tensor sum_ = add(add(mul_scalar(l_dir, w.at("ae_direction").get<double>()),
                              mul_scalar(l_int, w.at("ae_intensity").get<double>())),
                          mul_scalar(l_hdr, w.at("ae_hdr").get<double>()));
  if (total) *total = sum_;
  return {{"loss", sum_.item()}, {"direction", l_dir.item()}, {"intensity", l_int.item()}, {"hdr", l_hdr.item()}};
}

Metrics SkyStage::step(int64_t step) {
  model_->train();
  PhaseClock clock;
  const Batch b = make_batch(seed_, shard_first_index(step, batch_size_), batch_size_);
  const double data_ms = clock.lap();
  optim_->zero_grad();
  const SkyAutoencoder::Output out = model_->run(b.ldr);
  Tensor total;
  Metrics m = losses(b, out, &total);
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
  m["time_data_ms"] = data_ms;
  m["time_forward_ms"] = forward_ms;
  m["time_render_ms"] = 0.0;
  m["time_backward_ms"] = backward_ms;
  m["time_optimizer_ms"] = clock.lap();
  return m;
}

Metrics SkyStage::validate() {
  NoGradGuard no_grad;
  model_->eval();
  const int64_t n = config_.at("data").at("val_size").get<int64_t>();
  Metrics sum_m;
  std::vector<double> errs;
  for (int64_t i = 0; i < n; i += batch_size_) {
    const int64_t count = std::min(batch_size_, n - i);
    const Batch b = make_batch(seed_ ^ kValStream, static_cast<uint64_t>(i), count);
    const SkyAutoencoder::Output out = model_->run(b.ldr);
    for (const auto& [k, v] : losses(b, out, nullptr)) sum_m[k] += v * static_cast<double>(count);
    const auto pd = out.code.dir.to_vector(), td = b.sun_dir.to_vector();
    for (int64_t r = 0; r < count; ++r)
      errs.push_back(angular_error_deg({pd[3 * r], pd[3 * r + 1], pd[3 * r + 2]}, {td[3 * r], td[3 * r + 1], td[3 * r + 2]}));
  }
  Metrics m;
  for (const auto& [k, v] : sum_m) m["val_" + k] = v / static_cast<double>(std::max<int64_t>(n, 1));
  m["val_sun_error_median_deg"] = median(errs);
  m["val_sun_error_mean_deg"] = mean_of(errs);
  model_->train();
  return m;
}

void SkyStage::write_strip(const std::string& path) {
  NoGradGuard no_grad;
  model_->eval();
  const Batch b = make_batch(seed_ ^ kValStream, 0, 1);
  const SkyAutoencoder::Output out = model_->run(b.ldr);
  // Rows: input LDR; true and decoded HDR at exposure 1; the same at 1/256 to show the sun.
  const Tensor truth = select(b.hdr, 0, 0).contiguous(), pred = select(out.sky.hdr, 0, 0).contiguous();
  train::write_strip(path, {select(b.ldr, 0, 0), to_ldr(truth, 1.0), to_ldr(pred, 1.0), to_ldr(truth, 1.0 / 256),
                            to_ldr(pred, 1.0 / 256)});
  model_->train();
}

}  // namespace sl::train
