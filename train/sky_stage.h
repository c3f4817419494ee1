// Stage 1 (Sec 3.4, "Sky Modeling Supervision"): the sky autoencoder trained on (LDR, HDR)
// panoramas from sky_data.h with
//   L = w_dir·L1-angular(f̂_dir, f_dir) + w_int·LogEncodedL2(f̂_intensity, f_intensity)
//     + w_hdr·LogEncodedL2(decoded HDR, HDR).
// Validation: the same losses plus the sun's angular error (median and mean, degrees) of f̂_dir
// on data.val_size held-out samples (a seed stream the training never draws). Best metric:
// val_loss. The next stage freezes the model from this stage's checkpoint.
#pragma once
#include <memory>

#include <nlohmann/json.hpp>

#include "train/sky_autoencoder.h"
#include "train/sky_data.h"
#include "train/trainer.h"

namespace sl::train {

class SkyStage : public Stage {
 public:
  explicit SkyStage(const nlohmann::json& config);
  std::string name() const override { return "sky_autoencoder"; }
  nn::Module& model() override { return *model_; }
  nn::Optimizer& optimizer() override { return *optim_; }
  Metrics step(int64_t step) override;
  Metrics validate() override;
  std::string best_metric() const override { return "val_loss"; }
  void write_strip(const std::string& path) override;
  SkyAutoencoder& autoencoder() { return *model_; }

 private:
  struct Batch {
    Tensor ldr, hdr, sun_dir, sun_intensity;
  };
  Batch make_batch(uint64_t seed, uint64_t first_index, int64_t count) const;
  Metrics losses(const Batch& b, const SkyAutoencoder::Output& out, Tensor* total) const;

  nlohmann::json config_;
  uint64_t seed_;
  int64_t batch_size_;
  double clip_;
  std::unique_ptr<SkyDataSource> data_;
  std::shared_ptr<SkyAutoencoder> model_;
  std::unique_ptr<nn::Optimizer> optim_;
};

}  // namespace sl::train
