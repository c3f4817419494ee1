// Learning tests: the pieces together actually learn. Each builds its model only from nn/
// modules and optimisers, makes its own synthetic data from a seed, and takes 1-3 s on one core
// (a few hundred small optimiser steps: that is what "learns" costs, so they exceed 1 s).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "autodiff/ops.h"
#include "nn/layers.h"
#include "nn/modules/resnet.h"
#include "nn/modules/unet.h"
#include "nn/optim.h"
#include "util/math.h"
#include "util/random.h"

namespace sl::test {
using nn::Adam;
using nn::Conv2d;
using nn::ConvOptions;
using nn::Flatten;
using nn::Linear;
using nn::MaxPool2d;
using nn::Module;
using nn::ReLU;
using nn::ResNet;
using nn::Sequential;
using nn::UNet3D;

namespace {

// A batch of 16×16 dark images, each with one bright Gaussian blob at radius 5 px from the
// centre and angle θ ~ U[0, 2π); targets are (cos θ, sin θ) so the task has no wrap-around.
struct BlobBatch {
  Tensor images, targets;
  std::vector<double> angles;
};

BlobBatch make_blobs(int64_t n, uint64_t seed) {
  std::vector<double> img(static_cast<size_t>(n * 256)), tgt(static_cast<size_t>(n * 2));
  BlobBatch b;
  for (int64_t i = 0; i < n; ++i) {
    const double theta = 2 * kPi * uniform01(seed, 0, static_cast<uint64_t>(i));
    b.angles.push_back(theta);
    const double cx = 7.5 + 5.0 * std::cos(theta), cy = 7.5 + 5.0 * std::sin(theta);
    for (int y = 0; y < 16; ++y)
      for (int x = 0; x < 16; ++x) {
        const double d2 = (x - cx) * (x - cx) + (y - cy) * (y - cy);
        img[static_cast<size_t>(i * 256 + y * 16 + x)] = std::exp(-d2 / (2 * 1.5 * 1.5));
      }
    tgt[static_cast<size_t>(2 * i)] = std::cos(theta);
    tgt[static_cast<size_t>(2 * i + 1)] = std::sin(theta);
  }
  b.images = Tensor::from_vector(img, {n, 1, 16, 16});
  b.targets = Tensor::from_vector(tgt, {n, 2});
  return b;
}

// Median angular error (degrees) of the predicted (cos, sin) over a held-out batch.
double median_error_deg(Module& net, const BlobBatch& test) {
  const Tensor pred = net.forward(test.images);
  std::vector<double> errors;
  for (int64_t i = 0; i < pred.size(0); ++i) {
    const double a = std::atan2(pred.at({i, 1}), pred.at({i, 0}));
    const double d = std::fmod(std::abs(a - test.angles[static_cast<size_t>(i)]), 2 * kPi);
    errors.push_back(std::min(d, 2 * kPi - d) * 180 / kPi);
  }
  std::nth_element(errors.begin(), errors.begin() + errors.size() / 2, errors.end());
  return errors[errors.size() / 2];
}

TEST(Learning, SmallCnnLearnsTheAngleOfABlobBelowFiveDegreesMedianError) {
  auto net = std::make_shared<Sequential>(std::vector<std::shared_ptr<Module>>{
      std::make_shared<Conv2d>(1, 8, 3, ConvOptions{.padding = 1}), std::make_shared<ReLU>(),
      std::make_shared<MaxPool2d>(2),
      std::make_shared<Conv2d>(8, 16, 3, ConvOptions{.padding = 1}), std::make_shared<ReLU>(),
      std::make_shared<MaxPool2d>(2), std::make_shared<Flatten>(),
      std::make_shared<Linear>(256, 64), std::make_shared<ReLU>(), std::make_shared<Linear>(64, 2)});
  net->init_parameters(1);
  const BlobBatch test = make_blobs(200, 7);  // a seed no training batch uses
  const double before = median_error_deg(*net, test);
  Adam opt(net->named_parameters(), {.lr = 3e-3});
  for (int step = 0; step < 150; ++step) {  // fresh images every step: no memorising
    const BlobBatch batch = make_blobs(32, 1000 + step);
    opt.zero_grad();
    backward(mean(square(sub(net->forward(batch.images), batch.targets))));
    opt.step();
  }
  const double after = median_error_deg(*net, test);
  EXPECT_GT(before, 20.0) << "an untrained net should not already know the angle";
  EXPECT_LT(after, 5.0) << "median angular error in degrees on 200 held-out images (before training: " << before
                        << ")";
}

// Returns final / initial loss after `steps` Adam steps on one fixed batch.
template <class Forward>
double overfit_ratio(Module& model, Forward forward, const Tensor& target, int steps, double lr) {
  Adam opt(model.named_parameters(), {.lr = lr});
  double first = 0, last = 0;
  for (int s = 0; s < steps; ++s) {
    opt.zero_grad();
    const Tensor loss = mean(square(sub(forward(), target)));
    if (s == 0) first = loss.item();
    last = loss.item();
    backward(loss);
    opt.step();
  }
  return last / first;
}

TEST(Learning, Resnet18OverfitsOneSmallBatchByTenfold) {
  ResNet net({.depth = 18, .in_channels = 3, .base_width = 8, .num_classes = 4, .seed = 2});
  const Tensor x = Tensor::uniform({4, 3, 32, 32}, -1, 1, 3);
  const Tensor y = Tensor::uniform({4, 4}, -1, 1, 4);
  const double ratio = overfit_ratio(net, [&] { return net.forward(x); }, y, 60, 1e-2);
  EXPECT_LT(ratio, 0.1) << "loss ratio final/initial";
}

TEST(Learning, UNet3DOverfitsOneSmallBatchByTenfold) {
  UNet3D net({.in_channels = 1, .out_channels = 2, .base_channels = 4, .depth = 2, .norm = "group", .seed = 5});
  const Tensor x = Tensor::uniform({2, 1, 8, 8, 8}, -1, 1, 6);
  // A target the net can represent: smooth functions of the input plus an offset.
  const Tensor y = concat({mul_scalar(x, 0.5), add_scalar(square(x), -0.3)}, 1);
  const double ratio = overfit_ratio(net, [&] { return net.forward(x); }, y, 150, 1e-2);
  EXPECT_LT(ratio, 0.1) << "loss ratio final/initial";
}

}  // namespace
}  // namespace sl::test
