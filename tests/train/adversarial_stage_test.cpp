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

using sl::data::StreetSample;
using sl::data::StreetView;
using sl::render::insert_objects;
using sl::render::InsertionInputs;
using sl::render::InsertionOptions;
using sl::render::InsertionResult;
using sl::render::make_box;
using sl::render::place_object;
using sl::render::Placement;
using sl::render::VsgGrid;
using sl::render::write_glb;

namespace sl::test {
using train::AdversarialStage;
using train::LightingPrediction;
using train::LightingPredictor;
using train::LightingPredictorOptions;
using train::LightingStage;
using train::Metrics;
using train::SampleSource;
using train::SkyAutoencoderOptions;
using train::default_train_config;
using train::discriminator_hinge;
using train::generator_adversarial;
using train::kStageAdversarial;
using train::ldr_from_hdr;
using train::unproject_rgba;

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
    if (t.grad().defined()) {
      for (double v : t.grad().to_vector()) ASSERT_TRUE(std::isfinite(v)) << n;
    }
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
  // 3e-3: at 1e-2 Adam's first steps throw D past the hinge margin and d_loss oscillates
  // (2.00 -> 2.83 -> 1.99 ... 2.80 -> 1.98), so last < first held or failed by the build's
  // rounding; from 2e-3 to 4e-3 it falls steadily (2.00 -> 1.65 at 3e-3).
  c["optim"]["discriminator_lr"] = 3e-3;
  c["optim"]["lr"] = 1e-3;
  c["insertion"]["real"] = "path_traced";  // the fixture's truth lacks the object: a separable pair
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

// "Real and fake differ only in lighting" (insertion.real = "renderer"): a discriminator trained
// for a fixed budget on real composites against composites of the fake path under the TRUE
// lighting stays at chance on held-out pairs — nothing but the lighting tells them apart. With
// the path-traced reals of before (here the fixture's truth image, as different from the renderer
// as a path tracer is), the same budget separates them.
TEST(AdversarialStage, UnderTrueLightingTheDiscriminatorStaysAtChance) {
  const fs::path dir = fs::path(STREETLIGHT_BINARY_DIR) / "test_tmp" / "train" / "adversarial_chance";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string glb = (dir / "box.glb").string();
  write_glb(make_box({-1.5f, 0.0f, -1.5f}, {1.5f, 2.0f, 1.5f}), glb);
  auto config = [&](const std::string& real) {
    nlohmann::json c = default_train_config();
    c["stage"] = kStageAdversarial;
    sl::test::apply_tiny_model(c);
    c["model"]["discriminator"] = {{"base_channels", 4}, {"layers", 2}, {"norm", "none"}};
    c["data"]["pano_rays"] = 8;
    c["data"]["view_rays"] = 8;
    c["data"]["dataset"] = "in-memory";
    c["insertion"]["light_samples"] = 2;
    c["insertion"]["shadow_width"] = 16;
    c["insertion"]["shadow_height"] = 8;
    c["insertion"]["shadow_rays"] = 4;
    c["insertion"]["real"] = real;
    c["train"]["batch_size"] = 1;
    return c;
  };
  constexpr size_t kScenes = 24;
  auto make = [&](size_t i, uint64_t) {
    StreetSample s = test::tiny_street_sample(i + 1, 64, 32);
    s.has_insertion = true;
    s.object_glb = glb;
    s.object_x = 0.2 * double(i % 5) - 0.4;
    s.object_z = -5.0 - 0.5 * double(i % 3);
    s.object_yaw_deg = 17.0 * double(i);
    s.insert_with_object_hdr = pow_scalar(s.views[0].ldr, 2.2);  // the "path-traced" truth of the fixture
    return s;
  };
  // Pairs (real, fake under the true light) of scene i with per-pair sample seeds.
  auto pairs = [&](const std::string& real, uint64_t first_seed, size_t count) {
    AdversarialStage stage(config(real), SampleSource{kScenes, make}, SampleSource{kScenes, make});
    std::vector<LightingStage::Forward> scenes;
    for (size_t i = 0; i < kScenes; ++i) scenes.push_back(stage.forward_val(i));
    std::vector<std::pair<Tensor, Tensor>> out;
    for (size_t k = 0; k < count; ++k) {
      const LightingStage::Forward& f = scenes[k % kScenes];
      NoGradGuard ng;
      const uint64_t seed = first_seed + 2 * k;
      out.push_back({stage.real_composite_ldr(f, 0, seed),
                     ldr_from_hdr(stage.composite_under(f, 0, stage.ground_truth_env(f, 0), Tensor(), seed + 1))});
    }
    return out;
  };
  auto held_out_accuracy = [&](const std::string& real) {
    // 480 held-out pairs (960 decisions): at chance the accuracy's standard deviation is 0.016, so
    // the ±0.05 band is 3σ (with 120 pairs it was 1.5σ, and a chance-level D failed it 1 run in 8).
    const auto train = pairs(real, 1000, 32), test = pairs(real, 5000, 480);
    nn::PatchDiscriminator d({.base_channels = 8, .layers = 2, .norm = "none", .seed = 3});
    d.init_parameters(3);
    nn::AdamW opt(d.named_parameters(), {.lr = 2e-3});
    for (int step = 0; step < 200; ++step) {
      TensorList r, f;
      for (int b = 0; b < 8; ++b) {
        const auto& p = train[(size_t(step) * 8 + size_t(b)) % train.size()];
        r.push_back(p.first), f.push_back(p.second);
      }
      opt.zero_grad();
      const Tensor hl = discriminator_hinge(d.forward(stack(r, 0)), d.forward(stack(f, 0)));
      backward(hl);
      opt.step();
    }
    NoGradGuard ng;
    int correct = 0;
    for (const auto& [r, f] : test) {
      correct += mean(d.forward(unsqueeze(r, 0))).item() > 0;
      correct += mean(d.forward(unsqueeze(f, 0))).item() <= 0;
    }
    return double(correct) / double(2 * test.size());
  };
  const double same_renderer = held_out_accuracy("renderer");
  std::fprintf(stderr, "held-out accuracy: same renderer %.3f\n", same_renderer);
  EXPECT_NEAR(same_renderer, 0.5, 0.05) << "real and fake must differ only in lighting";
  const double path_traced = held_out_accuracy("path_traced");
  std::fprintf(stderr, "held-out accuracy: path-traced reals %.3f\n", path_traced);
  EXPECT_GT(path_traced, 0.75) << "the path-traced reals are told apart by the renderer alone";
}

}  // namespace
}  // namespace sl::test
