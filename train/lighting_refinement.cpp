// Discriminator test-time optimisation (Fig. 7). See lighting_refinement.h.
#include "train/lighting_refinement.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include <nlohmann/json.hpp>

#include "autodiff/ops.h"
#include "autodiff/tape.h"
#include "nn/optim.h"
#include "nn/safetensors.h"
#include "render/vsg_volume.h"
#include "train/losses.h"
#include "train/train_config.h"
#include "util/random.h"

using sl::render::InsertionInputs;
using sl::render::insert_objects;
using sl::render::InsertionOptions;
using sl::render::VsgGrid;

namespace sl::train {

namespace {

// [out, in] box-filter weights: output i covers input [i·s, (i + 1)·s), s = in/out, each input
// pixel weighted by its overlap, normalised to sum 1.
Tensor area_weights(int64_t out, int64_t in, DType dtype) {
  std::vector<double> w(static_cast<size_t>(out * in), 0.0);
  const double s = double(in) / double(out);
  for (int64_t i = 0; i < out; ++i) {
    const double a = i * s, b = (i + 1) * s;
    for (int64_t j = static_cast<int64_t>(std::floor(a)); j < std::min<int64_t>(in, static_cast<int64_t>(std::ceil(b))); ++j)
      w[size_t(i * in + j)] = (std::min(b, double(j + 1)) - std::max(a, double(j))) / s;
  }
  return Tensor::from_vector(w, {out, in}, DType::F64).to(dtype);
}

bool all_finite(const Tensor& t) {
  const Tensor c = t.detach().to(DType::F64).contiguous();
  const double* p = c.data<double>();
  return std::all_of(p, p + c.numel(), [](double v) { return std::isfinite(v); });
}

double inverse_softplus(double y) {
  y = std::max(y, 1e-6);
  return y > 20.0 ? y : y + std::log(-std::expm1(-y));  // log(e^y − 1), stable for small and large y
}

// vsg_activate's inverse (render/vsg_volume.h), values clamped into its open range first.
Tensor vsg_raw_from_activated(const Tensor& vsg) {
  const Tensor c = vsg.detach().to(DType::F64).contiguous();
  const int64_t n = c.numel() / 8;
  std::vector<double> raw(c.data<double>(), c.data<double>() + c.numel());
  for (int64_t i = 0; i < n; ++i) {
    for (int ch = 0; ch < 3; ++ch) raw[size_t(ch * n + i)] = inverse_softplus(raw[size_t(ch * n + i)]);
    raw[size_t(6 * n + i)] = inverse_softplus(raw[size_t(6 * n + i)] - VsgGrid::kMinSharpness);
    const double a = std::clamp(raw[size_t(7 * n + i)], 1e-6, 1.0 - 1e-6);
    raw[size_t(7 * n + i)] = std::log(a / (1.0 - a));
  }
  return Tensor::from_vector(raw, vsg.shape(), DType::F64).to(vsg.dtype());
}

// D frozen and in eval mode for a scope; restored after.
class FrozenForScope {
 public:
  explicit FrozenForScope(nn::Module& m) : m_(m), frozen_(m.is_frozen()), training_(m.is_training()) {
    m_.freeze(true);
    m_.eval();
  }
  ~FrozenForScope() {
    m_.freeze(frozen_);
    m_.train(training_);
  }
  FrozenForScope(const FrozenForScope&) = delete;
  FrozenForScope& operator=(const FrozenForScope&) = delete;

 private:
  nn::Module& m_;
  bool frozen_, training_;
};

// −mean D(I_edit) (train/losses.h) of the composite of `scene` under env/vsg.
Tensor adversarial_loss(nn::PatchDiscriminator& d, InsertionInputs scene, const Tensor& env, const Tensor& vsg,
                        const InsertionOptions& io, const RefinementOptions& r) {
  scene.env = env;
  scene.vsg = vsg;
  const Tensor composite = insert_objects(scene, io).composite;
  return generator_adversarial(d.forward(discriminator_input(composite, r.discriminator_height, r.discriminator_width)));
}

glm::dvec3 row3(const Tensor& t) {
  const Tensor c = t.detach().to(DType::F64).contiguous();
  return {c.data<double>()[0], c.data<double>()[1], c.data<double>()[2]};
}

}  // namespace

std::shared_ptr<nn::PatchDiscriminator> load_discriminator(const std::string& path) {
  const nn::SafetensorsFile file = nn::read_safetensors(path);
  nn::StateDict state;
  const std::string prefix = "discriminator.";
  for (const auto& [name, t] : file.tensors)
    if (name.rfind(prefix, 0) == 0) state.emplace(name.substr(prefix.size()), t);
  if (state.empty()) return nullptr;
  nlohmann::json opt = default_train_config().at("model").at("discriminator");
  const auto it = file.metadata.find("config");
  if (it != file.metadata.end()) {
    nlohmann::json config;
    try {
      config = nlohmann::json::parse(it->second);
    } catch (const std::exception& e) {
      SL_CHECK(false, "discriminator file '", path, "': its config metadata is not JSON (", e.what(), ")");
    }
    if (config.contains("model") && config["model"].contains("discriminator"))
      for (const auto& [k, v] : config["model"]["discriminator"].items()) opt[k] = v;
  }
  std::shared_ptr<nn::PatchDiscriminator> d;
  try {
    d = std::make_shared<nn::PatchDiscriminator>(nn::PatchDiscriminatorOptions{
        .base_channels = opt.at("base_channels").get<int64_t>(),
        .layers = opt.at("layers").get<int>(),
        .norm = opt.at("norm").get<std::string>()});
    d->load_state_dict(state);
  } catch (const Error& e) {
    SL_CHECK(false, "discriminator in '", path, "' does not match its config (model.discriminator ", opt.dump(),
             "): ", e.what());
  } catch (const nlohmann::json::exception& e) {
    SL_CHECK(false, "discriminator file '", path, "': bad model.discriminator ", opt.dump(), " (", e.what(), ")");
  }
  d->eval();
  return d;
}

Tensor area_resize(const Tensor& image, int64_t height, int64_t width) {
  SL_CHECK(image.dim() == 3 && height > 0 && width > 0, "area_resize: expected [C, H, W] and a positive size, got ",
           image.describe(), " to ", height, "x", width);
  const int64_t C = image.size(0), H = image.size(1), W = image.size(2);
  if (H == height && W == width) return image;
  const Tensor ry = area_weights(height, H, image.dtype()), rx_t = transpose(area_weights(width, W, image.dtype()), 0, 1);
  // Rows: [h, H] · [H, C·W]; then columns: [h·C, W] · [W, w].
  const Tensor rows = matmul(ry, reshape(permute(image, {1, 0, 2}), {H, C * W}));
  const Tensor both = matmul(reshape(rows, {height * C, W}), rx_t);
  return permute(reshape(both, {height, C, width}), {1, 0, 2});
}

Tensor discriminator_input(const Tensor& composite_linear, int64_t height, int64_t width) {
  SL_CHECK(composite_linear.dim() == 3 && composite_linear.size(0) == 3,
           "discriminator_input: expected a composite [3, H, W], got ", composite_linear.describe());
  SL_CHECK(height >= 0 && width >= 0 && (height == 0) == (width == 0), "discriminator_input: size ", height, "x",
           width, " must be both positive or both 0");
  const Tensor sized = height > 0 ? area_resize(composite_linear, height, width) : composite_linear;
  return unsqueeze(ldr_from_hdr(sized), 0);
}

RefinementResult refine_lighting(const EstimatedLighting& start, SkyDecoder& decoder, nn::PatchDiscriminator& d,
                                 const InsertionInputs& scene, const PhotoInsertionOptions& insertion,
                                 const RefinementOptions& r) {
  SL_CHECK(r.steps >= 0, "lighting refinement: steps ", r.steps, " must be >= 0");
  SL_CHECK(std::isfinite(r.lr) && r.lr > 0, "lighting refinement: lr ", r.lr, " must be positive");
  SL_CHECK(start.has_sky_code && start.sky_code.dir.defined(),
           "lighting refinement needs the sky vector of the 'sky_decoder' sky branch; this lighting has none");
  SL_CHECK(!r.volume || start.vsg.defined(), "lighting refinement: the volume was asked for, but the lighting has none");
  SL_CHECK(r.intensity || r.direction || r.latent || r.volume,
           "lighting refinement: no parameter chosen (intensity, direction, latent, volume)");
  const auto t0 = std::chrono::steady_clock::now();
  FrozenForScope frozen(d);
  InsertionOptions io = insertion_options(insertion);
  io.radiance_cache = false;  // gradients into env/vsg need exact volume queries (render/object_insertion.h)
  RefinementResult out;
  out.lighting = start;
  {
    NoGradGuard no_grad;
    out.loss_before = adversarial_loss(d, scene, start.env, start.vsg, io, r).item();
  }
  if (r.steps == 0) {
    out.loss_after = out.loss_before;
    out.time_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    return out;
  }
  // Leaves: log f_int, v (f_dir = v/|v|), f_latent, the volume's raw values.
  Tensor log_int = start.sky_code.log_intensity.detach().clone().set_requires_grad(r.intensity);
  Tensor dir_v = start.sky_code.dir.detach().clone().set_requires_grad(r.direction);
  Tensor latent = start.sky_code.latent.detach().clone().set_requires_grad(r.latent);
  Tensor vsg_raw = r.volume ? vsg_raw_from_activated(start.vsg).set_requires_grad(true) : Tensor();
  nn::NamedTensors params;
  if (r.intensity) params.emplace_back("log_intensity", log_int);
  if (r.direction) params.emplace_back("direction", dir_v);
  if (r.latent) params.emplace_back("latent", latent);
  if (r.volume) params.emplace_back("vsg_raw", vsg_raw);
  nn::Adam adam(params, nn::AdamOptions{.lr = r.lr});
  auto code_on_tape = [&] {
    SkyCode c;
    c.log_intensity = log_int;
    c.dir = normalize(dir_v, 1, 1e-8);
    c.latent = latent;
    return c;
  };
  for (int step = 0; step < r.steps; ++step) {
    adam.zero_grad();
    InsertionOptions step_io = io;
    step_io.seed = hash_counter(insertion.seed, kRefineStream, static_cast<uint64_t>(step));
    const Tensor env = select(decoder.decode(code_on_tape()).hdr, 0, 0);
    const Tensor vsg = r.volume ? render::vsg_activate(vsg_raw) : start.vsg;
    const Tensor loss = adversarial_loss(d, scene, env, vsg, step_io, r);
    const double value = loss.item();
    out.loss_per_step.push_back(value);
    if (std::isfinite(value)) backward(loss);
    bool finite = std::isfinite(value);
    for (const auto& [name, p] : params) finite = finite && (!p.grad().defined() || all_finite(p.grad()));
    if (finite) {
      adam.step();
      NoGradGuard no_grad;
      const double len = glm::length(row3(dir_v));
      if (std::isfinite(len) && len > 1e-12) dir_v.copy_(mul_scalar(dir_v.detach(), 1.0 / len));
    } else {
      ++out.skipped_steps;
    }
    if (r.on_step) r.on_step(step, value);
  }
  adam.zero_grad();
  NoGradGuard no_grad;
  SkyCode code;
  code.log_intensity = log_int.detach().clone();
  code.dir = normalize(dir_v.detach(), 1, 1e-8).contiguous();
  code.latent = latent.detach().clone();
  out.lighting.env = select(decoder.decode(code).hdr, 0, 0).contiguous();
  if (r.volume) out.lighting.vsg = render::vsg_activate(vsg_raw.detach()).contiguous();
  out.lighting.sky_code = code;
  out.lighting.sun_direction_canonical = row3(code.dir);
  if (r.intensity) {
    const glm::dvec3 li = row3(code.log_intensity);
    out.lighting.sun_intensity_rgb = {std::exp(li.x), std::exp(li.y), std::exp(li.z)};
  }
  out.loss_after = adversarial_loss(d, scene, out.lighting.env, out.lighting.vsg, io, r).item();
  out.time_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace sl::train
