// Layer modules (conv, norm, resampling, dropout) and the blocks built from them.
#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "autodiff/gradcheck.h"
#include "autodiff/ops.h"
#include "nn/functional/conv.h"
#include "nn/layers.h"
#include "nn/modules/mlp.h"
#include "nn/modules/patch_discriminator.h"
#include "nn/modules/resnet.h"
#include "nn/modules/unet.h"

namespace sl::test {
using nn::AvgPool2d;
using nn::AvgPool3d;
using nn::BasicBlock;
using nn::BatchNorm2d;
using nn::BatchNorm3d;
using nn::Conv2d;
using nn::Conv3d;
using nn::Dropout;
using nn::GlobalAvgPool;
using nn::GroupNorm;
using nn::InstanceNorm;
using nn::MLP;
using nn::MaxPool2d;
using nn::MaxPool3d;
using nn::PatchDiscriminator;
using nn::ResNet;
using nn::ResNetOutput;
using nn::StateDict;
using nn::UNet;
using nn::UNet2D;
using nn::UNet3D;
using nn::Upsample;
using nn::conv2d;
using nn::make_norm;

namespace {

std::set<std::string> names_of(const StateDict& s) {
  std::set<std::string> out;
  for (const auto& [n, t] : s) out.insert(n);
  return out;
}

TEST(Conv2d, HoldsTorchLayoutAndMatchesTheFunctionalOp) {
  Conv2d conv(3, 5, 3, {.stride = 2, .padding = 1});
  EXPECT_EQ(conv.parameter("weight").shape(), (Shape{5, 3, 3, 3}));
  EXPECT_EQ(conv.parameter("bias").shape(), (Shape{5}));
  const Tensor x = Tensor::uniform({2, 3, 9, 9}, -1, 1, 4);
  const Tensor y = conv.forward(x);
  EXPECT_EQ(y.shape(), (Shape{2, 5, 5, 5}));
  EXPECT_EQ(y.to_vector(), conv2d(x, conv.parameter("weight"), conv.parameter("bias"), {2, 2}, {1, 1}).to_vector());
  EXPECT_THROW(conv.forward(Tensor::zeros({2, 4, 9, 9})), Error);
  Conv3d c3(2, 4, 3, {.padding = 1, .bias = false});
  EXPECT_FALSE(c3.has_parameter("bias"));
  EXPECT_EQ(c3.forward(Tensor::zeros({1, 2, 4, 4, 4})).shape(), (Shape{1, 4, 4, 4, 4}));
}

TEST(BatchNorm2d, UpdatesRunningStatisticsOnlyInTrainingAndUsesThemInEval) {
  BatchNorm2d bn(2);
  EXPECT_EQ(names_of(bn.state_dict()),
            (std::set<std::string>{"weight", "bias", "running_mean", "running_var", "num_batches_tracked"}));
  const Tensor x = add_scalar(mul_scalar(Tensor::uniform({4, 2, 3, 3}, -1, 1, 2), 3.0), 5.0);
  const Tensor y = bn.forward(x);
  EXPECT_NEAR(mean(y).item(), 0.0, 1e-5);  // batch statistics in training
  EXPECT_EQ(bn.buffer("num_batches_tracked").item(), 1);
  EXPECT_NEAR(bn.buffer("running_mean").at({0}), 0.1 * mean(select(x, 1, 0)).item(), 1e-5);
  bn.eval();
  const std::vector<double> rm = bn.buffer("running_mean").to_vector();
  const Tensor ye = bn.forward(x);
  EXPECT_EQ(bn.buffer("running_mean").to_vector(), rm);
  EXPECT_EQ(bn.buffer("num_batches_tracked").item(), 1);
  const double expect = (x.at({0, 0, 0, 0}) - rm[0]) / std::sqrt(bn.buffer("running_var").at({0}) + 1e-5);
  EXPECT_NEAR(ye.at({0, 0, 0, 0}), expect, 1e-4);
  EXPECT_THROW(bn.forward(Tensor::zeros({4, 2, 3})), Error);
  EXPECT_THROW(BatchNorm3d(2).forward(Tensor::zeros({1, 2, 2, 2})), Error);
}

TEST(Norms, FactoryBuildsEachKindAndPicksADividingGroupCount) {
  EXPECT_EQ(make_norm("batch", 6, 3)->type_name(), "BatchNorm3d");
  EXPECT_EQ(make_norm("instance", 6, 2)->type_name(), "InstanceNorm");
  EXPECT_EQ(make_norm("none", 6, 2)->type_name(), "Identity");
  auto g = make_norm("group", 6, 2, 4);  // 4 does not divide 6: 3 groups
  const Tensor y = g->forward(Tensor::uniform({2, 6, 3, 3}, -1, 1, 1));
  EXPECT_EQ(y.shape(), (Shape{2, 6, 3, 3}));
  EXPECT_THROW(make_norm("layer", 6, 2), Error);
  EXPECT_THROW(GroupNorm(4, 6), Error);
  InstanceNorm in(3);
  EXPECT_TRUE(in.state_dict().empty());
  EXPECT_EQ(in.forward(Tensor::uniform({1, 3, 4, 4, 4}, -1, 1, 2)).shape(), (Shape{1, 3, 4, 4, 4}));
}

TEST(Dropout, SameSeedReplaysMasksEachStepDiffersAndEvalIsIdentity) {
  const Tensor x = Tensor::ones({1000});
  Dropout a(0.5, 7), b(0.5, 7);
  const auto a0 = a.forward(x).to_vector(), b0 = b.forward(x).to_vector(), a1 = a.forward(x).to_vector();
  EXPECT_EQ(a0, b0);
  EXPECT_NE(a0, a1);
  EXPECT_EQ(a.step(), 2u);
  int kept = 0;
  for (double v : a0) {
    EXPECT_TRUE(v == 0.0 || v == 2.0);
    kept += v != 0.0;
  }
  EXPECT_NEAR(kept, 500, 60);
  a.eval();
  EXPECT_TRUE(a.forward(x).same(x));
  EXPECT_THROW(Dropout(1.0), Error);
}

TEST(Resampling, UpsampleAndPoolsMapShapesForImagesAndVolumes) {
  const Tensor img = Tensor::uniform({1, 2, 4, 6}, -1, 1, 1);
  const Tensor vol = Tensor::uniform({1, 2, 4, 4, 6}, -1, 1, 2);
  EXPECT_EQ(Upsample(2).forward(img).shape(), (Shape{1, 2, 8, 12}));
  EXPECT_EQ(Upsample(2, "linear").forward(vol).shape(), (Shape{1, 2, 8, 8, 12}));
  EXPECT_EQ(MaxPool2d(2).forward(img).shape(), (Shape{1, 2, 2, 3}));
  EXPECT_EQ(AvgPool2d(3, 1, 1).forward(img).shape(), (Shape{1, 2, 4, 6}));
  EXPECT_EQ(MaxPool3d(2).forward(vol).shape(), (Shape{1, 2, 2, 2, 3}));
  EXPECT_EQ(AvgPool3d(2).forward(vol).shape(), (Shape{1, 2, 2, 2, 3}));
  EXPECT_EQ(GlobalAvgPool().forward(vol).shape(), (Shape{1, 2}));
  EXPECT_THROW(Upsample(2, "cubic"), Error);
  EXPECT_THROW(Upsample(2).forward(Tensor::zeros({2, 3})), Error);
  EXPECT_THROW(MaxPool2d(2).forward(vol), Error);
}

TEST(MLP, BatchNormVariantFlattensLeadingDims) {
  MLP mlp({.widths = {3, 8, 2}, .norm = "batch", .seed = 1});
  EXPECT_TRUE(mlp.state_dict().count("net.1.running_var"));
  EXPECT_EQ(mlp.forward(Tensor::uniform({4, 5, 3}, -1, 1, 2)).shape(), (Shape{4, 5, 2}));
}

// ---------------------------------------------------------------- ResNet
TEST(ResNet, Resnet18HasTorchvisionNamesAndParameterCount) {
  ResNet net({.depth = 18, .num_classes = 1000});
  // torchvision.models.resnet18(): 11,689,512 parameters, 122 state-dict entries.
  EXPECT_EQ(net.parameter_count(), 11689512);
  const StateDict s = net.state_dict();
  EXPECT_EQ(s.size(), 122u);
  for (const char* n : {"conv1.weight", "bn1.weight", "bn1.running_mean", "bn1.num_batches_tracked",
                        "layer1.0.conv1.weight", "layer1.1.bn2.bias", "layer2.0.downsample.0.weight",
                        "layer2.0.downsample.1.running_var", "layer4.1.conv2.weight", "fc.weight", "fc.bias"})
    EXPECT_TRUE(s.count(n)) << n;
  EXPECT_FALSE(s.count("layer1.0.downsample.0.weight"));
  EXPECT_EQ(s.at("layer3.0.conv1.weight").shape(), (Shape{256, 128, 3, 3}));
  // Kaiming normal, fan_out: std = sqrt(2 / (64·7·7)).
  const auto w = s.at("conv1.weight").to_vector();
  double sq = 0;
  for (double v : w) sq += v * v;
  EXPECT_NEAR(std::sqrt(sq / double(w.size())), std::sqrt(2.0 / (64 * 49)), 0.003);
}

TEST(ResNet, Resnet34HasItsStageDepths) {
  ResNet net({.depth = 34, .in_channels = 1, .base_width = 4});
  const StateDict s = net.state_dict();
  EXPECT_TRUE(s.count("layer3.5.conv2.weight"));
  EXPECT_FALSE(s.count("layer3.6.conv2.weight"));
  EXPECT_TRUE(s.count("layer2.3.bn1.weight"));
  EXPECT_TRUE(s.count("layer4.2.bn2.weight"));
  EXPECT_EQ(s.at("conv1.weight").shape(), (Shape{4, 1, 7, 7}));
  EXPECT_THROW(ResNet({.depth = 50}), Error);
}

TEST(ResNet, ReturnsEveryStageAndThePooledVector) {
  ResNet net({.depth = 18, .in_channels = 2, .base_width = 8, .seed = 3});
  const ResNetOutput out = net.forward_features(Tensor::uniform({2, 2, 64, 64}, -1, 1, 1));
  ASSERT_EQ(out.features.size(), 4u);
  EXPECT_EQ(out.features[0].shape(), (Shape{2, 8, 16, 16}));
  EXPECT_EQ(out.features[1].shape(), (Shape{2, 16, 8, 8}));
  EXPECT_EQ(out.features[2].shape(), (Shape{2, 32, 4, 4}));
  EXPECT_EQ(out.features[3].shape(), (Shape{2, 64, 2, 2}));
  EXPECT_EQ(out.pooled.shape(), (Shape{2, 64}));
  net.eval();  // one image with a 1×1 last stage: batch statistics would be undefined
  EXPECT_EQ(net.forward(Tensor::uniform({1, 2, 32, 32}, -1, 1, 2)).shape(), (Shape{1, 64}));
  EXPECT_THROW(net.forward(Tensor::zeros({1, 3, 32, 32})), Error);
}

TEST(ResNet, BasicBlockGradchecksInFloat64) {
  BasicBlock block(2, 3, 2);
  block.to(DType::F64);
  const GradcheckResult r = gradcheck([&](const TensorList& in) { return block.forward(in[0]); },
                                      {Tensor::uniform({2, 2, 4, 4}, -1, 1, 5, DType::F64)});
  EXPECT_TRUE(r.ok) << r.message;
}

// ---------------------------------------------------------------- UNet, discriminator
TEST(UNet, MapsShapesWithNamedLevelsForEveryNorm) {
  for (const char* norm : {"batch", "group", "instance", "none"}) {
    UNet2D net({.in_channels = 3, .out_channels = 2, .base_channels = 4, .depth = 2, .norm = norm});
    EXPECT_EQ(net.forward(Tensor::uniform({2, 3, 8, 12}, -1, 1, 1)).shape(), (Shape{2, 2, 8, 12})) << norm;
  }
  UNet3D net({.in_channels = 2, .out_channels = 8, .base_channels = 4, .depth = 2, .norm = "group",
              .upsample = "linear"});
  EXPECT_EQ(net.forward(Tensor::uniform({1, 2, 4, 8, 4}, -1, 1, 1)).shape(), (Shape{1, 8, 4, 8, 4}));
  const StateDict s = net.state_dict();
  for (const char* n : {"enc.0.conv1.weight", "enc.2.norm2.weight", "dec.0.up.1.weight", "dec.1.block.conv1.weight",
                        "head.weight", "head.bias"})
    EXPECT_TRUE(s.count(n)) << n;
  EXPECT_EQ(s.at("dec.0.block.conv1.weight").shape(), (Shape{8, 16, 3, 3, 3}));  // [up, skip] concatenated
  EXPECT_FALSE(s.count("enc.0.conv1.bias"));  // no bias before a norm
  EXPECT_THROW(net.forward(Tensor::zeros({1, 2, 4, 6, 4})), Error);
}

TEST(UNet, WithoutSkipsTheDecoderSeesOnlyTheUpsampledPath) {
  UNet2D net({.base_channels = 4, .depth = 1, .skip = false});
  EXPECT_EQ(net.state_dict().at("dec.0.block.conv1.weight").shape(), (Shape{4, 4, 3, 3}));
  EXPECT_EQ(net.forward(Tensor::zeros({1, 1, 4, 4})).shape(), (Shape{1, 1, 4, 4}));
}

TEST(UNet, SmallUNet2DGradchecksInFloat64) {
  UNet2D net({.in_channels = 1, .out_channels = 1, .base_channels = 2, .depth = 1, .norm = "group",
              .activation = "tanh"});
  net.to(DType::F64);
  const GradcheckResult r = gradcheck([&](const TensorList& in) { return net.forward(in[0]); },
                                      {Tensor::uniform({1, 1, 4, 4}, -1, 1, 9, DType::F64)});
  EXPECT_TRUE(r.ok) << r.message;
}

TEST(PatchDiscriminator, GivesOneLogitPerPatchWithPix2pixNames) {
  PatchDiscriminator d({.in_channels = 3, .base_channels = 8, .layers = 3});
  EXPECT_EQ(d.forward(Tensor::uniform({2, 3, 64, 64}, -1, 1, 1)).shape(), (Shape{2, 1, 6, 6}));
  const StateDict s = d.state_dict();
  for (const char* n : {"model.0.weight", "model.0.bias", "model.2.weight", "model.3.running_mean",
                        "model.11.weight", "model.11.bias"})
    EXPECT_TRUE(s.count(n)) << n;
  EXPECT_FALSE(s.count("model.2.bias"));
  EXPECT_EQ(s.at("model.11.weight").shape(), (Shape{1, 64, 4, 4}));
  PatchDiscriminator nonorm({.in_channels = 1, .base_channels = 4, .layers = 2, .norm = "none"});
  EXPECT_EQ(nonorm.forward(Tensor::zeros({1, 1, 32, 32})).shape(), (Shape{1, 1, 6, 6}));
}

}  // namespace
}  // namespace sl::test
