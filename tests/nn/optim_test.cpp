// Optimisers, gradient clipping and learning-rate schedules.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "autodiff/ops.h"
#include "nn/lr_schedule.h"
#include "nn/optim.h"

namespace sl::test {
using nn::Adam;
using nn::AdamW;
using nn::ConstantLr;
using nn::CosineLr;
using nn::LrSchedule;
using nn::NamedTensors;
using nn::Optimizer;
using nn::SGD;
using nn::StateDict;
using nn::StepLr;
using nn::WarmupLr;
using nn::clip_grad_norm;

namespace {

const std::vector<double> kP0 = {0.5, -1.25, 2.0};
const std::vector<std::vector<double>> kGrads = {{0.1, -0.2, 0.3}, {-0.05, 0.4, 0.01}, {0.2, 0.2, -0.6}};

// Runs three steps with the fixed gradients above on one F64 parameter.
template <class Make>
std::vector<double> run_three_steps(Make make) {
  Tensor p = Tensor::from_vector(kP0, {3}, DType::F64).set_requires_grad(true);
  auto opt = make(NamedTensors{{"p", p}});
  for (const auto& g : kGrads) {
    p.set_grad(Tensor::from_vector(g, {3}, DType::F64));
    opt.step();
  }
  return p.to_vector();
}

void expect_near(const std::vector<double>& a, const std::vector<double>& b, double tol) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) EXPECT_NEAR(a[i], b[i], tol) << "element " << i;
}

// Expected values: PyTorch's documented algorithms (torch.optim.{SGD,Adam,AdamW}, 1.13) run by
// hand in double precision on the same three gradients.
TEST(SGD, MomentumWeightDecayAndNesterovFollowPyTorch) {
  expect_near(run_three_steps([](NamedTensors p) {
                return SGD(p, {.lr = 0.1, .momentum = 0.9, .weight_decay = 0.01});
              }),
              {0.4596303895, -1.28482947875, 1.965704568}, 1e-12);
  expect_near(run_three_steps([](NamedTensors p) {
                return SGD(p, {.lr = 0.1, .momentum = 0.9, .weight_decay = 0.01, .nesterov = true});
              }),
              {0.4372273119805, -1.31763754924625, 1.992362146512}, 1e-12);
  expect_near(run_three_steps([](NamedTensors p) {
                return SGD(p, {.lr = 0.1, .momentum = 0.9, .dampening = 0.5, .weight_decay = 0.01});
              }),
              {0.465588822375, -1.2386306821875, 1.939491542}, 1e-12);
}

TEST(SGD, PlainStepIsLrTimesGradient) {
  Tensor p = Tensor::from_vector({1.0, 2.0}, {2}).set_requires_grad(true);
  SGD opt({{"p", p}}, {.lr = 0.5});
  p.set_grad(Tensor::from_vector({0.2, -0.4}, {2}));
  opt.step();
  expect_near(p.to_vector(), {0.9, 2.2}, 1e-7);
}

TEST(Adam, BiasCorrectedStepsFollowPyTorch) {
  expect_near(run_three_steps([](NamedTensors p) { return Adam(p, {.lr = 0.01, .weight_decay = 0.1}); }),
              {0.4752235505715115, -1.2406150051137452, 1.9791357957143945}, 1e-12);
}

TEST(Adam, FirstStepMovesEachParameterByLrAgainstItsGradientSign) {
  // With bias correction, m̂ = g and v̂ = g² after one step: Δp = −lr·g / (|g| + eps).
  Tensor p = Tensor::from_vector({1.0, 1.0, 1.0}, {3}).set_requires_grad(true);
  Adam opt({{"p", p}}, {.lr = 0.1});
  p.set_grad(Tensor::from_vector({1e-3, -5.0, 300.0}, {3}));
  opt.step();
  expect_near(p.to_vector(), {0.9, 1.1, 0.9}, 1e-5);
}

TEST(AdamW, DecoupledWeightDecayFollowsPyTorch) {
  expect_near(run_three_steps([](NamedTensors p) { return AdamW(p, {.lr = 0.01, .weight_decay = 0.1}); }),
              {0.4792796683031988, -1.2451235213470124, 1.980402295981196}, 1e-12);
}

// set_lr_scale: the named parameters step at lr·s (SGD exactly; Adam's first step by lr·s against the
// gradient's sign; AdamW's decay at lr·s too), the others exactly as without it; a prefix that names
// nothing and a scale that is not positive throw.
TEST(Optimizer, APrefixStepsAtItsOwnScaleOfTheRate) {
  Tensor head = Tensor::from_vector({1.0, 2.0}, {2}).set_requires_grad(true);
  Tensor body = Tensor::from_vector({1.0, 2.0}, {2}).set_requires_grad(true);
  SGD sgd({{"head.w", head}, {"body.w", body}}, {.lr = 0.5});
  sgd.set_lr_scale("head.", 10.0);
  head.set_grad(Tensor::from_vector({0.02, -0.04}, {2}));
  body.set_grad(Tensor::from_vector({0.2, -0.4}, {2}));
  sgd.step();
  expect_near(head.to_vector(), {0.9, 2.2}, 1e-7);  // float32
  expect_near(body.to_vector(), {0.9, 2.2}, 1e-7);
  // AdamW: the scaled parameter against a copy stepped by an unscaled optimiser at lr·s.
  Tensor a = Tensor::from_vector({1.0, -1.0}, {2}).set_requires_grad(true);
  Tensor b = Tensor::from_vector({1.0, -1.0}, {2}).set_requires_grad(true);
  Tensor c = Tensor::from_vector({1.0, -1.0}, {2}).set_requires_grad(true);
  Tensor d = Tensor::from_vector({1.0, -1.0}, {2}).set_requires_grad(true);
  AdamW scaled({{"domain_head.w", a}, {"rest", b}}, {.lr = 1e-3, .weight_decay = 0.1});
  scaled.set_lr_scale("domain_head.", 4.0);
  AdamW fast({{"x", c}}, {.lr = 4e-3, .weight_decay = 0.1}), plain({{"x", d}}, {.lr = 1e-3, .weight_decay = 0.1});
  for (int t = 0; t < 3; ++t) {
    const Tensor g = Tensor::from_vector({0.3 - t, 0.7 * t}, {2});
    for (Tensor* p : {&a, &b, &c, &d}) p->set_grad(g.clone());
    scaled.step(), fast.step(), plain.step();
  }
  EXPECT_EQ(a.to_vector(), c.to_vector());
  EXPECT_EQ(b.to_vector(), d.to_vector());
  EXPECT_THROW(scaled.set_lr_scale("trunk.", 2.0), Error);
  EXPECT_THROW(scaled.set_lr_scale("rest", 0.0), Error);
  EXPECT_THROW(scaled.set_lr_scale("rest", std::nan("")), Error);
}

TEST(Optimizer, SkipsParametersWithoutGradientAndDoesNotAdvanceTheirStep) {
  Tensor a = Tensor::from_vector({1.0}, {1}).set_requires_grad(true);
  Tensor b = Tensor::from_vector({1.0}, {1}).set_requires_grad(true);
  Adam opt({{"a", a}, {"b", b}}, {.lr = 0.1});
  a.set_grad(Tensor::from_vector({1.0}, {1}));
  opt.step();
  EXPECT_EQ(b.to_vector()[0], 1.0);
  EXPECT_EQ(opt.state_dict().at("step.a").item(), 1);
  EXPECT_EQ(opt.state_dict().at("step.b").item(), 0);
}

TEST(Optimizer, StateRoundTripResumesBitwiseIdentically) {
  auto make_param = [] { return Tensor::from_vector(kP0, {3}).set_requires_grad(true); };
  Tensor p1 = make_param(), p2 = make_param();
  Adam a({{"w", p1}}, {.lr = 0.01});
  for (int i = 0; i < 2; ++i) {
    p1.set_grad(Tensor::from_vector(kGrads[i], {3}));
    a.step();
  }
  const StateDict state = a.state_dict();
  EXPECT_TRUE(state.count("exp_avg.w") && state.count("exp_avg_sq.w") && state.count("step.w"));
  p2.copy_(p1);
  Adam b({{"w", p2}}, {.lr = 0.01});
  b.load_state_dict(state);
  p1.set_grad(Tensor::from_vector(kGrads[2], {3}));
  p2.set_grad(Tensor::from_vector(kGrads[2], {3}));
  a.step();
  b.step();
  EXPECT_EQ(p1.to_vector(), p2.to_vector());
}

TEST(Optimizer, LoadStateRejectsMismatchInOneMessage) {
  Tensor p = Tensor::zeros({3}).set_requires_grad(true);
  SGD opt({{"w", p}}, {.lr = 0.1, .momentum = 0.9});
  StateDict s = opt.state_dict();
  s["momentum_buffer.w"] = Tensor::zeros({4});
  s["exp_avg.w"] = Tensor::zeros({3});
  try {
    opt.load_state_dict(s);
    FAIL();
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("unexpected: exp_avg.w"), std::string::npos) << m;
    EXPECT_NE(m.find("momentum_buffer.w: expected f32[3], got f32[4]"), std::string::npos) << m;
  }
}

// The average follows a ← d·a + (1 − d)·p, d = min(decay, (1 + t)/(10 + t)), a = p at t = 1,
// computed here by hand beside plain SGD, whose parameter values are p0 − lr·Σg.
TEST(Optimizer, WeightAverageFollowsTheRampedMovingAverageAndSwapsBack) {
  Tensor p = Tensor::from_vector(kP0, {3}, DType::F64).set_requires_grad(true);
  Tensor frozen = Tensor::from_vector({7.0}, {1}, DType::F64).set_requires_grad(true);
  SGD opt({{"p", p}, {"frozen", frozen}}, {.lr = 0.5});
  opt.enable_average(0.2);
  std::vector<double> w = kP0, avg;
  for (size_t s = 0; s < kGrads.size(); ++s) {
    p.set_grad(Tensor::from_vector(kGrads[s], {3}, DType::F64));
    opt.step();
    const double t = double(s + 1), d = s == 0 ? 0.0 : std::min(0.2, (1 + t) / (10 + t));
    for (size_t k = 0; k < 3; ++k) w[k] -= 0.5 * kGrads[s][k];
    if (s == 0) avg = w;
    else
      for (size_t k = 0; k < 3; ++k) avg[k] = d * avg[k] + (1 - d) * w[k];
  }
  ASSERT_TRUE(opt.state_dict().count("average.p"));
  expect_near(opt.state_dict().at("average.p").to_vector(), avg, 1e-15);
  opt.swap_average();
  expect_near(p.to_vector(), avg, 1e-15);
  EXPECT_EQ(frozen.to_vector()[0], 7.0);  // never stepped: its (zero) average is not swapped in
  opt.swap_average();
  expect_near(p.to_vector(), w, 1e-15);
  EXPECT_THROW(opt.enable_average(0.5), Error);  // already on
}

TEST(Optimizer, WeightAverageIsStateSoAResumedRunAveragesIdentically) {
  auto make_param = [] { return Tensor::from_vector(kP0, {3}).set_requires_grad(true); };
  Tensor p1 = make_param(), p2 = make_param();
  Adam a({{"w", p1}}, {.lr = 0.01});
  a.enable_average(0.9);
  for (int i = 0; i < 2; ++i) {
    p1.set_grad(Tensor::from_vector(kGrads[i], {3}));
    a.step();
  }
  p2.copy_(p1);
  Adam b({{"w", p2}}, {.lr = 0.01});
  EXPECT_THROW(b.load_state_dict(a.state_dict()), Error);  // "average.w" unexpected while off
  b.enable_average(0.9);
  b.load_state_dict(a.state_dict());
  p1.set_grad(Tensor::from_vector(kGrads[2], {3}));
  p2.set_grad(Tensor::from_vector(kGrads[2], {3}));
  a.step();
  b.step();
  EXPECT_EQ(a.state_dict().at("average.w").to_vector(), b.state_dict().at("average.w").to_vector());
}

TEST(Optimizer, BadHyperparametersThrow) {
  Tensor p = Tensor::zeros({1}).set_requires_grad(true);
  EXPECT_THROW(SGD({{"p", p}}, {.lr = -1}), Error);
  EXPECT_THROW(Adam({{"p", p}}, {.beta1 = 1.0}), Error);
  EXPECT_THROW(Adam({{"p", p}}, {.eps = 0}), Error);
  EXPECT_THROW(SGD({{"p", p}}, {.nesterov = true}), Error);
  SGD ok({{"p", p}}, {.lr = 0.1});
  EXPECT_THROW(ok.enable_average(1.0), Error);
  EXPECT_THROW(ok.enable_average(0.0), Error);
  EXPECT_THROW(ok.swap_average(), Error);  // averaging is off
}

TEST(ClipGradNorm, ScalesToMaxNormAndReturnsTheNormBefore) {
  Tensor a = Tensor::zeros({2}).set_requires_grad(true), b = Tensor::zeros({1}).set_requires_grad(true);
  Tensor c = Tensor::zeros({1}).set_requires_grad(true);  // no gradient: ignored
  a.set_grad(Tensor::from_vector({3.0, 0.0}, {2}));
  b.set_grad(Tensor::from_vector({4.0}, {1}));
  EXPECT_NEAR(clip_grad_norm(std::vector<Tensor>{a, b, c}, 1.0), 5.0, 1e-6);
  expect_near(a.grad().to_vector(), {0.6, 0.0}, 1e-6);
  expect_near(b.grad().to_vector(), {0.8}, 1e-6);
  EXPECT_NEAR(clip_grad_norm(std::vector<Tensor>{a, b}, 10.0), 1.0, 1e-6);  // below: untouched
  expect_near(b.grad().to_vector(), {0.8}, 1e-6);
}

TEST(ClipGradNorm, NonFiniteNormIsReportedAndGradientsLeftUntouched) {
  Tensor a = Tensor::zeros({2}).set_requires_grad(true);
  a.set_grad(Tensor::from_vector({std::numeric_limits<double>::quiet_NaN(), 1.0}, {2}));
  EXPECT_TRUE(std::isnan(clip_grad_norm(std::vector<Tensor>{a}, 1.0)));
  EXPECT_EQ(a.grad().to_vector()[1], 1.0);
  a.set_grad(Tensor::from_vector({INFINITY, 1.0}, {2}));
  EXPECT_TRUE(std::isinf(clip_grad_norm(std::vector<Tensor>{a}, 1.0)));
}

// ---------------------------------------------------------------- schedules
TEST(LrSchedule, StepCosineAndConstantMatchTheirFormulas) {
  StepLr step(0.1, 10, 0.5);
  EXPECT_DOUBLE_EQ(step.lr(0), 0.1);
  EXPECT_DOUBLE_EQ(step.lr(9), 0.1);
  EXPECT_DOUBLE_EQ(step.lr(10), 0.05);
  EXPECT_DOUBLE_EQ(step.lr(25), 0.025);
  CosineLr cos(1.0, 100, 0.1);
  EXPECT_DOUBLE_EQ(cos.lr(0), 1.0);
  EXPECT_NEAR(cos.lr(50), 0.55, 1e-12);
  EXPECT_NEAR(cos.lr(100), 0.1, 1e-12);
  EXPECT_NEAR(cos.lr(1000), 0.1, 1e-12);
  EXPECT_DOUBLE_EQ(ConstantLr(0.3).lr(77), 0.3);
}

TEST(LrSchedule, WarmupThenCosineComposes) {
  WarmupLr s(10, std::make_shared<CosineLr>(1.0, 100));
  EXPECT_NEAR(s.lr(0), 0.1, 1e-12);
  EXPECT_NEAR(s.lr(4), 0.5, 1e-12);
  EXPECT_NEAR(s.lr(9), 1.0, 1e-12);
  EXPECT_NEAR(s.lr(10), 1.0, 1e-12);
  EXPECT_NEAR(s.lr(60), 0.5, 1e-12);
  EXPECT_NEAR(s.lr(110), 0.0, 1e-12);
  for (int64_t i = 1; i < 10; ++i) EXPECT_GT(s.lr(i), s.lr(i - 1));
}

TEST(LrSchedule, BadArgumentsThrow) {
  EXPECT_THROW(StepLr(0.1, 0, 0.5), Error);
  EXPECT_THROW(CosineLr(0.1, 0), Error);
  EXPECT_THROW(WarmupLr(0, std::make_shared<ConstantLr>(1.0)), Error);
  EXPECT_THROW(WarmupLr(5, nullptr), Error);
  EXPECT_THROW(ConstantLr(-1.0), Error);
}

}  // namespace
}  // namespace sl::test
