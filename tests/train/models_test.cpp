// Shape and gradient-flow tests of the paper's models (Sec 3.2): the sky autoencoder and the
// two-branch lighting predictor in each ablation variant, plus unprojection.
#include <gtest/gtest.h>

#include <cmath>

#include "autodiff/ops.h"
#include "train/lighting_predictor.h"
#include "train/sky_autoencoder.h"
#include "train/unprojection.h"

using sl::render::Camera;
using sl::render::intrinsics_from_fov;
using sl::render::rotation_from_yaw_pitch_roll;
using sl::render::VsgGrid;

namespace sl::train {
namespace {

SkyAutoencoderOptions tiny_sky() {
  return SkyAutoencoderOptions{.height = 8, .width = 32, .code_dim = 12, .base_channels = 4, .hidden = 16, .seed = 3};
}

LightingPredictorOptions tiny_predictor(const std::string& branch, bool volume) {
  LightingPredictorOptions o;
  o.image_height = 32;
  o.image_width = 64;
  o.backbone_width = 4;
  o.head_hidden = 16;
  o.sky_branch = branch;
  o.volume_branch = volume;
  o.vsg_dims = {8, 8, 4};
  o.coarse_scale = 4;
  o.coarse_channels = 2;
  o.unet_channels = 4;
  o.unet_depth = 1;
  o.sky = tiny_sky();
  o.seed = 5;
  return o;
}

double abs_sum(const Tensor& t) {
  double s = 0;
  for (double v : t.to_vector()) s += std::abs(v);
  return s;
}

Tensor grad_of(const nn::Module& m, const std::string& name) {
  for (const auto& [n, t] : m.named_parameters())
    if (n == name) return t.grad().defined() ? t.grad() : Tensor::zeros({1});
  ADD_FAILURE() << "no parameter " << name;
  return Tensor::zeros({1});
}

bool all_finite(const Tensor& t) {
  for (double v : t.to_vector())
    if (!std::isfinite(v)) return false;
  return true;
}

TEST(SkyAutoencoder, ShapesAndGradientsReachEveryParameter) {
  SkyAutoencoder ae(tiny_sky());
  const Tensor ldr = Tensor::uniform({2, 3, 8, 32}, 0.0, 1.0, 7);
  const auto out = ae.run(ldr);
  EXPECT_EQ(out.code.log_intensity.shape(), (Shape{2, 3}));
  EXPECT_EQ(out.code.dir.shape(), (Shape{2, 3}));
  EXPECT_EQ(out.code.latent.shape(), (Shape{2, 6}));
  EXPECT_EQ(out.sky.hdr.shape(), (Shape{2, 3, 8, 32}));
  for (int64_t i = 0; i < 2; ++i) {
    const auto d = select(out.code.dir, 0, i).to_vector();
    EXPECT_NEAR(d[0] * d[0] + d[1] * d[1] + d[2] * d[2], 1.0, 1e-5);
  }
  backward(mean(out.sky.log_hdr));
  for (const auto& [name, p] : ae.named_parameters()) {
    ASSERT_TRUE(p.grad().defined()) << name;
    EXPECT_TRUE(all_finite(p.grad())) << name;
  }
  EXPECT_GT(abs_sum(ae.named_parameters().front().second.grad()), 0.0);
}

// The decoder's explicit sun conditioning (Sec 3.2): f_dir moves the sun, f_intensity brightens it.
TEST(SkyDecoder, EditingDirectionMovesAndIntensityBrightensTheSun) {
  SkyAutoencoder ae(tiny_sky());
  NoGradGuard no_grad;
  auto peak_texel = [&](const Tensor& dir, double log_int) {
    SkyCode c;
    c.log_intensity = Tensor::full({1, 3}, log_int);
    c.dir = dir;
    c.latent = Tensor::zeros({1, 6});
    const Tensor hdr = ae.decoder()->decode(c).hdr;
    const auto v = hdr.to_vector();
    int64_t best = 0;
    for (int64_t i = 0; i < 8 * 32; ++i)
      if (v[i] > v[best]) best = i;
    return std::pair<int64_t, double>(best, v[best]);
  };
  // Sun at azimuth 0 (−Z), 30° elevation, then at azimuth +90° (+X).
  const double c30 = std::cos(0.5236), s30 = std::sin(0.5236);
  const auto a = peak_texel(Tensor::from_vector({0, s30, -c30}, {1, 3}), 8.0);
  const auto b = peak_texel(Tensor::from_vector({c30, s30, 0}, {1, 3}), 8.0);
  const auto bright = peak_texel(Tensor::from_vector({0, s30, -c30}, {1, 3}), 10.0);
  EXPECT_EQ(a.first / 32, b.first / 32);            // same row (elevation)
  EXPECT_EQ(std::abs(b.first % 32 - a.first % 32), 8);  // a quarter turn: 32 / 4 columns
  EXPECT_EQ(bright.first, a.first);
  EXPECT_GT(bright.second, 5.0 * a.second);          // e^2 ≈ 7.4× brighter
}

TEST(SkyCode, ZeroDirectionIsGuarded) {
  const Tensor raw = Tensor::zeros({1, 10}).set_requires_grad(true);
  const SkyCode c = sky_code_from_raw(raw);
  backward(sum(c.dir));
  EXPECT_TRUE(all_finite(c.dir));
  EXPECT_TRUE(all_finite(raw.grad()));
}

TEST(LightingPredictor, FullModelGradientsFlowThroughFrozenDecoderIntoBackbone) {
  LightingPredictor p(tiny_predictor("sky_decoder", true));
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
    LightingPredictor p(tiny_predictor(branch, true));
    const LightingPrediction out = p.predict(Tensor::uniform({1, 3, 32, 64}, 0, 1, 1), Tensor::zeros({1, 4, 8, 8, 4}));
    EXPECT_EQ(out.env.shape(), (Shape{1, 3, 8, 32})) << branch;
    EXPECT_FALSE(out.code.dir.defined()) << branch;
    backward(add(mean(out.log_env), mean(out.vsg)));
    EXPECT_GT(abs_sum(p.backbone().named_parameters().front().second.grad()), 0.0) << branch;
  }
  LightingPredictor sky_only(tiny_predictor("sky_decoder", false));
  const LightingPrediction out = sky_only.predict(Tensor::uniform({1, 3, 32, 64}, 0, 1, 1), Tensor());
  EXPECT_FALSE(out.vsg.defined());
  EXPECT_THROW(LightingPredictor(tiny_predictor("nonsense", true)), Error);
}

TEST(Unprojection, APixelLandsInItsVoxelWithUnitAlpha) {
  const Camera cam(intrinsics_from_fov(1.2, 4, 2), rotation_from_yaw_pitch_roll(0, 0, 0), {0, 1.6, 0});
  VsgGrid grid;
  grid.dims = {8, 8, 4};
  grid.center = {0, 1.6, 0};
  Tensor image = Tensor::zeros({3, 2, 4});
  image.data<float>()[0] = 0.5f;  // red of pixel (0, 0)
  Tensor depth = Tensor::zeros({2, 4});
  depth.data<float>()[0] = 10.0f;  // only pixel (0, 0) has depth
  const Tensor v = unproject_rgba(image, depth, cam, grid);
  ASSERT_EQ(v.shape(), (Shape{4, 8, 8, 4}));
  const glm::dvec3 vox = grid.to_voxel(cam.unproject(0.5, 0.5, 10.0));
  const int64_t ix = static_cast<int64_t>(vox.x), iy = static_cast<int64_t>(vox.y), iz = static_cast<int64_t>(vox.z);
  EXPECT_FLOAT_EQ(v.at({3, ix, iy, iz}), 1.0f);
  EXPECT_FLOAT_EQ(v.at({0, ix, iy, iz}), 0.5f);
  EXPECT_DOUBLE_EQ(sum(select(v, 0, 3)).item(), 1.0);
}

}  // namespace
}  // namespace sl::train
