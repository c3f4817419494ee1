// The sky modelling network of Sec 3.2 / Fig. 3: an encoder from an LDR panorama to the sky
// vector f = (f_intensity 3, f_dir 3, f_latent d − 6) and a decoder from f back to the HDR sky.
//
// Units: every radiance here is EXPOSURE-NORMALISED, i.e. the radiance L·exposure for which the
// paper's LDR is clip(L^(1/2.2), 0, 1) (Sec 3.4). The predictor, the losses and the insertion
// all work in these units, so an LDR photo and its predicted lighting agree without an extra
// exposure parameter.
//
// Contract:
// - SkyEncoder.forward(ldr [N, 3, H, W]) -> raw [N, d]; sky_code_from_raw() turns raw outputs
//   (of the encoder or of the predictor's sky head) into a SkyCode:
//     log_intensity = raw[0:3] (f_intensity = exp(log_intensity), positive by construction),
//     dir = normalize(raw[3:6]) (guarded: a zero vector maps to 0, never NaN),
//     latent = raw[6:d].
//   The encoder sees a per-pixel direction encoding next to the LDR image, so it can locate
//   the sun; it downsamples by 2 until the height is at most 4, then flattens into an MLP.
// - SkyDecoder.forward(code) -> SkyDecoding { log_hdr [N, 3, H, W], hdr = exp(log_hdr) }.
//   The decoder works in LOG space (so it spans 1e-3..1e6) and is conditioned explicitly on
//   the sun: at every scale it is fed the per-pixel direction encoding d, the spherical-Gaussian
//   maps exp(λ_j (d·f_dir − 1)) for a few sharpnesses λ_j and the log sun intensity. Its output
//   is combined with an analytic sun lobe in log space,
//     log L(d) = logaddexp(net(d), log f_intensity + λ_sun (d·f_dir − 1)),
//   so editing f_dir moves the sun and editing f_intensity brightens it, trained or not.
//   λ_sun gives the lobe a full width at half maximum of `sun_lobe_texels` texel heights.
// - All outputs are finite for any finite input (log_hdr is clamped to [−16, 16] before exp).
// - Names: encoder.*, decoder.* (PyTorch style); deterministic init from options.seed.
#pragma once
#include <cstdint>
#include <memory>
#include <vector>

#include "nn/module.h"

namespace sl::train {

struct SkyAutoencoderOptions {
  int64_t height = 32, width = 128;  // sky dome resolution (paper 64×256)
  int64_t code_dim = 64;             // d (paper 64)
  int64_t base_channels = 16;
  int64_t hidden = 256;              // MLP width between the conv trunk and the code
  double sun_lobe_texels = 1.0;
  uint64_t seed = 0;
};

// The sky vector f, split (Sec 3.2).
struct SkyCode {
  Tensor log_intensity;  // [N, 3]
  Tensor dir;            // [N, 3] unit
  Tensor latent;         // [N, d − 6]
  Tensor intensity() const;  // exp(log_intensity), clamped to stay finite
};

SkyCode sky_code_from_raw(const Tensor& raw);

struct SkyDecoding {
  Tensor log_hdr;  // [N, 3, H, W]
  Tensor hdr;      // exp(log_hdr)
};

// Unit world direction of every texel centre of an H×W panorama: [3, H, W] (render/equirect.h).
Tensor panorama_directions(int64_t height, int64_t width, DType dtype = DType::F32);

// The spherical-Gaussian sharpness whose lobe is `texels` texel heights wide at half maximum.
double sun_lobe_sharpness(int64_t height, double texels);

class SkyEncoder : public nn::Module {
 public:
  explicit SkyEncoder(const SkyAutoencoderOptions& options);
  Tensor forward(const Tensor& ldr) override;  // raw [N, d]
  SkyCode encode(const Tensor& ldr) { return sky_code_from_raw(forward(ldr)); }

 private:
  SkyAutoencoderOptions opt_;
  std::vector<std::shared_ptr<nn::Module>> trunk_;
  std::shared_ptr<nn::Module> head_;
  Tensor dirs_;
};

class SkyDecoder : public nn::Module {
 public:
  explicit SkyDecoder(const SkyAutoencoderOptions& options);
  SkyDecoding decode(const SkyCode& code);
  const SkyAutoencoderOptions& options() const { return opt_; }

 private:
  Tensor conditioning(const SkyCode& code, int64_t level) const;  // [N, 9, h, w]
  SkyAutoencoderOptions opt_;
  int levels_ = 0;
  int64_t h0_ = 0, w0_ = 0, c0_ = 0;
  std::shared_ptr<nn::Module> fc_, head_;
  std::vector<std::shared_ptr<nn::Module>> blocks_;
  std::vector<Tensor> dirs_;  // per level [1, 3, h, w]
  double sun_sharpness_ = 0.0;
};

class SkyAutoencoder : public nn::Module {
 public:
  explicit SkyAutoencoder(const SkyAutoencoderOptions& options);
  struct Output {
    SkyCode code;
    SkyDecoding sky;
  };
  Output run(const Tensor& ldr);
  const std::shared_ptr<SkyEncoder>& encoder() const { return encoder_; }
  const std::shared_ptr<SkyDecoder>& decoder() const { return decoder_; }
  const SkyAutoencoderOptions& options() const { return opt_; }

 private:
  SkyAutoencoderOptions opt_;
  std::shared_ptr<SkyEncoder> encoder_;
  std::shared_ptr<SkyDecoder> decoder_;
};

// Number of 2× downsamplings from `height` until it is at most 4 (at least 1).
int sky_levels(int64_t height);

}  // namespace sl::train
