// Stage 3 (Sec 3.4, "Training Lighting via Object Insertion"): the lighting stage trained end to
// end through differentiable object insertion (Sec 3.3, render/object_insertion.h) against a
// discriminator.
//
// Contract: the config's stage is "adversarial" (train/train_config.h); the model is
// LightingStage's plus discriminator.* when loss.adversarial > 0 (with 0, the no-adversarial
// ablation: the same steps without D). One step: (1) predictor forward, supervised loss
// (LightingStage), the composite I_edit of each sample whose object centre is in view 0,
// generator loss L_adv = −D(I_edit) with D frozen, backward, update the predictor with
// supervised + w_adv·L_adv; (2) hinge loss of D on the dataset's path-traced insertions (real)
// against the detached composites (fake), update D at optim.discriminator_lr. Deterministic in
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
  // The differentiable composite of sample i (insert_objects), linear [3, H, W].
  Tensor composite(const Forward& f, size_t i, uint64_t seed);
  // The dataset's path-traced insertion of a sample, in LDR: the discriminator's "real".
  Tensor real_composite_ldr(const StreetSample& s) const;

 protected:
  Tensor strip_composite(const Forward& f) override;

 private:
  const Mesh& object_mesh(const std::string& path);
  std::map<std::string, Mesh> meshes_;
};

}  // namespace sl::train
