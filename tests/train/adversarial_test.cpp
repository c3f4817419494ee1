// Stage 3 (Sec 3.3-3.4): the adversarial loss on a differentiable composite reaches the
// backbone's FIRST convolution through the discriminator, the composite (insert_objects), the
// radiance query, the frozen sky decoder and both heads; and a few steps of the stage run.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "autodiff/ops.h"
#include "nn/checkpoint.h"
#include "nn/modules/patch_discriminator.h"
#include "render/gltf_writer.h"
#include "render/object_insertion.h"
#include "render/primitives.h"
#include "support/street_fixture.h"
#include "support/tiny_model.h"
#include "train/adversarial_stage.h"
#include "train/lighting_stage.h"
#include "train/losses.h"
#include "train/train_config.h"
#include "train/unprojection.h"

namespace sl::train {
namespace {

namespace fs = std::filesystem;

double grad_abs_sum(const nn::Module& m, const std::string& prefix) {
  double s = 0;
  for (const auto& [n, t] : m.named_parameters())
    if (n.rfind(prefix, 0) == 0 && t.grad().defined())
      for (double v : t.grad().to_vector()) s += std::abs(v);
  return s;
}

TEST(Adversarial, GeneratorLossReachesTheFirstConvThroughCompositeRendererAndFrozenDecoder) {
  LightingPredictorOptions o;
  o.image_height = 32;
  o.image_width = 64;
  o.backbone_width = 4;
  o.head_hidden = 16;
  o.vsg_dims = {8, 8, 4};
  o.coarse_scale = 4;
  o.coarse_channels = 2;
  o.unet_channels = 4;
  o.unet_depth = 1;
  o.sky = SkyAutoencoderOptions{.height = 8, .width = 32, .code_dim = 12, .base_channels = 4, .hidden = 16};
  LightingPredictor predictor(o);
  nn::PatchDiscriminator disc({.base_channels = 4, .layers = 2, .norm = "none", .seed = 1});

  const StreetSample s = test::tiny_street_sample(3, 64, 32);
  const StreetView& view = s.views[0];
  VsgGrid grid;
  grid.dims = {8, 8, 4};
  grid.center = view.camera.position();
  const Tensor rgba = unsqueeze(unproject_rgba(view.ldr, view.depth, view.camera, grid), 0);
  const LightingPrediction pred = predictor.predict(unsqueeze(view.ldr, 0), rgba);

  InsertionInputs in;
  in.background = pow_scalar(view.ldr, 2.2);
  in.depth = view.depth;
  in.camera = view.camera;
  in.env = select(pred.env, 0, 0);
  in.vsg = select(pred.vsg, 0, 0);
  in.grid = grid;
  in.objects.push_back(place_object(make_box({-0.8f, 0.0f, -0.8f}, {0.8f, 1.4f, 0.8f}), Placement{.x_m = 0.0, .z_m = -6.0},
                                    view.camera, view.depth));
  InsertionOptions io;
  io.aa_samples = 1;
  io.light_samples = 8;
  io.shadow_width = 16;
  io.shadow_height = 8;
  io.shadow_rays = 8;
  io.query.samples = 8;
  const InsertionResult r = insert_objects(in, io);
  ASSERT_GT(sum(r.object_mask).item(), 0.0) << "the object must be visible";
  const Tensor adv = generator_adversarial(disc.forward(unsqueeze(ldr_from_hdr(r.composite), 0)));
  backward(adv);

  EXPECT_GT(grad_abs_sum(predictor, "backbone.conv1.weight"), 0.0);
  EXPECT_GT(grad_abs_sum(predictor, "sky_head."), 0.0);      // sky head, through the frozen decoder
  EXPECT_GT(grad_abs_sum(predictor, "volume_unet."), 0.0);  // volume head, through Eq. 1
  EXPECT_GT(grad_abs_sum(predictor, "volume_mlp."), 0.0);
  EXPECT_EQ(grad_abs_sum(predictor, "sky_decoder."), 0.0);  // frozen: nothing accumulates
  for (const auto& [n, t] : predictor.named_parameters())
    if (t.grad().defined())
      for (double v : t.grad().to_vector()) ASSERT_TRUE(std::isfinite(v)) << n;
}

TEST(AdversarialStage, StepsRunAndTheDiscriminatorLearns) {
  const fs::path dir = fs::path(STREETLIGHT_BINARY_DIR) / "test_tmp" / "train" / "adversarial_stage";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string glb = (dir / "box.glb").string();
  write_glb(make_box({-0.8f, 0.0f, -0.8f}, {0.8f, 1.4f, 0.8f}), glb);

  nlohmann::json c = default_train_config();
  c["stage"] = kStageAdversarial;
  sl::test::apply_tiny_model(c);
  c["model"]["discriminator"] = {{"base_channels", 4}, {"layers", 2}, {"norm", "none"}};
  c["data"]["pano_rays"] = 32;
  c["data"]["view_rays"] = 32;
  c["data"]["dataset"] = "in-memory";
  c["insertion"]["light_samples"] = 4;
  c["insertion"]["shadow_width"] = 16;
  c["insertion"]["shadow_height"] = 8;
  c["insertion"]["shadow_rays"] = 4;
  c["train"]["batch_size"] = 1;
  c["optim"]["discriminator_lr"] = 1e-2;
  c["optim"]["lr"] = 1e-3;
  auto make = [&](size_t i, uint64_t) {
    StreetSample s = test::tiny_street_sample(i + 1, 64, 32);
    s.has_insertion = true;
    s.object_glb = glb;
    s.object_x = 0.0;
    s.object_z = -6.0;
    s.insert_with_object_hdr = pow_scalar(s.views[0].ldr, 2.2);
    return s;
  };
  AdversarialStage stage(c, SampleSource{1, make}, SampleSource{1, make});
  double first = 0, last = 0;
  for (int k = 0; k < 20; ++k) {
    stage.set_lr(1e-3);
    const Metrics m = stage.step(0);
    ASSERT_TRUE(std::isfinite(m.at("adversarial")));
    if (k == 0) first = m.at("d_loss");
    last = m.at("d_loss");
  }
  EXPECT_LT(last, first) << first << " -> " << last;  // D separates real from fake on one batch
}

}  // namespace
}  // namespace sl::train
