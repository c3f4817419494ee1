// Discriminator test-time optimisation (paper Sec 4.3, Fig. 7): after the predictor has estimated a
// photo's lighting, N gradient steps on the lighting parameters lower the adversarial loss
// L_adv = −mean D(I_edit) of the stage-3 discriminator D (train/adversarial_stage.h) on the
// composite of the object being inserted. The composite is rendered by the one photo-insertion
// path (train/photo_insertion.h, Eq. 2-4) with the lighting on the tape, as stage 3 backpropagates
// L_adv into the predictor; here the gradient stops at the lighting instead.
//
// Contract:
// - load_discriminator(path): the PatchGAN stored as discriminator.* in a stage-3 checkpoint or
//   in an export that kept it (streetlight-export --with-discriminator), built from the file's
//   own config (model.discriminator; train_config.h's defaults for keys it lacks). Returns
//   nullptr when the file holds no discriminator.* tensor. Throws sl::Error naming the file when
//   it cannot be read or its tensors do not match its config.
// - area_resize(image [C, H, W], h, w): every output pixel is the mean of the input area it
//   covers (fractional overlaps weighted), so a constant image stays constant and the mean is
//   kept. Two matmuls with fixed weights: differentiable, any float dtype.
// - discriminator_input(composite_linear [3, H, W], h, w): D's input as stage 3 forms it,
//   ldr_from_hdr(composite) as [1, 3, h, w], after area_resize to h×w (h = w = 0: as rendered).
//   Stage 3 shows D composites at the dataset's view size, which the shipped configs make the
//   predictor's input size (quickstart 128×64, release 256×128), so the tool passes that size.
// - refine_lighting(start, decoder, D, scene, insertion, options):
//   parameters (RefinementOptions picks them): log f_intensity [1, 3] (the intensity stays in
//   its log form); f_dir as a free v [1, 3] with f_dir = v/|v| on the tape and v set back to
//   unit length after every update; f_latent; with `volume`, the VSG volume's raw values
//   (vsg_activate's inverse of start.vsg, amplitudes, sharpness − λ_min and α clamped into
//   [1e-6, ·] / [1e-6, 1 − 1e-6] first so the inverse is finite).
//   One step: env = decoder(f) (the frozen sky decoder of Sec 3.2), vsg = vsg_activate(raw) or
//   start.vsg, composite = insert_objects(scene with that env and vsg, insertion_options(insertion)
//   with exact volume queries and seed hash_counter(insertion.seed, kRefineStream, step)),
//   loss = generator_adversarial(D(discriminator_input(composite))), backward, one Adam step
//   (nn/optim.h, lr options.lr) on the chosen parameters. A step whose loss or gradient is not
//   finite changes nothing and is counted in skipped_steps, so the refined lighting is finite.
//   loss_before / loss_after: the same loss under start and under the refined lighting, both
//   rendered with insertion.seed (the same seeds; the environment samples still follow each
//   lighting, so a difference smaller than the Monte Carlo noise means nothing).
//   scene: photo_insertion_inputs() of `start` (its env and vsg are replaced, never modified).
//   D is frozen and in eval mode during the call (its state is restored on return); neither D
//   nor the decoder is updated. The result's env is decoded from the refined code off the tape;
//   with steps = 0 the result's lighting is `start` itself, bitwise.
//   Throws sl::Error when start has no sky vector (the "sky_decoder" branch is needed), when
//   `volume` is asked without a volume, when no parameter is chosen, or for steps < 0 or a
//   non-positive or non-finite lr. on_step, when set, is called after every step with its loss.
#pragma once
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "autodiff/tensor.h"
#include "nn/modules/patch_discriminator.h"
#include "render/object_insertion.h"
#include "train/inference.h"
#include "train/photo_insertion.h"
#include "train/sky_autoencoder.h"

namespace sl::train {

inline constexpr uint64_t kRefineStream = 0x726566696E65ULL;  // "refine": each step's own samples

std::shared_ptr<nn::PatchDiscriminator> load_discriminator(const std::string& path);

Tensor area_resize(const Tensor& image, int64_t height, int64_t width);
Tensor discriminator_input(const Tensor& composite_linear, int64_t height, int64_t width);

struct RefinementOptions {
  int steps = 0;
  double lr = 0.05;  // Adam; log-intensity, direction and latent are all O(1) quantities
  bool intensity = true, direction = true, latent = true;
  bool volume = false;
  int64_t discriminator_height = 0, discriminator_width = 0;  // 0: D sees the composite as rendered
  std::function<void(int step, double loss)> on_step;  // after each step (progress); may be empty
};

struct RefinementResult {
  EstimatedLighting lighting;          // refined (start when steps = 0)
  double loss_before = 0.0, loss_after = 0.0;  // −mean D at insertion.seed
  std::vector<double> loss_per_step;   // −mean D at each step's own samples, before its update
  int skipped_steps = 0;               // non-finite loss or gradient: no update
  double time_ms = 0.0;
};

RefinementResult refine_lighting(const EstimatedLighting& start, SkyDecoder& decoder, nn::PatchDiscriminator& d,
                                 const render::InsertionInputs& scene, const PhotoInsertionOptions& insertion,
                                 const RefinementOptions& options);

}  // namespace sl::train
