// Sky modelling network (Sec 3.2, Fig. 3). See sky_autoencoder.h for the contract.
#include "train/sky_autoencoder.h"

#include <cmath>

#include "autodiff/ops.h"
#include "nn/functional/upsample.h"
#include "nn/layers.h"
#include "nn/modules/mlp.h"
#include "render/equirect.h"
#include "util/math.h"

namespace sl::train {

namespace {

// A log-intensity prior: the exposure-normalised sun texel of a 32×128 dome is ~e^5..e^9, so
// starting the raw output near 0 means starting near the data rather than at intensity 1.
constexpr double kLogIntensityPrior = 5.0;
// Sharpnesses of the SG conditioning maps fed to the decoder (broad to narrow).
constexpr double kConditioningSharpness[3] = {2.0, 16.0, 128.0};
constexpr int64_t kConditioningChannels = 9;  // 3 direction + 3 SG + 3 log intensity

int64_t level_channels(int64_t base, int level) { return base * (int64_t{1} << std::min(level, 3)); }

std::shared_ptr<nn::Module> conv_gn_act(int64_t in, int64_t out, int64_t stride) {
  auto seq = std::make_shared<nn::Sequential>();
  seq->push_back(std::make_shared<nn::Conv2d>(in, out, 3, nn::ConvOptions{.stride = stride, .padding = 1, .bias = false}));
  seq->push_back(nn::make_norm("group", out, 2, 8));
  seq->push_back(std::make_shared<nn::LeakyReLU>(0.2));
  return seq;
}

void check_sky_options(const SkyAutoencoderOptions& o) {
  SL_CHECK(o.code_dim > 6, "sky autoencoder: code_dim must exceed 6 (intensity 3 + direction 3), got ", o.code_dim);
  SL_CHECK(o.height >= 4 && o.width >= 8, "sky autoencoder: dome must be at least 4×8, got ", o.height, "×", o.width);
  const int levels = sky_levels(o.height);
  const int64_t f = int64_t{1} << levels;
  SL_CHECK(o.height % f == 0 && o.width % f == 0, "sky autoencoder: dome ", o.height, "×", o.width,
           " must be divisible by ", f, " (", levels, " downsamplings)");
  SL_CHECK(o.base_channels >= 1 && o.hidden >= 1, "sky autoencoder: base_channels and hidden must be positive");
  SL_CHECK(o.sun_lobe_texels > 0, "sky autoencoder: sun_lobe_texels must be positive, got ", o.sun_lobe_texels);
}

}  // namespace

int sky_levels(int64_t height) {
  int levels = 0;
  while ((height >> levels) > 4) ++levels;
  return std::max(levels, 1);
}

Tensor SkyCode::intensity() const { return exp(clamp(log_intensity, -30.0, 30.0)); }

SkyCode sky_code_from_raw(const Tensor& raw) {
  SL_CHECK(raw.dim() == 2 && raw.size(1) > 6, "sky_code_from_raw: expected raw [N, d > 6], got ", raw.describe());
  SkyCode c;
  c.log_intensity = add_scalar(slice(raw, 1, 0, 3), kLogIntensityPrior);
  c.dir = normalize(slice(raw, 1, 3, 6), 1, 1e-8);
  c.latent = slice(raw, 1, 6, raw.size(1));
  return c;
}

Tensor panorama_directions(int64_t height, int64_t width, DType dtype) {
  std::vector<double> v(static_cast<size_t>(3 * height * width));
  const int64_t plane = height * width;
  for (int64_t i = 0; i < height; ++i)
    for (int64_t j = 0; j < width; ++j) {
      const auto d =
          render::equirect::uv_to_direction(j + 0.5, i + 0.5, static_cast<int>(width), static_cast<int>(height));
      v[static_cast<size_t>(i * width + j)] = d.x;
      v[static_cast<size_t>(plane + i * width + j)] = d.y;
      v[static_cast<size_t>(2 * plane + i * width + j)] = d.z;
    }
  return Tensor::from_vector(v, {3, height, width}, dtype);
}

double sun_lobe_sharpness(int64_t height, double texels) {
  // exp(λ(cos θ − 1)) ≈ exp(−λθ²/2) is ½ at θ = fwhm/2  ⇒  λ = 8 ln 2 / fwhm².
  const double fwhm = texels * kPi / static_cast<double>(height);
  return 8.0 * std::log(2.0) / (fwhm * fwhm);
}

// ---------------------------------------------------------------- encoder

SkyEncoder::SkyEncoder(const SkyAutoencoderOptions& options) : nn::Module("SkyEncoder"), opt_(options) {
  check_sky_options(opt_);
  const int levels = sky_levels(opt_.height);
  trunk_.push_back(register_module("stem", conv_gn_act(6, opt_.base_channels, 1)));
  for (int l = 0; l < levels; ++l)
    trunk_.push_back(register_module("down" + std::to_string(l),
                                     conv_gn_act(level_channels(opt_.base_channels, l),
                                                 level_channels(opt_.base_channels, l + 1), 2)));
  const int64_t flat = level_channels(opt_.base_channels, levels) * (opt_.height >> levels) * (opt_.width >> levels);
  head_ = register_module("head", std::make_shared<nn::MLP>(nn::MlpOptions{
                                      .widths = {flat, opt_.hidden, opt_.code_dim}, .activation = "leaky_relu:0.2"}));
  dirs_ = unsqueeze(panorama_directions(opt_.height, opt_.width), 0);
}

Tensor SkyEncoder::forward(const Tensor& ldr) {
  SL_CHECK(ldr.dim() == 4 && ldr.size(1) == 3 && ldr.size(2) == opt_.height && ldr.size(3) == opt_.width,
           "SkyEncoder: expected an LDR panorama [N, 3, ", opt_.height, ", ", opt_.width, "], got ", ldr.describe());
  Tensor dirs = dirs_.dtype() == ldr.dtype() ? dirs_ : dirs_.to(ldr.dtype());
  Tensor x = concat({ldr, expand(dirs, {ldr.size(0), 3, opt_.height, opt_.width})}, 1);
  for (auto& m : trunk_) x = m->forward(x);
  return head_->forward(flatten(x, 1));
}

// ---------------------------------------------------------------- decoder

SkyDecoder::SkyDecoder(const SkyAutoencoderOptions& options) : nn::Module("SkyDecoder"), opt_(options) {
  check_sky_options(opt_);
  levels_ = sky_levels(opt_.height);
  h0_ = opt_.height >> levels_;
  w0_ = opt_.width >> levels_;
  c0_ = level_channels(opt_.base_channels, levels_);
  fc_ = register_module("fc", std::make_shared<nn::MLP>(nn::MlpOptions{
                                  .widths = {opt_.code_dim, opt_.hidden, c0_ * h0_ * w0_},
                                  .activation = "leaky_relu:0.2", .output_activation = "leaky_relu:0.2"}));
  // blocks_[k] runs at level levels_ − 1 − k (after the k-th 2× upsampling).
  for (int k = 0; k < levels_; ++k) {
    const int level = levels_ - 1 - k;
    auto block = std::make_shared<nn::Sequential>();
    block->push_back(conv_gn_act(level_channels(opt_.base_channels, level + 1) + kConditioningChannels,
                                 level_channels(opt_.base_channels, level), 1));
    block->push_back(conv_gn_act(level_channels(opt_.base_channels, level), level_channels(opt_.base_channels, level), 1));
    blocks_.push_back(register_module("up" + std::to_string(k), block));
  }
  head_ = register_module("head", std::make_shared<nn::Conv2d>(opt_.base_channels + kConditioningChannels, 3, 3,
                                                               nn::ConvOptions{.padding = 1}));
  for (int level = 0; level <= levels_; ++level)
    dirs_.push_back(unsqueeze(panorama_directions(opt_.height >> level, opt_.width >> level), 0));
  sun_sharpness_ = sun_lobe_sharpness(opt_.height, opt_.sun_lobe_texels);
}

Tensor SkyDecoder::conditioning(const SkyCode& code, int64_t level) const {
  const Tensor& d0 = dirs_[static_cast<size_t>(level)];
  const Tensor dirs = d0.dtype() == code.dir.dtype() ? d0 : d0.to(code.dir.dtype());
  const int64_t n = code.dir.size(0), h = dirs.size(2), w = dirs.size(3);
  const Tensor cos_to_sun = sum(mul(dirs, reshape(code.dir, {n, 3, 1, 1})), {1}, true);  // [N, 1, h, w]
  TensorList maps{expand(dirs, {n, 3, h, w})};
  for (double lambda : kConditioningSharpness) maps.push_back(exp(mul_scalar(add_scalar(cos_to_sun, -1.0), lambda)));
  maps.push_back(expand(reshape(mul_scalar(code.log_intensity, 1.0 / 8.0), {n, 3, 1, 1}), {n, 3, h, w}));
  return concat(maps, 1);
}

SkyDecoding SkyDecoder::decode(const SkyCode& code) {
  const Tensor f = concat({code.log_intensity, code.dir, code.latent}, 1);
  SL_CHECK(f.size(1) == opt_.code_dim, "SkyDecoder: code has ", f.size(1), " entries, expected ", opt_.code_dim);
  const int64_t n = f.size(0);
  Tensor x = reshape(fc_->forward(f), {n, c0_, h0_, w0_});
  for (int k = 0; k < levels_; ++k) {
    x = nn::upsample_bilinear2d(x, 2);
    x = blocks_[static_cast<size_t>(k)]->forward(concat({x, conditioning(code, levels_ - 1 - k)}, 1));
  }
  const Tensor log_net = head_->forward(concat({x, conditioning(code, 0)}, 1));  // [N, 3, H, W]
  // The analytic sun lobe of the code, in log space: log f_intensity + λ_sun (d·f_dir − 1).
  const Tensor& d0 = dirs_[0];
  const Tensor dirs = d0.dtype() == f.dtype() ? d0 : d0.to(f.dtype());
  const Tensor cos_to_sun = sum(mul(dirs, reshape(code.dir, {n, 3, 1, 1})), {1}, true);
  const Tensor log_sun = add(reshape(code.log_intensity, {n, 3, 1, 1}),
                             mul_scalar(add_scalar(cos_to_sun, -1.0), sun_sharpness_));
  SkyDecoding out;
  out.log_hdr = logsumexp(stack({log_net, log_sun}, 0), 0);
  out.hdr = exp(clamp(out.log_hdr, -16.0, 16.0));
  return out;
}

// ---------------------------------------------------------------- autoencoder

SkyAutoencoder::SkyAutoencoder(const SkyAutoencoderOptions& options) : nn::Module("SkyAutoencoder"), opt_(options) {
  encoder_ = register_module("encoder", std::make_shared<SkyEncoder>(opt_));
  decoder_ = register_module("decoder", std::make_shared<SkyDecoder>(opt_));
  init_parameters(opt_.seed);
}

SkyAutoencoder::Output SkyAutoencoder::run(const Tensor& ldr) {
  Output out;
  out.code = encoder_->encode(ldr);
  out.sky = decoder_->decode(out.code);
  return out;
}

}  // namespace sl::train
