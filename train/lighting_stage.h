// Stages 2 and 3 (Sec 3.4): the hybrid lighting predictor with supervised losses ("lighting"),
// then end to end through differentiable object insertion with a discriminator
// ("adversarial": AdversarialStage, train/adversarial_stage.h, a LightingStage with stage 3's step).
//
// Model (one checkpoint): predictor.* (LightingPredictor, with its frozen sky decoder),
// teacher.* (the frozen stage-1 SkyAutoencoder, for the HDR pseudo-labels of Sec 3.4; absent
// for the volume-only "constant" sky branch), discriminator.* (stage 3 only).
//
// Supervised loss per sample (weights loss.*), averaged over the batch:
//   sky_decoder branch: sky_intensity LogEncodedL2(f̂_int, f̃_int), sky_latent L1(f̂_lat, f̃_lat)
//     (f̃ = teacher encoder on the full panorama), sky_direction between f̂_dir and the true sun
//     (loss.sky_direction_form: angular_l1 by default, or elevation_azimuth_l1; train/losses.h),
//     sky_ldr L1 between LDR(decoded sky) and the panorama inside the sky mask; sun_energy
//     LogEncodedL2 between the energy of the sky vector's analytic sun lobe and the true sun's
//     Σ L·Ω within 5° (StreetItem.sun_energy: samples whose sky is HDR and sun known);
//     ldr_sun_energy, on LDR panoramas whose sun has a position (no energy label: their sun is
//     clipped), the lobe's distance outside loss.ldr_sun_energy_range (log_encoded_range_l2);
//   direct branch: sky_hdr LogEncodedL2(env, teacher-decoded HDR) and sky_ldr;
//   constant branch: no sky term (the volume-only baseline learns the sky from rays);
//   volume terms on radiance-queried rays (Eq. 1; env lookup only without the volume):
//     radiance L2 in LDR, depth consistency, sky_separation BCE(τ_K, sky mask).
// Init (initialise()): a stage-1 checkpoint (init.sky_checkpoint: the teacher, and the predictor's
// frozen decoder copied from it), or a stage-2/3 checkpoint (init.checkpoint: predictor and
// teacher; an exported predictor-only file takes its teacher from init.sky_checkpoint). The
// teacher runs only when sky_intensity or sky_latent is on, and then its decoder must be the
// predictor's frozen decoder bit for bit (else sl::Error). train.freeze names predictor parts
// that keep their weights and batch-norm statistics.
// Data order: sample (step·B + i) of the epoch permutation epoch_order(n, seed, epoch); the
// input view and the rays come from Rng(seed, step·B + i): resume is bit-identical. Sources
// (train/sample_source.h): the street dataset, mixed with crops of real HDR panoramas at
// data.real_fraction and of labelled real LDR panoramas at data.ldr_fraction (configs/README.md,
// "Mixing"); samples whose sun is not a usable label (sun_known = false) get no direction loss. data.flip (stage 2): each training sample is mirrored with probability 1/2
// (data/augment.h flip_sample, drawn from the same Rng after the view). The next step's batch
// is built on a background thread while the current step computes; it is the same pure
// function of the step, so prefetching changes nothing.
// Each step reports its phases' wall time (time_data_ms, time_forward_ms, time_render_ms,
// time_backward_ms, time_optimizer_ms); time_data_ms is the time spent WAITING for data.
// Validation on the val split (view 0 as input, fixed rays): val_loss, sun angular error
// median/mean (f̂_dir, or the peak of the predicted env map for the other branches) over the
// samples with a known sun, also split into val_street_*, val_real_* (crops of the HDRI split's
// val panoramas, data.real_val_crops each, whenever data.hdri_split is set) and val_ldr_* (crops
// of the LDR split's val panoramas, data.ldr_val_crops each, whenever data.ldr_split is set), and PSNR / si-PSNR of the LDR
// radiance of every other view rendered at data.val_view_height rows. best.safetensors follows
// train.best_metric (default val_loss).
// Domain-adversarial training (loss.domain_adversarial > 0, stage 2 only; issue 53): a classifier
// domain_head.* (MLP g → 64 → 1, ReLU) on the pooled features g, behind a gradient reversal of
// strength loss.domain_reversal (nn/functional/gradient_reversal.h), learns to tell a generated
// street (label 0) from a real crop (HDR or LDR panorama, label 1) by bce_with_logits, while the
// reversed gradient pushes the backbone toward features in which the two look alike, so that what
// the sun head learns on the streets' many places carries over to the real photos. It is a
// training term only: validation and val_loss leave it out, and the exported model holds no
// domain_head. Reported as domain_adversarial and domain_accuracy (the classifier's share right).
// The classifier learns at loss.domain_lr_scale times the stage's learning rate (nn::Optimizer
// set_lr_scale): it starts afresh inside a model that is often fine-tuned at a small rate.
#pragma once
#include <future>
#include <map>
#include <memory>

#include <nlohmann/json.hpp>

#include "data/street_dataset.h"
#include "nn/modules/patch_discriminator.h"
#include "render/mesh.h"
#include "train/lighting_predictor.h"
#include "train/sample_source.h"
#include "train/street_batch.h"
#include "train/trainer.h"

namespace sl::train {

class LightingStage : public Stage {
 public:
  LightingStage(const nlohmann::json& config, SampleSource train, SampleSource val);
  std::string name() const override { return adversarial_ ? "adversarial" : "lighting"; }
  nn::Module& model() override { return *model_; }
  nn::Optimizer& optimizer() override { return *optim_; }
  void initialise() override;
  Metrics step(int64_t step) override;
  Metrics validate() override;
  std::string best_metric() const override { return best_metric_; }
  void write_strip(const std::string& path) override;
  void set_lr(double lr) override { lr_ = lr; optim_->set_lr(lr); }

  LightingPredictor& predictor() { return *predictor_; }
  nn::PatchDiscriminator* discriminator() { return discriminator_.get(); }

  struct Forward {
    std::vector<data::StreetSample> samples;
    std::vector<StreetItem> items;
    LightingPrediction pred;
    // Data parallel: this shard's factor on the sky_ldr masked mean (distributed.h, global_share).
    double sky_ldr_share = 1.0;
  };
  // Builds the batch of `step` (or the validation batch of sample `val_index`) and runs the
  // predictor on it.
  Forward forward_train(int64_t step);
  Forward forward_val(size_t val_index);
  // The supervised loss of Sec 3.4 over a forward (adds its terms to `m`).
  Tensor supervised_loss(const Forward& f, Metrics& m);

 protected:
  // loss.sky_intensity or loss.sky_latent is on: the stage-1 teacher's pseudo-labels are used.
  bool teacher_pseudo_labels() const;
  // The composite shown in the training strip (undefined: none); stage 3 overrides it.
  virtual Tensor strip_composite(const Forward& f) { return Tensor(); }
  struct Batch {
    std::vector<data::StreetSample> samples;
    std::vector<StreetItem> items;
  };
  // The samples and items of training step `step`: a pure function of it (thread-safe).
  Batch train_batch(int64_t step) const;
  Batch make_batch(std::vector<data::StreetSample> samples, const std::vector<size_t>& views, uint64_t seed,
                   uint64_t first_stream) const;
  Forward run_predictor(Batch batch);
  struct Query {
    Tensor radiance, transmittance, depth;
  };
  Query query(const Forward& f, size_t i, const Tensor& origins, const Tensor& directions);
  Metrics supervised_step(int64_t step);
  // loss.domain_adversarial's term over a training forward (adds it and the classifier's accuracy to `m`).
  Tensor domain_loss(const Forward& f, Metrics& m);

  nlohmann::json config_;
  bool adversarial_ = false, flip_ = false;
  uint64_t seed_;
  int64_t batch_size_;
  double clip_, lr_ = 0.0;
  SampleSource train_, val_;
  StreetBatchOptions batch_opt_;
  render::VsgGrid grid_template_;
  std::shared_ptr<nn::Module> model_;
  std::shared_ptr<LightingPredictor> predictor_;
  std::shared_ptr<SkyAutoencoder> teacher_;
  std::shared_ptr<nn::PatchDiscriminator> discriminator_;
  std::shared_ptr<nn::Module> domain_head_;  // loss.domain_adversarial > 0 only
  std::unique_ptr<nn::Optimizer> optim_;
  std::string best_metric_ = "val_loss";
  double last_data_ms_ = 0.0;
  // The next step's batch, built in the background; declared last so that it is waited for
  // before anything it reads is destroyed.
  int64_t prefetch_step_ = -1;
  std::future<Batch> prefetch_;
};

std::unique_ptr<Stage> make_lighting_stage(const nlohmann::json& config);

}  // namespace sl::train
