// Shape and gradient-flow tests of the two-branch lighting predictor (Sec 3.2, Fig. 2a) in each
// ablation variant.
#include "train/lighting_predictor.h"

#include <gtest/gtest.h>

#include "autodiff/ops.h"
#include "nn/modules/resnet.h"
#include "support/test_util.h"
#include "support/tiny_model.h"
#include "util/error.h"

namespace sl::test {
using train::LightingPrediction;
using train::LightingPredictor;

namespace {

TEST(LightingPredictor, FullModelGradientsFlowThroughFrozenDecoderIntoBackbone) {
  LightingPredictor p(tiny_predictor_options("sky_decoder", true));
  const Tensor image = Tensor::uniform({2, 3, 32, 64}, 0.0, 1.0, 1);
  const Tensor rgba = Tensor::uniform({2, 4, 8, 8, 4}, 0.0, 1.0, 2);
  const LightingPrediction out = p.predict(image, rgba);
  EXPECT_EQ(out.env.shape(), (Shape{2, 3, 8, 32}));
  EXPECT_EQ(out.vsg.shape(), (Shape{2, 8, 8, 8, 4}));
  EXPECT_EQ(out.code.latent.shape(), (Shape{2, 6}));
  // A loss on the sky alone must reach the first convolution through the frozen decoder.
  backward(mean(out.log_env));
  EXPECT_GT(abs_sum(grad_of(p.backbone(), "conv1.weight")), 0.0);
  for (const auto& [name, t] : p.sky_decoder()->named_parameters()) {
    EXPECT_FALSE(t.requires_grad()) << name;
    EXPECT_FALSE(t.grad().defined()) << name;
  }
}

TEST(LightingPredictor, AblationVariantsHaveTheirShapes) {
  for (const std::string branch : {"direct", "constant"}) {
    LightingPredictor p(tiny_predictor_options(branch, true));
    const LightingPrediction out = p.predict(Tensor::uniform({1, 3, 32, 64}, 0, 1, 1), Tensor::zeros({1, 4, 8, 8, 4}));
    EXPECT_EQ(out.env.shape(), (Shape{1, 3, 8, 32})) << branch;
    EXPECT_FALSE(out.code.dir.defined()) << branch;
    backward(add(mean(out.log_env), mean(out.vsg)));
    EXPECT_GT(abs_sum(p.backbone().named_parameters().front().second.grad()), 0.0) << branch;
  }
  LightingPredictor sky_only(tiny_predictor_options("sky_decoder", false));
  const LightingPrediction out = sky_only.predict(Tensor::uniform({1, 3, 32, 64}, 0, 1, 1), Tensor());
  EXPECT_FALSE(out.vsg.defined());
  EXPECT_THROW(LightingPredictor(tiny_predictor_options("nonsense", true)), Error);
}

TEST(LightingPredictor, GridHeadSeesTheBackbonesLastMapAndPassesGradientsThroughIt) {
  // The stride-32 size rule is the backbone's own, odd sizes included.
  for (const auto& [h, w] : {std::pair<int64_t, int64_t>{32, 64}, {128, 256}, {97, 161}}) {
    nn::ResNet r(nn::ResNetOptions{.base_width = 4});
    const Tensor last = r.forward_features(Tensor::uniform({1, 3, h, w}, 0, 1, 3)).features.back();
    const auto hw = train::backbone_grid_size(h, w);
    EXPECT_EQ(last.size(2), hw[0]) << h << "x" << w;
    EXPECT_EQ(last.size(3), hw[1]) << h << "x" << w;
  }
  train::LightingPredictorOptions o = tiny_predictor_options("sky_decoder", true);
  o.head_grid_channels = 3;
  LightingPredictor p(o);
  // 32×64 input → a 1×2 map: the heads read 8·4 pooled + 3·1·2 grid features.
  int found = 0;
  for (const auto& [name, t] : p.named_parameters()) {
    if (name == "head_grid.weight") {
      EXPECT_EQ(t.shape(), (Shape{3, 32, 1, 1}));
      ++found;
    }
    if (name == "sky_head.net.0.weight" || name == "volume_mlp.net.0.weight") {
      EXPECT_EQ(t.size(1), 32 + 3 * 2) << name;
      ++found;
    }
  }
  EXPECT_EQ(found, 3);
  const LightingPrediction out =
      p.predict(Tensor::uniform({2, 3, 32, 64}, 0.0, 1.0, 1), Tensor::uniform({2, 4, 8, 8, 4}, 0.0, 1.0, 2));
  backward(add(mean(out.log_env), mean(out.vsg)));
  EXPECT_GT(abs_sum(grad_of(p, "head_grid.weight")), 0.0);
  EXPECT_GT(abs_sum(grad_of(p.backbone(), "conv1.weight")), 0.0);
  o.head_grid_channels = -1;
  EXPECT_THROW(LightingPredictor{o}, Error);
}

}  // namespace
}  // namespace sl::test
