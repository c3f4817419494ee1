// The learned sun-glare detector's pieces (train/sun_glare.h): its input, its target, its readout
// and the shapes and finiteness of its forward pass. Its accuracy is measured by
// `streetlight-bench sun-glare` on the validation split, not here.
#include "train/sun_glare.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "autodiff/ops.h"
#include "nn/checkpoint.h"
#include "nn/optim.h"
#include "support/test_files.h"
#include "train/sun_distribution.h"

namespace sl::test {
namespace {

using train::kGlareCols;
using train::kGlareOutputs;
using train::kGlareRows;

TEST(SunGlare, InputIsTheResampledImageAndItsClippedShare) {
  // A 128×256 grey image with a clipped 8×8 square at rows 16-23, columns 64-71.
  Tensor ldr = Tensor::full({3, 128, 256}, 0.25);
  float* p = ldr.data<float>();
  for (int ch = 0; ch < 3; ++ch)
    for (int r = 16; r < 24; ++r)
      for (int c = 64; c < 72; ++c) p[(ch * 128 + r) * 256 + c] = 1.0f;
  p[5] = std::numeric_limits<float>::quiet_NaN();  // read as 0
  const Tensor x = train::glare_input(ldr);
  ASSERT_EQ(x.shape(), (Shape{4, 64, 128}));
  const float* q = x.data<float>();
  auto at = [&](int ch, int r, int c) { return q[(ch * 64 + r) * 128 + c]; };
  EXPECT_NEAR(at(0, 40, 100), 0.25 - 0.5, 1e-6);
  EXPECT_NEAR(at(1, 10, 34), 1.0 - 0.5, 1e-6);  // inside the square (rows 8-11, cols 32-35 at half size)
  EXPECT_NEAR(at(3, 10, 34), 1.0, 1e-6);
  EXPECT_NEAR(at(3, 40, 100), 0.0, 1e-6);
  // The NaN pixel is counted as 0: its neighbourhood is darker than the rest, and finite.
  EXPECT_LT(at(0, 0, 2), 0.25 - 0.5 - 0.01);
  EXPECT_GT(at(0, 0, 2), -0.5);
  for (int64_t i = 0; i < x.numel(); ++i) ASSERT_TRUE(std::isfinite(q[i]));
  EXPECT_THROW(train::glare_input(Tensor::zeros({1, 8, 8})), Error);
}

TEST(SunGlare, TargetIsNoSunOrAGaussianAroundThePixel) {
  const Tensor none = train::glare_target(std::nullopt, 128, 256);
  ASSERT_EQ(none.numel(), kGlareOutputs);
  EXPECT_EQ(none.data<float>()[0], 1.0f);
  EXPECT_NEAR(sum(none).item(), 1.0, 1e-6);

  // The sun at the centre of cell (5, 20): pixel (20.5·8, 5.5·8) of a 128×256 image.
  const Tensor t = train::glare_target(glm::dvec2(20.5 * 8, 5.5 * 8), 128, 256);
  const float* p = t.data<float>();
  EXPECT_EQ(p[0], 0.0f);
  EXPECT_NEAR(sum(t).item(), 1.0, 1e-6);
  int best = 1;
  for (int k = 2; k < kGlareOutputs; ++k)
    if (p[k] > p[best]) best = k;
  EXPECT_EQ(best, 1 + 5 * kGlareCols + 20);
  EXPECT_NEAR(p[1 + 5 * kGlareCols + 21], p[1 + 5 * kGlareCols + 19], 1e-7);  // symmetric
}

TEST(SunGlare, ReadoutIsAtTheLargerPeakAndItsProbability) {
  // Two separated peaks, the larger at cell (3, 4), the smaller at (12, 28); "no sun" small.
  std::vector<double> l(kGlareOutputs, -30.0);
  l[0] = std::log(0.1);
  l[1 + 3 * kGlareCols + 4] = std::log(0.5);
  l[1 + 12 * kGlareCols + 28] = std::log(0.4);
  const train::GlareReading g = train::read_glare(Tensor::from_vector(l, {kGlareOutputs}), 128, 256);
  EXPECT_NEAR(g.p_sun, 0.9, 1e-8);
  EXPECT_NEAR(g.pixel.x, 4.5 * 8, 1e-6);
  EXPECT_NEAR(g.pixel.y, 3.5 * 8, 1e-6);

  // Mass split evenly between two neighbouring cells reads between them.
  std::vector<double> m(kGlareOutputs, -30.0);
  m[1 + 7 * kGlareCols + 10] = 0.0;
  m[1 + 7 * kGlareCols + 11] = 0.0;
  const train::GlareReading h = train::read_glare(Tensor::from_vector(m, {kGlareOutputs}), 64, 128);
  EXPECT_NEAR(h.pixel.x, 11.0 * 4, 1e-6);
  EXPECT_NEAR(h.pixel.y, 7.5 * 4, 1e-6);
  EXPECT_NEAR(h.p_sun, 1.0, 1e-9);

  // Non-finite logits are ignored; all of them non-finite reads "no sun".
  m[0] = std::numeric_limits<double>::quiet_NaN();
  m[5] = std::numeric_limits<double>::infinity();
  EXPECT_TRUE(std::isfinite(train::read_glare(Tensor::from_vector(m, {kGlareOutputs}), 64, 128).p_sun));
  const std::vector<double> bad(kGlareOutputs, std::numeric_limits<double>::quiet_NaN());
  EXPECT_EQ(train::read_glare(Tensor::from_vector(bad, {kGlareOutputs}), 64, 128).p_sun, 0.0);
  EXPECT_THROW(train::read_glare(Tensor::zeros({7}), 64, 128), Error);
}

TEST(SunGlare, ForwardGivesFiniteLogitsAndLearnsABlob) {
  train::SunGlareDetector net({.width = 4, .seed = 3});
  // Two images: a clipped blob at cell (4, 8), and the same sky without it.
  auto image = [](bool blob) {
    Tensor ldr = Tensor::full({3, 128, 256}, 0.4);
    float* p = ldr.data<float>();
    if (blob)
      for (int ch = 0; ch < 3; ++ch)
        for (int r = 32; r < 40; ++r)
          for (int c = 64; c < 72; ++c) p[(ch * 128 + r) * 256 + c] = 1.0f;
    return train::glare_input(ldr);
  };
  const Tensor x = stack({image(true), image(false)}, 0);
  const Tensor t = stack({train::glare_target(glm::dvec2(68.0, 36.0), 128, 256), train::glare_target(std::nullopt, 128, 256)}, 0);
  const Tensor w = Tensor::from_vector({1.0, 1.0}, {2});
  nn::Adam opt(net.named_parameters(), {.lr = 3e-3});
  double first = 0.0, last = 0.0;
  for (int step = 0; step < 150; ++step) {
    const Tensor logits = net.forward(x);
    ASSERT_EQ(logits.shape(), (Shape{2, kGlareOutputs}));
    const Tensor loss = train::sun_distribution_loss(logits, t, w);
    ASSERT_TRUE(std::isfinite(loss.item()));
    (step == 0 ? first : last) = loss.item();
    opt.zero_grad();
    backward(loss);
    opt.step();
  }
  EXPECT_LT(last, 0.5 * first);
  NoGradGuard ng;
  const Tensor logits = net.forward(x);
  const train::GlareReading yes = train::read_glare(select(logits, 0, 0), 128, 256);
  const train::GlareReading no = train::read_glare(select(logits, 0, 1), 128, 256);
  EXPECT_GT(yes.p_sun, 0.5);
  EXPECT_LT(no.p_sun, 0.5);
  EXPECT_NEAR(yes.pixel.x, 68.0, 8.0);
  EXPECT_NEAR(yes.pixel.y, 36.0, 8.0);
  EXPECT_THROW(net.forward(Tensor::zeros({1, 3, 64, 128})), Error);
}

// The azimuth head (front and back): its target peaks at the sun's sector, wraps around at ±180°
// and sums to 1; the mirror image reverses the sectors; the head learns which side is bright.
TEST(SunGlare, TheAzimuthTargetPeaksAtTheSunsSectorAndWraps) {
  const std::vector<double> t = train::azimuth_target(8, 0.1, 20.0);
  ASSERT_EQ(t.size(), 8u);
  double total = 0.0;
  for (const double v : t) total += v;
  EXPECT_NEAR(total, 1.0, 1e-12);
  EXPECT_EQ(std::max_element(t.begin(), t.end()) - t.begin(), 4);  // sector 4 spans [0°, 45°)
  // Just beside ±180°: sectors 0 and 7 hold nearly all of it, and the same for either sign.
  const std::vector<double> a = train::azimuth_target(8, M_PI - 0.01, 20.0), b = train::azimuth_target(8, -M_PI + 0.01, 20.0);
  EXPECT_GT(a[0] + a[7], 0.95);
  for (size_t j = 0; j < 8; ++j) EXPECT_NEAR(a[j], b[7 - j], 1e-12);
  EXPECT_EQ(train::mirror_sectors({1.0, 2.0, 3.0}), (std::vector<double>{3.0, 2.0, 1.0}));
  // Narrower than a sector: one-hot at the sector that holds it.
  const std::vector<double> one = train::azimuth_target(8, -3.0, 1e-3);
  EXPECT_EQ(one[0], 1.0);
  EXPECT_THROW(train::azimuth_target(0, 0.0, 20.0), Error);
  EXPECT_THROW(train::azimuth_target(8, std::nan(""), 20.0), Error);
  EXPECT_THROW(train::azimuth_target(8, 0.0, 0.0), Error);
}

TEST(SunGlare, TheAzimuthHeadLearnsWhichSideIsBright) {
  train::SunGlareDetector net({.width = 4, .azimuth_bins = 4, .seed = 5});
  ASSERT_TRUE(net.has_azimuth());
  // A sky brighter on the left (the sun to the left, sector 1 of 4: [−90°, 0°)) and on the right
  // (sector 2), no glare in view.
  auto image = [](bool left) {
    Tensor ldr = Tensor::full({3, 128, 256}, 0.3);
    float* p = ldr.data<float>();
    for (int ch = 0; ch < 3; ++ch)
      for (int r = 0; r < 128; ++r)
        for (int c = 0; c < 128; ++c) p[(ch * 128 + r) * 256 + (left ? c : 128 + c)] = 0.8f;
    return train::glare_input(ldr);
  };
  const Tensor x = stack({image(true), image(false)}, 0);
  const Tensor glare = stack({train::glare_target(std::nullopt, 128, 256), train::glare_target(std::nullopt, 128, 256)}, 0);
  const Tensor az = stack({Tensor::from_vector(train::azimuth_target(4, -0.25 * M_PI, 20.0), {4}).to(DType::F32),
                           Tensor::from_vector(train::azimuth_target(4, 0.25 * M_PI, 20.0), {4}).to(DType::F32)},
                          0);
  const Tensor w = Tensor::from_vector({1.0, 1.0}, {2});
  nn::Adam opt(net.named_parameters(), {.lr = 1e-3});
  for (int step = 0; step < 60; ++step) {
    const train::GlareHeads h = net.forward_heads(x);
    ASSERT_EQ(h.azimuth.shape(), (Shape{2, 4}));
    const Tensor loss = add(train::sun_distribution_loss(h.glare, glare, w), train::sun_distribution_loss(h.azimuth, az, w));
    ASSERT_TRUE(std::isfinite(loss.item()));
    opt.zero_grad();
    backward(loss);
    opt.step();
  }
  NoGradGuard ng;
  const train::GlareHeads h = net.forward_heads(x);
  const train::GlareReading left = train::read_glare(select(h.glare, 0, 0), 128, 256, select(h.azimuth, 0, 0));
  const train::GlareReading right = train::read_glare(select(h.glare, 0, 1), 128, 256, select(h.azimuth, 0, 1));
  ASSERT_EQ(left.azimuth.size(), 4u);
  EXPECT_NEAR(left.azimuth[0] + left.azimuth[1] + left.azimuth[2] + left.azimuth[3], 1.0, 1e-12);
  EXPECT_GT(left.azimuth[1], 0.5);
  EXPECT_GT(right.azimuth[2], 0.5);
  // Without the head the reading has no azimuth, and forward() is the glare logits alone.
  EXPECT_TRUE(train::read_glare(select(h.glare, 0, 0), 128, 256).azimuth.empty());
  EXPECT_EQ(max(abs(sub(net.forward(x), h.glare))).item(), 0.0);
}

// azimuth_features is what the azimuth head reads: its two layers applied to it by hand give the
// head's logits, image by image; a detector without the head refuses.
TEST(SunGlare, TheAzimuthFeaturesAreTheAzimuthHeadsInput) {
  train::SunGlareDetector net({.width = 3, .azimuth_bins = 8, .seed = 4});
  const Tensor x = Tensor::uniform({2, 4, train::kGlareInputHeight, train::kGlareInputWidth}, -0.5, 0.5, 9);
  NoGradGuard ng;
  const Tensor f = net.azimuth_features(x);
  ASSERT_EQ(f.shape(), (Shape{2, 2 * 3 * 32}));
  Tensor w1, b1, w2, b2;
  for (const auto& [name, p] : net.named_parameters()) {
    if (name == "azimuth.0.weight") w1 = p;
    if (name == "azimuth.0.bias") b1 = p;
    if (name == "azimuth.2.weight") w2 = p;
    if (name == "azimuth.2.bias") b2 = p;
  }
  ASSERT_TRUE(w1.defined() && b1.defined() && w2.defined() && b2.defined());
  const Tensor hidden = relu(add(matmul(f, transpose(w1, 0, 1)), b1));
  const Tensor by_hand = add(matmul(hidden, transpose(w2, 0, 1)), b2);
  EXPECT_LT(max(abs(sub(by_hand, net.forward_heads(x).azimuth))).item(), 1e-5);
  // azimuth_hidden is that head's hidden layer after its ReLU (how many units are alive).
  const Tensor h = net.azimuth_hidden(x);
  ASSERT_EQ(h.shape(), (Shape{2, 64}));
  EXPECT_LT(max(abs(sub(h, hidden))).item(), 1e-6);
  EXPECT_GE(min(h).item(), 0.0);
  const Tensor one = net.azimuth_features(slice(x, 0, 1, 2));
  EXPECT_LT(max(abs(sub(one, slice(f, 0, 1, 2)))).item(), 1e-6);
  train::SunGlareDetector without({.width = 3, .seed = 4});
  EXPECT_THROW(without.azimuth_features(x), Error);
  EXPECT_THROW(without.azimuth_hidden(x), Error);
  // With a leaky head (azimuth_slope s) a negative pre-activation p gives s·p, not 0.
  train::SunGlareDetector leaky({.width = 3, .azimuth_bins = 8, .azimuth_slope = 0.25, .seed = 4});
  Tensor lw1, lb1;
  for (const auto& [name, p] : leaky.named_parameters()) {
    if (name == "azimuth.0.weight") lw1 = p;
    if (name == "azimuth.0.bias") lb1 = p;
  }
  const Tensor pre = add(matmul(leaky.azimuth_features(x), transpose(lw1, 0, 1)), lb1);
  const Tensor want = add(relu(pre), mul_scalar(neg(relu(neg(pre))), 0.25));
  EXPECT_LT(max(abs(sub(leaky.azimuth_hidden(x), want))).item(), 1e-6);
  EXPECT_LT(min(leaky.azimuth_hidden(x)).item(), 0.0);
  EXPECT_THROW(train::SunGlareDetector({.width = 3, .azimuth_bins = 8, .azimuth_slope = 1.0}), Error);
}

// The glare map as a likelihood ratio over the sun head's grid: a map with half its mass on one
// cell above the horizon raises the sun-grid cell its centre ray falls in, and only cells in view;
// a map sure of no sun in view lowers every cell in view and leaves the rest at 1.
TEST(SunGlare, TheGlareMapFavoursTheSkyCellsWhereItSeesTheSun) {
  const train::SunGrid grid{8, 32};
  const render::Camera cam(render::intrinsics_from_fov(1.2, 256, 128), render::rotation_from_yaw_pitch_roll(0.0, 0.0, 0.0),
                           {0.0, 1.6, 0.0});
  std::vector<double> cells(kGlareOutputs, 0.0);
  const int r = 3, c = 24;  // above the horizon (row 8 of 16 for a level camera), right of centre
  cells[0] = 0.5;
  cells[size_t(1 + r * kGlareCols + c)] = 0.5;
  const std::vector<double> f = train::glare_sky_factor(grid, cam, cells);
  ASSERT_EQ(f.size(), size_t(grid.cells()));
  const glm::dvec3 ray = cam.ray((c + 0.5) / kGlareCols * 256, (r + 0.5) / kGlareRows * 128).direction;
  const int64_t hit = train::cell_of_direction(grid, ray);
  ASSERT_GE(hit, 0);
  EXPECT_EQ(std::max_element(f.begin(), f.end()) - f.begin(), hit);
  // Its value: (0.5 / n) / ((1 − π₀) / 512) over (0.5 / π₀), n the glare cells whose rays share it.
  int n = 0, in_view = 0;
  std::vector<bool> seen(f.size(), false);
  for (int rr = 0; rr < kGlareRows; ++rr)
    for (int cc = 0; cc < kGlareCols; ++cc) {
      const int64_t k = train::cell_of_direction(grid, cam.ray((cc + 0.5) / kGlareCols * 256, (rr + 0.5) / kGlareRows * 128).direction);
      if (k < 0) continue;
      n += k == hit;
      if (!seen[size_t(k)]) ++in_view;
      seen[size_t(k)] = true;
    }
  const double pi0 = train::kGlareNoSunPrior;
  EXPECT_NEAR(f[size_t(hit)], (0.5 / n) / ((1.0 - pi0) / 512.0) / (0.5 / pi0), 1e-9);
  int ones = 0, zeros = 0;
  for (size_t k = 0; k < f.size(); ++k) {
    if (k == size_t(hit)) continue;
    if (seen[k]) {
      EXPECT_EQ(f[k], 0.0) << k;
      ++zeros;
    } else {
      EXPECT_EQ(f[k], 1.0) << k;
      ++ones;
    }
  }
  EXPECT_GT(zeros, 10);   // the sky in view
  EXPECT_GT(ones, 100);   // out of view, or behind
  // A map sure there is no sun in view.
  std::vector<double> none(kGlareOutputs, 1e-9);
  none[0] = 1.0;
  const std::vector<double> g = train::glare_sky_factor(grid, cam, none);
  for (size_t k = 0; k < g.size(); ++k) {
    if (seen[k]) EXPECT_LT(g[k], 1e-5) << k;
    else EXPECT_EQ(g[k], 1.0) << k;
  }
  // All finite for a map of zeros, mass at the floor.
  for (const double v : train::glare_sky_factor(grid, cam, std::vector<double>(kGlareOutputs, 0.0))) EXPECT_TRUE(std::isfinite(v));
  // The mirror image of the map: column c ↔ 31 − c, twice the identity.
  const std::vector<double> m = train::mirror_glare_cells(cells);
  EXPECT_EQ(m[0], 0.5);
  EXPECT_EQ(m[size_t(1 + r * kGlareCols + (kGlareCols - 1 - c))], 0.5);
  EXPECT_EQ(train::mirror_glare_cells(m), cells);
  EXPECT_THROW(train::glare_sky_factor(grid, cam, std::vector<double>(5, 0.0)), Error);
  cells[7] = -1.0;
  EXPECT_THROW(train::glare_sky_factor(grid, cam, cells), Error);
  EXPECT_THROW(train::mirror_glare_cells(std::vector<double>(5, 0.0)), Error);
}

TEST(SunGlare, LoadsWhatTheBenchSavedAndRefusesOtherCheckpoints) {
  train::SunGlareDetector net({.width = 3, .seed = 9});
  const std::string good = scratch("glare.safetensors"), other = scratch("not_glare.safetensors");
  nn::save_checkpoint(good, net, nullptr, {.stage = "sun_glare", .step = 1, .config_json = R"({"width": 3})"});
  nn::save_checkpoint(other, net, nullptr, {.stage = "lighting", .step = 1, .config_json = R"({"width": 3})"});
  const auto loaded = train::load_sun_glare(good);
  const Tensor x = Tensor::uniform({1, 4, 64, 128}, -0.5, 0.5, 4);
  NoGradGuard ng;
  EXPECT_EQ(max(abs(sub(loaded->forward(x), net.forward(x)))).item(), 0.0);
  // A detector with an azimuth head loads with it ("azimuth_bins" in its config).
  train::SunGlareDetector with_head({.width = 3, .azimuth_bins = 8, .seed = 2});
  const std::string head = scratch("glare_azimuth.safetensors");
  nn::save_checkpoint(head, with_head, nullptr, {.stage = "sun_glare", .step = 1, .config_json = R"({"width": 3, "azimuth_bins": 8})"});
  const auto loaded_head = train::load_sun_glare(head);
  ASSERT_TRUE(loaded_head->has_azimuth());
  EXPECT_EQ(max(abs(sub(loaded_head->forward_heads(x).azimuth, with_head.forward_heads(x).azimuth))).item(), 0.0);
  EXPECT_FALSE(loaded->has_azimuth());
  // A leaky head loads leaky ("azimuth_slope"): its hidden units' negative parts survive the round trip.
  train::SunGlareDetector leaky({.width = 3, .azimuth_bins = 8, .azimuth_slope = 0.2, .seed = 2});
  const std::string leaky_file = scratch("glare_leaky.safetensors");
  nn::save_checkpoint(leaky_file, leaky, nullptr,
                      {.stage = "sun_glare", .step = 1, .config_json = R"({"width": 3, "azimuth_bins": 8, "azimuth_slope": 0.2})"});
  const auto loaded_leaky = train::load_sun_glare(leaky_file);
  EXPECT_EQ(loaded_leaky->options().azimuth_slope, 0.2);
  EXPECT_EQ(max(abs(sub(loaded_leaky->forward_heads(x).azimuth, leaky.forward_heads(x).azimuth))).item(), 0.0);
  nn::save_checkpoint(leaky_file, leaky, nullptr,
                      {.stage = "sun_glare", .step = 1, .config_json = R"({"width": 3, "azimuth_bins": 8, "azimuth_slope": 1.5})"});
  EXPECT_THROW(train::load_sun_glare(leaky_file), Error);
  try {
    train::load_sun_glare(other);
    ADD_FAILURE() << "expected sl::Error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(other), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace sl::test
