// Stage 3 (Sec 3.4, "Training Lighting via Object Insertion"): the lighting stage trained end to
// end through differentiable object insertion (Sec 3.3, render/object_insertion.h) against a
// discriminator.
//
// Contract: the config's stage is "adversarial" (train/train_config.h); the model is
// LightingStage's plus discriminator.* when loss.adversarial > 0 (with 0, the no-adversarial
// ablation: the same steps without D). One step: (1) predictor forward, supervised loss
// (LightingStage), the composite I_edit of each sample whose object centre is in view 0,
// generator loss L_adv = −D(I_edit) with D frozen, backward, update the predictor with
// supervised + w_adv·L_adv; (2) hinge loss of D on real_composite_ldr (below) against the
// detached composites (fake), update D at optim.discriminator_lr. Deterministic in
// (seed, step) like LightingStage, so resume is bit-identical.
// Throws: sl::Error naming the sample when it lacks its path-traced insertion.
#pragma once
#include <map>
#include <string>

#include "render/mesh.h"
#include "train/lighting_stage.h"

namespace sl::train {

class AdversarialStage : public LightingStage {
 public:
  AdversarialStage(const nlohmann::json& config, SampleSource train, SampleSource val);
  Metrics step(int64_t step) override;
  // The differentiable composite of sample i (insert_objects) under the predicted lighting,
  // linear [3, H, W]; composite_under() under any env (and optional vsg).
  Tensor composite(const Forward& f, size_t i, uint64_t seed);
  Tensor composite_under(const Forward& f, size_t i, const Tensor& env, const Tensor& vsg, uint64_t seed);
  // The true light of sample i as the predictor's sky dome: the generator's HDR panorama at the
  // camera, exposure-normalised, turned into the canonical frame and area-averaged to the dome
  // size (so it is no sharper than a predicted dome can be). [3, dome_height, dome_width].
  Tensor ground_truth_env(const Forward& f, size_t i) const;
  // The discriminator's "real" image of sample i, LDR [3, H, W] (insertion.real):
  //   "renderer": composite_under(ground_truth_env) with its own seed — the same renderer,
  //     options and object as the fake, so real and fake differ only in their lighting;
  //   "path_traced": the generator's path-traced insertion (differs in renderer as well).
  Tensor real_composite_ldr(const Forward& f, size_t i, uint64_t seed);

 protected:
  Tensor strip_composite(const Forward& f) override;

 private:
  const render::Mesh& object_mesh(const std::string& path);
  // Data parallel: a rank with no insertable sample while others have one still takes part in
  // both updates (its supervised gradients, no discriminator gradient).
  Metrics step_without_samples(int64_t step, const Tensor& total, Metrics& m, double forward_ms);
  std::map<std::string, render::Mesh> meshes_;
};

}  // namespace sl::train
