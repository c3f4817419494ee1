// Stages 2 and 3 (Sec 3.4): the hybrid lighting predictor with supervised losses ("lighting"),
// then end to end through differentiable object insertion with a discriminator
// ("adversarial", adversarial_stage.cpp).
//
// Model (one checkpoint): predictor.* (LightingPredictor, with its frozen sky decoder),
// teacher.* (the frozen stage-1 SkyAutoencoder, for the HDR pseudo-labels of Sec 3.4; absent
// for the volume-only "constant" sky branch), discriminator.* (stage 3 only).
//
// Supervised loss per sample (weights loss.*), averaged over the batch:
//   sky_decoder branch: sky_intensity LogEncodedL2(f̂_int, f̃_int), sky_latent L1(f̂_lat, f̃_lat)
//     (f̃ = teacher encoder on the full panorama), sky_direction L1-angular(f̂_dir, true sun),
//     sky_ldr L1 between LDR(decoded sky) and the panorama inside the sky mask;
//   direct branch: sky_hdr LogEncodedL2(env, teacher-decoded HDR) and sky_ldr;
//   constant branch: no sky term (the volume-only baseline learns the sky from rays);
//   volume terms on radiance-queried rays (Eq. 1; env lookup only without the volume):
//     radiance L2 in LDR, depth consistency, sky_separation BCE(τ_K, sky mask).
// Data order: sample (step·B + i) of the epoch permutation epoch_order(n, seed, epoch); the
// input view and the rays come from Rng(seed, step·B + i): resume is bit-identical.
// Validation on the val split (view 0 as input, fixed rays): val_loss (best metric), sun angular
// error median/mean (f̂_dir, or the peak of the predicted env map for the other branches), and
// PSNR / si-PSNR of the LDR radiance of every other view rendered at data.val_view_height rows.
#pragma once
#include <functional>
#include <map>
#include <memory>

#include <nlohmann/json.hpp>

#include "data/street_dataset.h"
#include "nn/discriminator.h"
#include "render/mesh.h"
#include "train/lighting_predictor.h"
#include "train/street_batch.h"
#include "train/trainer.h"

namespace sl::train {

// Where samples come from: a StreetDataset split, or in-memory samples in tests.
struct SampleSource {
  size_t size = 0;
  std::function<StreetSample(size_t)> load;
};
SampleSource dataset_source(const std::string& dir, const std::string& split);

class LightingStage : public Stage {
 public:
  LightingStage(const nlohmann::json& config, SampleSource train, SampleSource val);
  std::string name() const override { return adversarial_ ? "adversarial" : "lighting"; }
  nn::Module& model() override { return *model_; }
  nn::Optimizer& optimizer() override { return *optim_; }
  void initialise() override;
  Metrics step(int64_t step) override;
  Metrics validate() override;
  std::string best_metric() const override { return "val_loss"; }
  void write_strip(const std::string& path) override;
  void set_lr(double lr) override { lr_ = lr; optim_->set_lr(lr); }

  LightingPredictor& predictor() { return *predictor_; }
  nn::PatchDiscriminator* discriminator() { return discriminator_.get(); }

  struct Forward {
    std::vector<StreetSample> samples;
    std::vector<StreetItem> items;
    LightingPrediction pred;
  };
  // Builds the batch of `step` (or the validation batch of sample `val_index`) and runs the
  // predictor on it.
  Forward forward_train(int64_t step);
  Forward forward_val(size_t val_index);
  // The supervised loss of Sec 3.4 over a forward (adds its terms to `m`).
  Tensor supervised_loss(const Forward& f, Metrics& m);
  // Stage 3: the differentiable composite of sample i (insert_objects), linear [3, H, W].
  Tensor composite(const Forward& f, size_t i, uint64_t seed);
  Tensor real_composite_ldr(const StreetSample& s) const;

 private:
  Forward forward_items(std::vector<StreetSample> samples, const std::vector<size_t>& views, uint64_t seed,
                        uint64_t first_stream);
  struct Query {
    Tensor radiance, transmittance, depth;
  };
  Query query(const Forward& f, size_t i, const Tensor& origins, const Tensor& directions);
  Metrics adversarial_step(int64_t step);
  Metrics supervised_step(int64_t step);
  const Mesh& object_mesh(const std::string& path);

  nlohmann::json config_;
  bool adversarial_ = false;
  uint64_t seed_;
  int64_t batch_size_;
  double clip_, lr_ = 0.0;
  SampleSource train_, val_;
  StreetBatchOptions batch_opt_;
  VsgGrid grid_template_;
  std::shared_ptr<nn::Module> model_;
  std::shared_ptr<LightingPredictor> predictor_;
  std::shared_ptr<SkyAutoencoder> teacher_;
  std::shared_ptr<nn::PatchDiscriminator> discriminator_;
  std::unique_ptr<nn::Optimizer> optim_;
  std::map<std::string, Mesh> meshes_;
};

std::unique_ptr<Stage> make_lighting_stage(const nlohmann::json& config);

}  // namespace sl::train
