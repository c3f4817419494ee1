// Hybrid lighting predictor (Sec 3.2, Fig. 2a). See lighting_predictor.h.
#include "train/lighting_predictor.h"

#include "autodiff/ops.h"
#include "nn/functional/upsample.h"
#include "nn/layers.h"
#include "nn/modules/mlp.h"
#include "nn/modules/unet.h"
#include "render/vsg_volume.h"
#include "train/image_statistics.h"

using sl::render::vsg_activate;

namespace sl::train {

namespace {

// The "direct" env decoder starts from a 4×16 map (or smaller for tiny domes) and doubles.
int direct_levels(int64_t height) { return sky_levels(height); }

}  // namespace

std::array<int64_t, 2> backbone_grid_size(int64_t image_height, int64_t image_width) {
  std::array<int64_t, 2> hw{image_height, image_width};
  for (int64_t& v : hw)
    for (int i = 0; i < 5; ++i) v = (v + 1) / 2;
  return hw;
}

void validate(const LightingPredictorOptions& o) {
  SL_CHECK(o.sky_branch == "sky_decoder" || o.sky_branch == "direct" || o.sky_branch == "constant",
           "model.sky_branch must be \"sky_decoder\", \"direct\" or \"constant\", got \"", o.sky_branch, "\"");
  SL_CHECK(o.image_height >= 32 && o.image_width >= 32, "model.image: at least 32×32, got ", o.image_height, "×",
           o.image_width);
  SL_CHECK(o.head_hidden >= 1, "model.head_hidden must be positive, got ", o.head_hidden);
  validate(o.sun_grid);
  SL_CHECK(!o.sun_grid.enabled() || o.sky_branch == "sky_decoder", "model.sun_grid needs the \"sky_decoder\" sky branch, got \"",
           o.sky_branch, "\"");
  SL_CHECK(!o.sun_image_statistics || o.sun_grid.enabled(), "model.sun_image_statistics needs model.sun_grid (the sun head)");
  SL_CHECK(o.sun_backbone.empty() || o.sun_backbone == "mobilenet_v2",
           "model.sun_backbone must be \"\" or \"mobilenet_v2\", got \"", o.sun_backbone, "\"");
  SL_CHECK(o.sun_backbone.empty() || o.sun_grid.enabled(), "model.sun_backbone needs model.sun_grid (the sun head)");
  SL_CHECK(o.sun_backbone_channels >= 1, "model.sun_backbone_channels must be positive, got ", o.sun_backbone_channels);
  SL_CHECK(o.head_grid_channels >= 0, "model.head_grid_channels must be >= 0, got ", o.head_grid_channels);
  if (o.volume_branch) {
    const int64_t f = int64_t{1} << o.unet_depth;
    for (int a = 0; a < 3; ++a) {
      SL_CHECK(o.vsg_dims[a] % o.coarse_scale == 0, "model.volume.coarse_scale ", o.coarse_scale,
               " must divide every VSG dim, got dim ", o.vsg_dims[a]);
      SL_CHECK(o.vsg_dims[a] % f == 0, "model.volume.unet_depth ", o.unet_depth, ": VSG dim ", o.vsg_dims[a],
               " must be divisible by ", f);
    }
  }
}

LightingPredictor::LightingPredictor(const LightingPredictorOptions& options)
    : nn::Module("LightingPredictor"), opt_(options) {
  validate(opt_);
  backbone_ = register_module("backbone", std::make_shared<nn::ResNet>(nn::ResNetOptions{
                                              .depth = opt_.backbone_depth, .base_width = opt_.backbone_width}));
  int64_t feat = backbone_->feature_dim();
  if (opt_.head_grid_channels > 0) {
    const auto hw = backbone_grid_size(opt_.image_height, opt_.image_width);
    head_grid_ = register_module("head_grid", std::make_shared<nn::Conv2d>(feat, opt_.head_grid_channels, 1));
    feat += opt_.head_grid_channels * hw[0] * hw[1];
  }
  feat_ = feat;
  const SkyAutoencoderOptions& sky = opt_.sky;
  if (opt_.sky_branch == "sky_decoder") {
    sky_head_ = register_module("sky_head", std::make_shared<nn::MLP>(nn::MlpOptions{
                                                .widths = {feat, opt_.head_hidden, sky.code_dim}}));
    sky_decoder_ = register_module("sky_decoder", std::make_shared<SkyDecoder>(sky));
    if (opt_.sun_grid.enabled()) {
      int64_t sun_inputs = feat + (opt_.sun_image_statistics ? kImageStatistics : 0);
      if (!opt_.sun_backbone.empty()) {
        const auto hw = backbone_grid_size(opt_.image_height, opt_.image_width);
        sun_backbone_ = register_module("sun_backbone", std::make_shared<nn::MobileNetV2>());
        sun_backbone_grid_ = register_module(
            "sun_backbone_grid", std::make_shared<nn::Conv2d>(nn::MobileNetV2::kFeatures, opt_.sun_backbone_channels, 1));
        sun_inputs += opt_.sun_backbone_channels * hw[0] * hw[1];
      }
      sun_head_ = register_module("sun_head", std::make_shared<nn::MLP>(nn::MlpOptions{
                                                  .widths = {sun_inputs, opt_.head_hidden, opt_.sun_grid.cells()}}));
    }
  } else if (opt_.sky_branch == "direct") {
    // Without sky modelling: g → 4×16 feature map → (upsample, conv) per level → log env.
    const int levels = direct_levels(sky.height);
    const int64_t h0 = sky.height >> levels, w0 = sky.width >> levels, c = 2 * sky.base_channels;
    auto dec = std::make_shared<nn::Sequential>();
    dec->push_back(std::make_shared<nn::Linear>(feat, c * h0 * w0));
    env_decoder_ = register_module("env_decoder", dec);
    for (int l = 0; l < levels; ++l) {
      dec->push_back(std::make_shared<nn::Upsample>(2, "linear"));
      dec->push_back(std::make_shared<nn::Conv2d>(c, c, 3, nn::ConvOptions{.padding = 1}));
      dec->push_back(std::make_shared<nn::LeakyReLU>(0.2));
    }
    dec->push_back(std::make_shared<nn::Conv2d>(c, 3, 3, nn::ConvOptions{.padding = 1}));
  } else {
    // Volume-only baseline: a learned constant log environment at 1/4 resolution.
    register_parameter("env_constant", Tensor::zeros({1, 3, std::max<int64_t>(sky.height / 4, 1),
                                                      std::max<int64_t>(sky.width / 4, 1)}));
  }
  if (opt_.volume_branch) {
    for (int a = 0; a < 3; ++a) coarse_[a] = opt_.vsg_dims[a] / opt_.coarse_scale;
    volume_mlp_ = register_module(
        "volume_mlp", std::make_shared<nn::MLP>(nn::MlpOptions{
                          .widths = {feat, opt_.head_hidden, opt_.coarse_channels * coarse_[0] * coarse_[1] * coarse_[2]}}));
    volume_unet_ = register_module("volume_unet", std::make_shared<nn::UNet3D>(nn::UNetOptions{
                                                      .in_channels = opt_.coarse_channels + 4,
                                                      .out_channels = 8,
                                                      .base_channels = opt_.unet_channels,
                                                      .depth = opt_.unet_depth,
                                                      .norm = "group",
                                                      .groups = 4,
                                                      .activation = "leaky_relu:0.2"}));
  }
  init_parameters(opt_.seed);
  if (sky_decoder_) {
    sky_decoder_->freeze(true);
    sky_decoder_->eval();
  }
}

void LightingPredictor::set_training(bool on) {
  train(on);
  // A frozen part (the sky decoder always; train.freeze's parts) keeps its batch-norm statistics.
  for (const auto& [name, child] : children())
    if (child->is_frozen()) child->eval();
}

Tensor LightingPredictor::head_features(const Tensor& image) {
  SL_CHECK(image.dim() == 4 && image.size(1) == 3 && image.size(2) == opt_.image_height &&
               image.size(3) == opt_.image_width,
           "LightingPredictor: expected image [N, 3, ", opt_.image_height, ", ", opt_.image_width, "], got ",
           image.describe());
  const nn::ResNetOutput features = backbone_->forward_features(image);
  if (!head_grid_) return features.pooled;  // [N, feat]
  return concat({features.pooled, flatten(relu(head_grid_->forward(features.features.back())), 1)}, 1);
}

SkyCode LightingPredictor::sky_code(const Tensor& g) {
  SL_CHECK(opt_.sky_branch == "sky_decoder", "LightingPredictor: the '", opt_.sky_branch,
           "' sky branch has no sky vector");
  return sky_code_from_raw(sky_head_->forward(g));
}

SkyCode LightingPredictor::predict_sky_code(const Tensor& image) { return sky_code(head_features(image)); }

Tensor LightingPredictor::volume(const Tensor& g, const Tensor& rgba) {
  SL_CHECK(opt_.volume_branch, "LightingPredictor: this model has no volume branch");
  const int64_t n = g.size(0);
  const auto& d = opt_.vsg_dims;
  SL_CHECK(rgba.defined() && rgba.dim() == 5 && rgba.size(0) == n && rgba.size(1) == 4 && rgba.size(2) == d[0] &&
               rgba.size(3) == d[1] && rgba.size(4) == d[2],
           "LightingPredictor: expected an RGBα volume [", n, ", 4, ", d[0], ", ", d[1], ", ", d[2], "], got ",
           rgba.defined() ? rgba.describe() : std::string("undefined"));
  Tensor coarse = reshape(volume_mlp_->forward(g), {n, opt_.coarse_channels, coarse_[0], coarse_[1], coarse_[2]});
  if (opt_.coarse_scale > 1) coarse = nn::upsample_trilinear3d(coarse, opt_.coarse_scale);
  const Tensor rgba_t = rgba.dtype() == g.dtype() ? rgba : rgba.to(g.dtype());
  return vsg_activate(volume_unet_->forward(concat({coarse, rgba_t}, 1)), 1);
}

Tensor LightingPredictor::sun_logits(const Tensor& g, const Tensor& image) {
  if (!sun_head_) return Tensor();
  if (!opt_.sun_image_statistics && !sun_backbone_) return sun_head_->forward(g);
  SL_CHECK(image.defined() && image.dim() == 4 && image.size(0) == g.size(0), "LightingPredictor::sun_logits: expected the ",
           g.size(0), " image(s) g came from, got ", image.defined() ? image.describe() : std::string("undefined"));
  TensorList inputs{g};
  if (opt_.sun_image_statistics) inputs.push_back(image_statistics(image).to(g.dtype()));
  if (sun_backbone_) {
    const Tensor x = nn::imagenet_input(image.dtype() == g.dtype() ? image : image.to(g.dtype()));
    inputs.push_back(flatten(relu(sun_backbone_grid_->forward(sun_backbone_->forward_map(x))), 1));
  }
  return sun_head_->forward(concat(inputs, 1));
}

SkyPrediction LightingPredictor::predict_sky(const Tensor& image) {
  const Tensor g = head_features(image);
  SkyPrediction out;
  out.code = sky_code(g);
  out.sun_logits = sun_logits(g, image);
  return out;
}

LightingPrediction LightingPredictor::predict(const Tensor& image, const Tensor& rgba) {
  const Tensor g = head_features(image);
  const int64_t n = image.size(0);
  LightingPrediction out;
  out.features = g;
  const SkyAutoencoderOptions& sky = opt_.sky;
  if (opt_.sky_branch == "sky_decoder") {
    out.code = sky_code(g);
    out.sun_logits = sun_logits(g, image);
    SkyDecoding d = sky_decoder_->decode(out.code);
    out.log_env = d.log_hdr;
  } else if (opt_.sky_branch == "direct") {
    const int levels = direct_levels(sky.height);
    const int64_t h0 = sky.height >> levels, w0 = sky.width >> levels, c = 2 * sky.base_channels;
    auto& seq = static_cast<nn::Sequential&>(*env_decoder_);
    Tensor x = reshape(seq[0]->forward(g), {n, c, h0, w0});
    for (size_t i = 1; i < seq.size(); ++i) x = seq[i]->forward(x);
    out.log_env = x;
  } else {
    const Tensor& c = parameter("env_constant");
    Tensor up = c;
    const int64_t scale = sky.height / c.size(2);
    if (scale > 1) up = nn::upsample_bilinear2d(c, scale);
    out.log_env = expand(up, {n, 3, sky.height, sky.width});
  }
  out.env = exp(clamp(out.log_env, -16.0, 16.0));
  if (opt_.volume_branch) out.vsg = volume(g, rgba);
  return out;
}

}  // namespace sl::train
