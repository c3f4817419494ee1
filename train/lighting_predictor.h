// The two-branch hybrid lighting predictor of Sec 3.2 / Fig. 2a.
//
//   image [N, 3, h, w] ─ ResNet backbone ─ feature g: the pooled vector [N, 8·width], and with
//     head_grid_channels = r > 0 also layer4's map reduced by a 1×1 conv + ReLU to r channels and
//     flattened ([N, r·h/32·w/32], "head_grid.*"), so the heads see WHERE things are in the image
//     (the sun, the bright side of the sky, the shadows), which a global average discards
//     (a) sky head: MLP(g) → raw f̂ → SkyCode → FROZEN sky decoder → HDR sky [N, 3, Hs, Ws]
//         with sun_grid on, also a sun head: MLP(g) → logits [N, K] of a distribution over sun
//         directions on the upper hemisphere (train/sun_distribution.h, issue 53); inference
//         reads the sky vector's direction at its mode (train/inference.h). With
//         sun_image_statistics on, the sun head's input is g concatenated with 102 photometric
//         statistics of the image (train/image_statistics.h); with sun_backbone "mobilenet_v2" it
//         also sees an ImageNet MobileNetV2's map of the image (nn/modules/mobilenet_v2.h, stride 32,
//         1280 channels) reduced by a 1×1 conv + ReLU to sun_backbone_channels and flattened
//         ("sun_backbone.*", "sun_backbone_grid.*"), after g and the statistics
//     (b) volume: MLP(g) → coarse feature volume [N, C, X/s, Y/s, Z/s] → trilinear ×s,
//         concatenated with the unprojected RGBα volume [N, 4, X, Y, Z] (unprojection.h),
//         → UNet3D → raw [N, 8, X, Y, Z] → vsg_activate → VSG parameters
//
// Sky branch variants (the paper's ablations, Tables 1-2):
//   "sky_decoder" — the method: the frozen decoder of the stage-1 sky autoencoder. Its
//                   parameters never receive gradients (nn freeze()), but gradients flow
//                   THROUGH it into the sky head and the backbone.
//   "direct"      — without sky modelling: a small conv decoder maps g straight to a log-space
//                   environment map (no sky vector, no frozen model).
//   "constant"    — volume-only baseline (Wang et al.): no HDR sky model; a learned constant
//                   low-resolution log environment map, upsampled.
// volume_branch = false gives the sky-only baseline (Hold-Geoffroy et al.): vsg is undefined.
//
// Contract: forward(image, rgba) with image [N, 3, image_height, image_width] (LDR in [0, 1])
// and rgba [N, 4, X, Y, Z] (ignored, may be undefined, without the volume branch). Outputs are
// exposure-normalised radiance (sky_autoencoder.h). Shapes are checked, naming the input.
// Parameter names: backbone.*, head_grid.* (with head_grid_channels > 0), sky_head.*, sun_head.* (sun_grid on),
// sun_backbone.*, sun_backbone_grid.* (with sun_backbone), sky_decoder.*, env_decoder.*, env_constant,
// volume_mlp.*, volume_unet.*. Deterministic init from options.seed.
#pragma once
#include <array>
#include <memory>
#include <string>

#include "nn/module.h"
#include "nn/modules/mobilenet_v2.h"
#include "nn/modules/resnet.h"
#include "train/sky_autoencoder.h"
#include "train/sun_distribution.h"

namespace sl::train {

struct LightingPredictorOptions {
  int64_t image_height = 128, image_width = 256;
  int backbone_depth = 18;
  int64_t backbone_width = 64;
  int64_t head_hidden = 256;
  int64_t head_grid_channels = 0;  // 0: the pooled vector alone (the releases up to 2026-11-23)
  std::string sky_branch = "sky_decoder";  // "sky_decoder" | "direct" | "constant"
  bool volume_branch = true;
  std::array<int64_t, 3> vsg_dims{64, 64, 16};
  int64_t coarse_scale = 8;     // coarse feature volume = vsg_dims / coarse_scale
  int64_t coarse_channels = 8;
  int64_t unet_channels = 8;
  int unet_depth = 3;
  SkyAutoencoderOptions sky;    // dome size and code size (must match the stage-1 model)
  SunGrid sun_grid;             // off (0 × 0): the sky vector's direction alone (releases up to 2026-11-27)
  bool sun_image_statistics = false;  // the sun head also sees image_statistics(image) (needs sun_grid)
  std::string sun_backbone;           // "" or "mobilenet_v2": a second backbone for the sun head alone (needs sun_grid)
  int64_t sun_backbone_channels = 16;  // its map's channels after the 1×1 reduction
  uint64_t seed = 0;
};

struct LightingPrediction {
  SkyCode code;     // defined for the "sky_decoder" branch only
  Tensor log_env;   // [N, 3, Hs, Ws]
  Tensor env;       // [N, 3, Hs, Ws] = exp(log_env) (clamped)
  Tensor vsg;       // [N, 8, X, Y, Z] activated, or undefined without the volume branch
  Tensor sun_logits;  // [N, K] over options.sun_grid's cells, or undefined (sun_grid off)
  Tensor features;    // g [N, feat], the pooled features every head reads (loss.domain_adversarial)
};

// The sky half of a prediction: the sky vector and, with sun_grid on, the sun's logits.
struct SkyPrediction {
  SkyCode code;
  Tensor sun_logits;
};

class LightingPredictor : public nn::Module {
 public:
  explicit LightingPredictor(const LightingPredictorOptions& options);
  LightingPrediction predict(const Tensor& image, const Tensor& rgba);
  // The sky vector alone (backbone and sky head; no decoding, no volume): "sky_decoder" only.
  SkyCode predict_sky_code(const Tensor& image);
  // The sky vector and the sun's logits (backbone, sky head and sun head; no decoding, no volume).
  SkyPrediction predict_sky(const Tensor& image);
  // The parts predict() composes, for inference that needs only some outputs or batches images
  // whose volumes it does not want (train/inference.cpp): predict(image, rgba) computes
  // g = features(image), code = sky_code(g) (decoded to log_env), sun_logits(g, image), vsg = volume(g,
  // rgba), each the same ops on the same values as here. features: image [N, 3, h, w] -> g [N, feat];
  // sky_code: g [N, feat] -> SkyCode ("sky_decoder" only; throws otherwise); sun_logits: g and the
  // image g came from -> [N, K] (undefined without a sun head; the image is read only with
  // sun_image_statistics or a sun_backbone); volume: g [N, feat] and rgba [N, 4, X, Y, Z] -> activated VSG
  // [N, 8, X, Y, Z] (volume branch only; throws otherwise). Shapes are checked as predict() checks them.
  Tensor features(const Tensor& image) { return head_features(image); }
  SkyCode sky_code(const Tensor& g);
  Tensor sun_logits(const Tensor& g, const Tensor& image);
  Tensor volume(const Tensor& g, const Tensor& rgba);
  const LightingPredictorOptions& options() const { return opt_; }
  int64_t feature_dim() const { return feat_; }  // g's width
  // The frozen decoder (null unless sky_branch is "sky_decoder").
  const std::shared_ptr<SkyDecoder>& sky_decoder() const { return sky_decoder_; }
  nn::ResNet& backbone() { return *backbone_; }
  // The sun head's own backbone (null without options.sun_backbone).
  const std::shared_ptr<nn::MobileNetV2>& sun_backbone() const { return sun_backbone_; }
  // Restores train/eval recursively, keeping every frozen part (the sky decoder, and what
  // train.freeze names) in eval mode: a frozen backbone's batch norms keep their statistics.
  void set_training(bool on);

 private:
  Tensor head_features(const Tensor& image);  // g of the figure above, after the shape check

  LightingPredictorOptions opt_;
  std::shared_ptr<nn::ResNet> backbone_;
  std::shared_ptr<nn::Module> head_grid_, sky_head_, sun_head_, env_decoder_, volume_mlp_, volume_unet_, sun_backbone_grid_;
  std::shared_ptr<nn::MobileNetV2> sun_backbone_;
  std::shared_ptr<SkyDecoder> sky_decoder_;
  std::array<int64_t, 3> coarse_{};
  int64_t feat_ = 0;
};

void validate(const LightingPredictorOptions& options);

// Height and width of the backbone's last map (stride 32: five halvings, each rounding up).
std::array<int64_t, 2> backbone_grid_size(int64_t image_height, int64_t image_width);

}  // namespace sl::train
