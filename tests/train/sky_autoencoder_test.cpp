// Shape and gradient-flow tests of the sky autoencoder (Sec 3.2, Fig. 3): the encoder's sky code,
// the decoder's explicit sun conditioning and the guarded direction.
#include "train/sky_autoencoder.h"

#include <gtest/gtest.h>

#include <cmath>

#include "autodiff/ops.h"
#include "support/test_util.h"
#include "support/tiny_model.h"

namespace sl::test {
using train::SkyAutoencoder;
using train::SkyCode;
using train::sky_code_from_raw;

namespace {

TEST(SkyAutoencoder, ShapesAndGradientsReachEveryParameter) {
  SkyAutoencoder ae(tiny_sky_options());
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
  SkyAutoencoder ae(tiny_sky_options());
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

}  // namespace
}  // namespace sl::test
